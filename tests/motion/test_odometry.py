"""Tests of the odometry motion model (``ceamcl.motion.odometry``)."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.angles import wrap
from ceamcl.motion.odometry import (
    DEFAULT_STRIDE_M,
    MIN_TRANSLATION_FOR_ROT1_M,
    STRIDE_M,
    STRIDE_RAD,
    OdometryIncrement,
    OdometryMotionModel,
    OdometryNoise,
    apply_increment,
    increment_between,
    synthetic_odometry,
)

# Small enough that the sampled translation stays positive (0.5 m is > 6 standard deviations
# of the translation noise below), so the decomposition of every moved pose is unambiguous.
NOISE = OdometryNoise(alpha1=0.05, alpha2=0.02, alpha3=0.02, alpha4=0.01)
N_SAMPLES = 200_000
START = np.array([1.0, -2.0, 0.4])
# Table 5.6 over a whole update, as amcl applies it (no strides)
AMCL_MODEL = OdometryMotionModel(NOISE, stride_m=None, stride_rad=None)


def recover_components(start: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """(rot1, trans, rot2) of each moved pose relative to ``start``: inverse of apply_increment
    for positive translations."""
    dx = moved[:, 0] - start[0]
    dy = moved[:, 1] - start[1]
    trans = np.hypot(dx, dy)
    rot1 = wrap(np.arctan2(dy, dx) - start[2])
    rot2 = wrap(moved[:, 2] - start[2] - rot1)
    return np.column_stack([rot1, trans, rot2])


def check_moments(
    components: np.ndarray, expected_mean: np.ndarray, expected_var: np.ndarray
) -> None:
    """Sample means and variances within 5 standard errors of the model's.

    SE(mean) = sqrt(v / n); for Gaussian samples SE(variance) = v * sqrt(2 / (n - 1)).
    """
    n = components.shape[0]
    mean = components.mean(axis=0)
    var = components.var(axis=0, ddof=1)
    se_mean = np.sqrt(expected_var / n)
    se_var = expected_var * np.sqrt(2.0 / (n - 1))
    np.testing.assert_array_less(np.abs(mean - expected_mean), 5 * se_mean)
    np.testing.assert_array_less(np.abs(var - expected_var), 5 * se_var)
    # The three noise terms are independent: sample correlations within 5 / sqrt(n) of 0.
    corr = np.corrcoef(components.T)
    off_diagonal = corr[~np.eye(3, dtype=bool)]
    assert np.all(np.abs(off_diagonal) < 5 / np.sqrt(n))


def test_sample_has_the_increment_mean_and_the_model_variances() -> None:
    inc = OdometryIncrement(rot1=0.3, trans=0.5, rot2=-0.2)
    v = np.array(inc.variances(NOISE))
    # Table 5.6 by hand: variances, not standard deviations.
    np.testing.assert_allclose(
        v,
        [
            0.05 * 0.3**2 + 0.02 * 0.5**2,
            0.02 * 0.5**2 + 0.01 * (0.3**2 + 0.2**2),
            0.05 * 0.2**2 + 0.02 * 0.5**2,
        ],
        rtol=1e-12,
    )
    assert 0.5 / np.sqrt(v[1]) > 6.0  # translation never flips sign in practice
    rng = np.random.default_rng(0)
    moved = AMCL_MODEL.sample(np.tile(START, (N_SAMPLES, 1)), inc, rng)
    assert moved.shape == (N_SAMPLES, 3)
    assert np.all((moved[:, 2] > -np.pi) & (moved[:, 2] <= np.pi))
    check_moments(recover_components(START, moved), np.array([0.3, 0.5, -0.2]), v)


def test_backwards_motion_does_not_count_as_a_half_turn() -> None:
    # Driving 0.4 m straight backwards: rot1 = pi, rot2 = pi (wrap of -pi) in the
    # decomposition, but the rotation noise must use min(|rot1|, |rot1 - pi|) = 0, leaving only
    # the translation-induced term alpha2 * trans^2.
    prev = np.array([2.0, 1.0, 0.3])
    cur = np.array([2.0 - 0.4 * np.cos(0.3), 1.0 - 0.4 * np.sin(0.3), 0.3])
    inc = increment_between(prev, cur)
    assert inc.trans == pytest.approx(0.4)
    assert abs(float(wrap(inc.rot1 - np.pi))) < 1e-9
    v = np.array(inc.variances(NOISE))
    np.testing.assert_allclose(v, [0.02 * 0.16, 0.02 * 0.16, 0.02 * 0.16], rtol=1e-9, atol=1e-15)
    rng = np.random.default_rng(1)
    moved = AMCL_MODEL.sample(np.tile(prev, (N_SAMPLES, 1)), inc, rng)
    comp = recover_components(prev, moved)
    # Recovered rot1 and rot2 sit around +-pi: measure them relative to the increment's values
    # to stay clear of the seam.
    comp[:, 0] = wrap(comp[:, 0] - inc.rot1)
    comp[:, 2] = wrap(comp[:, 2] - inc.rot2)
    check_moments(comp, np.array([0.0, 0.4, 0.0]), v)
    # The mean moved pose is 0.4 m behind the start, heading unchanged.
    assert np.hypot(*(moved[:, :2].mean(axis=0) - cur[:2])) < 5e-3


def test_zero_noise_gives_exactly_apply_increment() -> None:
    rng = np.random.default_rng(2)
    poses = np.column_stack(
        [rng.uniform(-5, 5, 500), rng.uniform(-5, 5, 500), rng.uniform(-np.pi, np.pi, 500)]
    )
    inc = OdometryIncrement(0.3, 0.5, -0.2)
    model = OdometryMotionModel(OdometryNoise(0.0, 0.0, 0.0, 0.0))
    out = model.sample(poses, inc, rng)
    assert np.array_equal(out, apply_increment(poses, 0.3, 0.5, -0.2))


def test_apply_increment_geometry() -> None:
    out = apply_increment(np.array([[1.0, 2.0, np.pi / 2]]), np.pi / 2, 2.0, np.pi)
    # Heading pi after rot1, drive 2 m along -x, then turn by pi more: heading 0 (wrapped 2 pi).
    np.testing.assert_allclose(out[0], [-1.0, 2.0, 0.0], atol=1e-12)


def test_increment_between_round_trips_through_apply_increment() -> None:
    rng = np.random.default_rng(3)
    n = 2000
    a = np.column_stack(
        [rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(-np.pi, np.pi, n)]
    )
    step = rng.uniform(-1.0, 1.0, (n, 2))
    step[: n // 4] *= 0.05  # many short steps, down to well under a centimetre
    b = np.column_stack([a[:, :2] + step, rng.uniform(-np.pi, np.pi, n)])
    for i in range(n):
        inc = increment_between(a[i], b[i])
        assert inc.trans >= 0.0
        assert -np.pi < inc.rot1 <= np.pi
        assert -np.pi < inc.rot2 <= np.pi
        back = apply_increment(a[i], inc.rot1, inc.trans, inc.rot2)[0]
        assert abs(float(wrap(back[2] - b[i, 2]))) < 1e-9
        if inc.trans >= MIN_TRANSLATION_FOR_ROT1_M:
            np.testing.assert_allclose(back[:2], b[i, :2], atol=1e-9)
        else:
            # Under 1 cm the robot moves only forwards or backwards, as the displacement along
            # its old heading says: the position lands within sqrt(2) of the length, on the
            # right side of the start.
            assert inc.rot1 in (0.0, np.pi)
            assert np.hypot(*(back[:2] - b[i, :2])) <= np.sqrt(2) * inc.trans + 1e-12
            heading = np.array([np.cos(a[i, 2]), np.sin(a[i, 2])])
            assert (back[:2] - a[i, :2]) @ heading * (step[i] @ heading) >= 0.0


def test_a_robot_backing_up_in_steps_under_a_centimetre_ends_behind_its_start() -> None:
    # Odometry read at every scan of a slowly reversing robot: 200 steps of 5 mm straight back
    # at heading 0.3 rad. Re-integrating the increments ends where the odometry does (a rot1 of
    # 0 for short steps carried it 1 m forwards instead).
    heading = np.array([np.cos(0.3), np.sin(0.3)])
    poses = np.array([[*(-0.005 * k * heading), 0.3] for k in range(201)])
    here = poses[0]
    for k in range(1, len(poses)):
        inc = increment_between(poses[k - 1], poses[k])
        assert inc.rot1 == np.pi and inc.trans == pytest.approx(0.005)
        here = apply_increment(here, inc.rot1, inc.trans, inc.rot2)[0]
    np.testing.assert_allclose(here, poses[-1], atol=1e-9)
    # a reversing step has turned no more than a straight one: pi is no turn (module
    # docstring); the look-around measures turns so, the noise grows with them
    back = increment_between(poses[0], poses[1])
    assert back.turns == pytest.approx((0.0, 0.0), abs=1e-12)
    turning = increment_between(poses[0], poses[1] + np.array([0.0, 0.0, -0.6]))
    assert turning.rot1 == np.pi and turning.turns == pytest.approx((0.0, 0.6))
    # a big turn on the spot is a big turn (the noise's fold would read 3 rad as 0.14)
    spin = increment_between(poses[0], poses[0] + np.array([0.001, 0.0, 3.0]))
    assert spin.turns == pytest.approx((0.0, 3.0))
    spin_back = increment_between(poses[0], poses[1] + np.array([0.0, 0.0, 3.0]))
    assert spin_back.rot1 == np.pi and spin_back.turns == pytest.approx((0.0, 3.0))
    # the noise of a reversing step is a straight step's: pi is no turn (module docstring)
    forward = increment_between(poses[1], poses[0])
    assert increment_between(poses[0], poses[1]).variances(NOISE) == pytest.approx(
        forward.variances(NOISE)
    )


def test_synthetic_odometry_of_a_track_jittering_sideways_does_not_turn() -> None:
    # A SLAM track of a robot standing still: the estimate jitters 2-3 cm sideways and back
    # at every scan, the heading within a milliradian. Wheels made no turn, so odometry made
    # from the track must not turn either; the filter's model (Nav2's) reads each step as a
    # turn out of pi/2 and back, and drawing the odometry with it turned the synthetic robot
    # by about 0.22 rad a scan (alpha1 0.02).
    rng = np.random.default_rng(7)
    k = np.arange(41)
    side = np.where(k % 2 == 1, 0.025, 0.0) + 0.005 * rng.standard_normal(41)
    track = np.column_stack([0.001 * rng.standard_normal(41), side, 0.001 * np.sin(k)])
    noise = OdometryNoise(0.02, 0.02, 0.02, 0.02)
    inc = increment_between(track[0], track[1])
    assert abs(abs(inc.rot1) - np.pi / 2) < 0.5  # sideways: a turn out and back for the model
    assert inc.variances(noise)[0] > 0.02  # the filter's model keeps its noise
    assert inc.wheel_variances(noise)[0] < 1e-4  # the turn made: none, as the wheels saw
    turned = []
    for seed in range(20):
        odom = synthetic_odometry(track, noise, np.random.default_rng(seed))
        turned.append(np.abs(wrap(np.diff(odom[:, 2]))).max())
    # per scan: 0.01-0.02 rad at the worst scan of each seed; 0.6-1.1 rad with the model's noise
    assert max(turned) < 0.05


def test_wheel_variances_are_the_models_for_a_step_wheels_can_make() -> None:
    # Every step of a wheeled robot travels between its old and new heading (forwards or
    # backwards): driving straight, turning on the spot, an arc, a reversing arc. Those keep
    # the model's variances bit for bit (the simulator's runs do not change).
    start = np.array([1.0, 2.0, 0.4])
    offsets = np.array(
        [
            [0.3 * np.cos(0.4), 0.3 * np.sin(0.4), 0.0],
            [0.0, 0.0, 0.5],
            [0.2 * np.cos(0.55), 0.2 * np.sin(0.55), 0.3],
            [-0.2 * np.cos(0.3), -0.2 * np.sin(0.3), -0.2],
            [0.004, 0.0, 2.9],
        ]
    )
    for offset in offsets:
        inc = increment_between(start, start + offset)
        assert inc.wheel_variances(NOISE) == inc.variances(NOISE)
    # a step that leaves the sweep by 0.3 rad is charged for the turn within it only
    odd = increment_between(start, start + np.array([0.2 * np.cos(0.9), 0.2 * np.sin(0.9), 0.2]))
    v = odd.wheel_variances(NOISE)
    assert v[0] == pytest.approx(NOISE.alpha1 * 0.2**2 + NOISE.alpha2 * 0.2**2)
    assert v[2] == pytest.approx(NOISE.alpha2 * 0.2**2, abs=1e-12)


def test_zero_motion_is_zero_increment_and_adds_no_noise() -> None:
    p = np.array([3.0, 4.0, -2.0])
    inc = increment_between(p, p)
    assert inc.is_zero
    assert inc.variances(OdometryNoise()) == (0.0, 0.0, 0.0)
    out = OdometryMotionModel().sample(np.tile(p, (10, 1)), inc, np.random.default_rng(4))
    np.testing.assert_allclose(out, np.tile(p, (10, 1)), atol=1e-15)


def test_pure_rotation_has_rotation_noise_only() -> None:
    # Turning on the spot by 0.6 rad: rot1 = 0, trans = 0, rot2 = 0.6. Heading noise variance
    # alpha1 * 0.36, position noise from trans only: alpha4 * 0.36.
    p = np.array([0.0, 0.0, 1.0])
    inc = increment_between(p, p + np.array([0.0, 0.0, 0.6]))
    assert (inc.rot1, inc.trans) == (0.0, 0.0)
    assert inc.rot2 == pytest.approx(0.6)
    v = inc.variances(NOISE)
    assert v[0] == 0.0
    rng = np.random.default_rng(5)
    moved = AMCL_MODEL.sample(np.tile(p, (N_SAMPLES, 1)), inc, rng)
    dtheta = wrap(moved[:, 2] - p[2])
    expected_var = v[0] + v[2]
    assert abs(dtheta.mean() - 0.6) < 5 * np.sqrt(expected_var / N_SAMPLES)
    se_var = expected_var * np.sqrt(2.0 / (N_SAMPLES - 1))
    assert abs(dtheta.var(ddof=1) - expected_var) < 5 * se_var
    # Signed displacement along the start heading has variance v_trans.
    along = moved[:, 0] * np.cos(1.0) + moved[:, 1] * np.sin(1.0)
    se_var_t = v[1] * np.sqrt(2.0 / (N_SAMPLES - 1))
    assert abs(along.var(ddof=1) - v[1]) < 5 * se_var_t


def test_an_update_of_many_strides_has_the_noise_of_those_strides() -> None:
    """Noise per stride (module docstring), travel and turns counted (an option): an update
    of 1.5 m is six strides of 0.25 m, so its variances are Table 5.6's over 1.5 m divided by
    six (they grow with the distance, not its square); a turn of 0.6 rad on the spot is three
    strides of 0.2 rad; an update within one stride keeps Table 5.6's variances. The samples
    show it."""
    model = OdometryMotionModel(NOISE, stride_m=STRIDE_M, stride_rad=STRIDE_RAD)
    long = OdometryIncrement(rot1=0.05, trans=1.5, rot2=-0.05)
    assert long.strides(model.stride_m, model.stride_rad) == pytest.approx(6.0)
    v = np.array(long.variances(NOISE)) / 6.0
    moved = model.sample(np.tile(START, (N_SAMPLES, 1)), long, np.random.default_rng(11))
    check_moments(recover_components(START, moved), np.array([0.05, 1.5, -0.05]), v)
    turn = increment_between(START, START + np.array([0.0, 0.0, 0.6]))
    assert turn.strides(model.stride_m, model.stride_rad) == pytest.approx(3.0)
    moved = model.sample(np.tile(START, (N_SAMPLES, 1)), turn, np.random.default_rng(12))
    expected = (turn.variances(NOISE)[0] + turn.variances(NOISE)[2]) / 3.0
    dtheta = wrap(moved[:, 2] - START[2])
    assert abs(dtheta.var(ddof=1) - expected) < 5 * expected * np.sqrt(2.0 / (N_SAMPLES - 1))
    short = OdometryIncrement(rot1=0.1, trans=0.2, rot2=-0.05)
    assert short.strides(model.stride_m, model.stride_rad) == 1.0
    rng_a, rng_b = np.random.default_rng(13), np.random.default_rng(13)
    start = np.tile(START, (100, 1))
    assert np.array_equal(model.sample(start, short, rng_a), AMCL_MODEL.sample(start, short, rng_b))


def test_the_default_model_counts_strides_of_travel_not_turns() -> None:
    """The default (module docstring, "noise per stride of travel"): 1.5 m of travel is three
    strides of 0.5 m, so Table 5.6's variances are divided by three; an update Nav2 could make
    itself (0.45 m) and a turn of 0.6 rad on the spot keep Table 5.6's variances, as amcl's
    rule does (a turn's slip is one error)."""
    model = OdometryMotionModel(NOISE)
    assert (model.stride_m, model.stride_rad) == (DEFAULT_STRIDE_M, None) == (2 * STRIDE_M, None)
    long = OdometryIncrement(rot1=0.05, trans=1.5, rot2=-0.05)
    v = np.array(long.variances(NOISE)) / 3.0
    moved = model.sample(np.tile(START, (N_SAMPLES, 1)), long, np.random.default_rng(21))
    check_moments(recover_components(START, moved), np.array([0.05, 1.5, -0.05]), v)
    start = np.tile(START, (100, 1))
    nav2_update = OdometryIncrement(rot1=0.1, trans=0.45, rot2=-0.1)
    turn = increment_between(START, START + np.array([0.0, 0.0, 0.6]))
    for inc in (nav2_update, turn):
        rng_a, rng_b = np.random.default_rng(22), np.random.default_rng(22)
        assert np.array_equal(model.sample(start, inc, rng_a), AMCL_MODEL.sample(start, inc, rng_b))


def test_strides_are_validated() -> None:
    with pytest.raises(ValueError, match="stride_m"):
        OdometryMotionModel(stride_m=0.0)
    with pytest.raises(ValueError, match="stride_rad"):
        OdometryMotionModel(stride_rad=float("nan"))


def test_noise_parameters_are_validated() -> None:
    with pytest.raises(ValueError, match="alpha3"):
        OdometryNoise(0.1, 0.1, -0.1, 0.1)
    with pytest.raises(ValueError, match="alpha1"):
        OdometryNoise(float("nan"), 0.1, 0.1, 0.1)


@pytest.mark.parametrize(
    ("previous", "current", "message"),
    [
        ([0, 0], [1, 1], r"previous: expected an odometry pose \(x, y, theta\), got 2 value"),
        ([0, 0, 0], [1, 1, 0, 0], r"current: expected an odometry pose .* got 4 value"),
        ([0, 0, 0], "abc", r"current: expected an odometry pose \(x, y, theta\), got str"),
    ],
)
def test_increment_between_names_a_pose_that_is_not_three_numbers(
    previous: object, current: object, message: str
) -> None:
    """[0, 0] gave 'IndexError: index 2 is out of bounds for axis 0 with size 2'."""
    from ceamcl.errors import ConfigError

    with pytest.raises(ConfigError, match=message):
        increment_between(previous, current)  # type: ignore[arg-type]
    assert increment_between(np.array([[0.0, 0.0, 0.0]]), (1, 0, 0)).trans == 1.0
