"""Tests of the simulator and scenarios (``ceamcl.simulation``)."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.angles import diff
from ceamcl.errors import ConfigError
from ceamcl.motion.odometry import increment_between
from ceamcl.sensors.raycast import cast_rays
from ceamcl.sensors.scan import laser_poses
from ceamcl.simulation import (
    SimulatedLog,
    SimulationConfig,
    Simulator,
    drive_waypoints,
    get_scenario,
    office_scenario,
    paper_scenario,
)

LOG_ARRAYS = ("times", "true_poses", "odometry", "ranges")


@pytest.fixture(scope="module")
def paper_log() -> SimulatedLog:
    return paper_scenario(0).simulate(np.random.default_rng(30))


def test_same_seed_gives_the_same_log_bit_for_bit() -> None:
    sc = office_scenario()
    a = sc.simulate(np.random.default_rng(31))
    b = sc.simulate(np.random.default_rng(31))
    for name in LOG_ARRAYS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    c = sc.simulate(np.random.default_rng(32))
    assert np.array_equal(a.true_poses, c.true_poses)  # the route is deterministic
    assert np.array_equal(a.times, c.times)
    assert not np.array_equal(a.odometry, c.odometry)
    assert not np.array_equal(a.ranges, c.ranges)


def test_log_shapes_times_and_world(paper_log: SimulatedLog) -> None:
    n = len(paper_log)
    assert n > 100
    assert paper_log.true_poses.shape == (n, 3)
    assert paper_log.odometry.shape == (n, 3)
    assert paper_log.ranges.shape == (n, paper_log.laser.n_beams)
    assert paper_log.world == "symmetric-hall"
    # 10 Hz from t = 0.
    assert paper_log.times[0] == 0.0
    np.testing.assert_allclose(np.diff(paper_log.times), 0.1, atol=1e-12)
    scan = paper_log.scan(5)
    assert scan.stamp == pytest.approx(0.5)
    assert np.array_equal(scan.ranges, paper_log.ranges[5])
    assert scan.pose == paper_log.laser.pose == (0.1, 0.0, 0.0)


def test_ranges_within_limits(paper_log: SimulatedLog) -> None:
    laser = paper_log.laser
    r = paper_log.ranges
    assert np.all(np.isfinite(r))
    assert np.all((r >= laser.range_min) & (r <= laser.range_max))
    # The hall is 15 m wide: some beams see nothing within 8 m.
    assert np.any(r == laser.range_max)


def test_noise_free_scans_are_the_ray_cast_ranges() -> None:
    cfg = SimulationConfig(range_sigma_m=0.0, random_reading_prob=0.0)
    sc = paper_scenario(1, config=cfg)
    grid = sc.grid()
    truth = sc.true_path()[::20]
    log = Simulator(grid, cfg).run(truth, np.random.default_rng(33))
    lp = laser_poses(truth, cfg.laser.pose)
    m = cfg.laser.n_beams
    angles = (lp[:, 2:3] + cfg.laser.angles[None, :]).reshape(-1)
    exact = cast_rays(grid, np.repeat(lp[:, :2], m, axis=0), angles, cfg.laser.range_max)
    np.testing.assert_array_equal(log.ranges, exact.reshape(-1, m))


def test_scan_noise_statistics(paper_log: SimulatedLog) -> None:
    cfg = SimulationConfig()
    grid = paper_scenario(0).grid()
    truth = paper_log.true_poses
    lp = laser_poses(truth, cfg.laser.pose)
    m = cfg.laser.n_beams
    angles = (lp[:, 2:3] + cfg.laser.angles[None, :]).reshape(-1)
    exact = cast_rays(grid, np.repeat(lp[:, :2], m, axis=0), angles, cfg.laser.range_max)
    exact = exact.reshape(-1, m)
    hit = exact < cfg.laser.range_max - 0.2  # clear of the clipping at range_max
    residual = (paper_log.ranges - exact)[hit]
    n = residual.size
    # Random readings (probability 0.01) are uniform over [0.02, 8]: all but a 0.2 / 7.98 share
    # of them land more than 0.1 m (5 sigma) from the truth. That share of far readings is a
    # binomial proportion: p +- 5 sqrt(p (1 - p) / n).
    far = np.abs(residual) > 0.1
    p = cfg.random_reading_prob * (1.0 - 0.2 / (cfg.laser.range_max - cfg.laser.range_min))
    assert abs(far.mean() - p) < 5 * np.sqrt(p * (1 - p) / n)
    # The rest is Gaussian with sigma 0.02 m: std within 5 standard errors (sigma / sqrt(2 n)),
    # after removing the 1.4e-6 share of Gaussian draws beyond 5 sigma with the random ones
    # (a bias of ~1e-5 relative, negligible).
    core = residual[~far]
    assert abs(core.mean()) < 5 * 0.02 / np.sqrt(core.size)
    assert abs(core.std() - 0.02) < 5 * 0.02 / np.sqrt(2 * core.size)


def test_odometry_starts_at_the_truth_and_drifts(paper_log: SimulatedLog) -> None:
    odom, truth = paper_log.odometry, paper_log.true_poses
    assert np.array_equal(odom[0], truth[0])
    error = np.hypot(*(odom[:, :2] - truth[:, :2]).T)
    assert error[-1] > 1e-3
    assert np.all(np.isfinite(odom))


def test_odometry_increments_have_the_model_statistics(paper_log: SimulatedLog) -> None:
    """Each odometry increment is the true one plus the motion model's noise.

    The heading change of a step is rot1 + rot2, so its error has variance v_rot1 + v_rot2;
    on driving steps (true rot1 = rot2 = 0) the translation error has variance v_trans. The
    standardised errors must be N(0, 1): mean within 5 / sqrt(n), variance within
    5 sqrt(2 / n) of 1.
    """
    noise = SimulationConfig().odometry_noise
    odom, truth = paper_log.odometry, paper_log.true_poses
    z_heading, z_trans = [], []
    for k in range(1, len(paper_log)):
        true_inc = increment_between(truth[k - 1], truth[k])
        v1, vt, v2 = true_inc.variances(noise)
        d_true = float(diff(truth[k, 2], truth[k - 1, 2]))
        d_odom = float(diff(odom[k, 2], odom[k - 1, 2]))
        z_heading.append(float(diff(d_odom, d_true)) / np.sqrt(v1 + v2))
        if true_inc.trans > 0.01:
            odom_inc = increment_between(odom[k - 1], odom[k])
            z_trans.append((odom_inc.trans - true_inc.trans) / np.sqrt(vt))
    for z in (np.array(z_heading), np.array(z_trans)):
        n = z.size
        assert n > 50
        assert abs(z.mean()) < 5 / np.sqrt(n)
        assert abs(z.var() - 1.0) < 5 * np.sqrt(2 / n)


def test_drive_waypoints_reaches_each_waypoint_within_speed_limits() -> None:
    cfg = SimulationConfig(rate_hz=10.0, speed_mps=0.3, turn_rate_rps=0.6)
    start = np.array([1.0, 1.0, 0.0])
    waypoints = [np.array([3.0, 1.0]), np.array([3.0, 2.5]), np.array([1.0, 1.2, np.pi])]
    path = drive_waypoints(start, waypoints, cfg)
    assert np.array_equal(path[0], start)
    dt = 1.0 / cfg.rate_hz
    steps = np.hypot(*np.diff(path[:, :2], axis=0).T)
    turns = np.abs(diff(path[1:, 2], path[:-1, 2]))
    assert np.all(steps <= cfg.speed_mps * dt + 1e-12)
    assert np.all(turns <= cfg.turn_rate_rps * dt + 1e-12)
    # Turn on the spot, or drive straight: never both in one step.
    assert not np.any((steps > 1e-12) & (turns > 1e-12))
    # While driving, the robot faces where it goes.
    moving = steps > 1e-12
    direction = np.arctan2(*np.diff(path[:, :2], axis=0)[moving][:, ::-1].T)
    np.testing.assert_allclose(diff(direction, path[1:, 2][moving]), 0.0, atol=1e-9)
    # Each waypoint is reached, in order.
    last = 0
    for wp in waypoints:
        d = np.hypot(*(path[last:, :2] - wp[:2]).T)
        hit = int(np.argmax(d < 1e-9))
        assert d[hit] < 1e-9, f"waypoint {wp} not reached"
        last += hit
    assert float(diff(path[-1, 2], np.pi)) == pytest.approx(0.0, abs=1e-9)
    # Full speed except for the last fraction of a leg: 2 m at 0.03 m per step is 67 steps.
    assert np.count_nonzero(np.isclose(steps, 2.0 / 67)) == 67


def test_scenario_lookup() -> None:
    assert get_scenario("paper", "marked-hall", 2).world == "marked-hall"
    assert get_scenario("paper", None, 2).start_room == 2
    assert get_scenario("office").world == "small-office"
    with pytest.raises(ConfigError):
        get_scenario("nowhere")
    with pytest.raises(ConfigError):
        get_scenario("paper", "no-such-world")
    with pytest.raises(ConfigError):
        paper_scenario(4)
    with pytest.raises(ConfigError):
        paper_scenario(0, "small-office")


def test_simulation_config_validation() -> None:
    with pytest.raises(ValueError):
        SimulationConfig(rate_hz=0.0)
    with pytest.raises(ValueError):
        SimulationConfig(random_reading_prob=1.5)
    with pytest.raises(ValueError):
        SimulationConfig(range_sigma_m=-0.1)


@pytest.mark.parametrize(("rng", "got"), [(1, "int"), (None, "None")])
def test_simulate_refuses_a_seed_for_a_generator(rng: object, got: str) -> None:
    """``scenario.simulate(1)`` failed inside the odometry model ('int' object has no
    attribute 'standard_normal'); the simulator and free-space sampling say what to pass."""
    from ceamcl.errors import InputTypeError

    sc = paper_scenario(start_room=0, world="symmetric-hall")
    message = rf"^rng: expected numpy.random.Generator, got {got}; use numpy.random.default_rng"
    for call in (
        lambda: sc.simulate(rng),  # type: ignore[arg-type]
        lambda: Simulator(sc.grid()).run(sc.true_path(), rng),  # type: ignore[arg-type]
        lambda: sc.grid().sample_free_poses(3, rng),  # type: ignore[arg-type]
    ):
        with pytest.raises(InputTypeError, match=message):
            call()
