"""Tests of the laser models (likelihood field, beam model), scans and the fitness scale."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from ceamcl.maps.grid import FREE, OCCUPIED, OccupancyGrid
from ceamcl.maps.worlds import get_world
from ceamcl.sensors import (
    BeamModel,
    BeamModelConfig,
    LaserGeometry,
    LaserScan,
    LikelihoodFieldConfig,
    LikelihoodFieldModel,
    fitness,
)
from ceamcl.sensors.scan import laser_poses, prepare_scan, select_beam_indices
from ceamcl.simulation import (
    SimulatedLog,
    SimulationConfig,
    Simulator,
    office_scenario,
    paper_scenario,
)

Model = LikelihoodFieldModel | BeamModel
MODELS: dict[str, Callable[[OccupancyGrid], Model]] = {
    "likelihood-field": LikelihoodFieldModel,
    "beam": BeamModel,
}


@pytest.fixture(scope="module")
def paper_log() -> SimulatedLog:
    return paper_scenario(0).simulate(np.random.default_rng(1))


@pytest.fixture(scope="module")
def office_log() -> SimulatedLog:
    return office_scenario().simulate(np.random.default_rng(2))


def perturbed_poses(pose: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` poses at least 0.15 m or 0.1 rad away from ``pose`` (and at most 0.6 m, 0.4 rad):
    a third moved only in position, a third only in heading, a third in both."""
    out: list[np.ndarray] = []
    while len(out) < n:
        kind = len(out) % 3
        dist = rng.uniform(0.15, 0.6) if kind != 1 else 0.0
        direction = rng.uniform(-np.pi, np.pi)
        dth = rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.4) if kind != 0 else 0.0
        out.append(pose + np.array([dist * np.cos(direction), dist * np.sin(direction), dth]))
    return np.array(out)


@pytest.mark.parametrize("model_name", list(MODELS))
@pytest.mark.parametrize("scenario", ["paper", "office"])
def test_true_pose_scores_highest(
    model_name: str, scenario: str, paper_log: SimulatedLog, office_log: SimulatedLog
) -> None:
    log = paper_log if scenario == "paper" else office_log
    grid = get_world(log.world)
    model = MODELS[model_name](grid)
    rng = np.random.default_rng(20)
    for k in np.linspace(0, len(log) - 1, 6).astype(int):
        truth = log.true_poses[k]
        others = perturbed_poses(truth, 200, rng)
        prepared = model.prepare(log.scan(k))
        ll = model.log_likelihood(np.vstack([truth, others]), prepared)
        assert np.all(np.isfinite(ll))
        assert ll[0] > ll[1:].max(), f"step {k}: a perturbed pose beats the truth"


@pytest.mark.parametrize("model_name", list(MODELS))
def test_compiled_log_likelihood_equals_reference(
    model_name: str, office_log: SimulatedLog
) -> None:
    rng = np.random.default_rng(21)
    office = get_world("small-office")
    # A yawed, shifted copy of the office exercises the world <-> grid transforms.
    moved = OccupancyGrid(office.data, office.resolution, (3.0, -1.0, 0.8), name="moved")
    for grid in (office, moved):
        model = MODELS[model_name](grid)
        poses = grid.sample_free_poses(300, rng)
        for k in (0, len(office_log) // 2):
            scan = office_log.scan(k)
            prepared = model.prepare(scan)
            fast = model.log_likelihood(poses, prepared)
            ref = model.log_likelihood_reference(poses, prepared)
            np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=0)
            assert fast.std() > 1.0  # the poses really score differently


def test_moved_map_scores_moved_poses_the_same() -> None:
    # Moving the map and the poses together changes nothing: the origin transform is honoured.
    office = get_world("small-office")
    origin = (3.0, -1.0, 0.8)
    moved = OccupancyGrid(office.data, office.resolution, origin)
    log = office_scenario().simulate(np.random.default_rng(22))
    poses = log.true_poses[::40]
    c, s = np.cos(origin[2]), np.sin(origin[2])
    moved_poses = np.column_stack(
        [
            origin[0] + c * poses[:, 0] - s * poses[:, 1],
            origin[1] + s * poses[:, 0] + c * poses[:, 1],
            poses[:, 2] + origin[2],
        ]
    )
    for factory in MODELS.values():
        a, b = factory(office), factory(moved)
        for k in range(0, len(log), 40):
            p = a.prepare(log.scan(k))
            np.testing.assert_allclose(
                a.log_likelihood(poses, p), b.log_likelihood(moved_poses, p), atol=1e-6
            )


@pytest.mark.parametrize("model_name", list(MODELS))
def test_fitness_in_unit_interval_and_high_at_the_truth(
    model_name: str, paper_log: SimulatedLog, office_log: SimulatedLog
) -> None:
    # Truth fitness: the geometric mean of per-beam likelihood over its maximum. With 2 cm range
    # noise against sigma_hit = 0.2 m a true beam loses ~exp(-0.5 * (0.02^2 + 0.025^2)/0.04)
    # ~ 0.99; a random reading (1% of beams, ~0.6 of 60) loses at most ~exp(-5.7). Falling
    # below 0.7 needs ~4 random readings among 60 beams: Poisson(0.6) tail ~ 3e-3 per scan.
    rng = np.random.default_rng(23)
    for log in (paper_log, office_log):
        grid = get_world(log.world)
        model = MODELS[model_name](grid)
        for k in np.linspace(0, len(log) - 1, 5).astype(int):
            prepared = model.prepare(log.scan(k))
            poses = np.vstack([log.true_poses[k], grid.sample_free_poses(500, rng)])
            fit = fitness(model.log_likelihood(poses, prepared), prepared, model)
            assert np.all((fit > 0.0) & (fit <= 1.0))
            assert fit[0] > 0.7
            assert np.median(fit[1:]) < fit[0]


def test_fitness_is_one_for_a_perfect_match_and_without_beams() -> None:
    grid = get_world("small-office")
    lf = LikelihoodFieldModel(grid)
    geom = LaserGeometry.covering(np.pi, 7, 8.0)
    pose = np.array([[3.0, 3.0, 0.0]])
    empty = lf.prepare(geom.scan(np.full(7, np.nan)))
    assert empty.n_beams == 0
    assert np.array_equal(fitness(lf.log_likelihood(pose, empty), empty, lf), [1.0])
    # Perfect match: a per-beam log-likelihood equal to the maximum gives fitness exactly 1.
    one_beam = lf.prepare(LaserGeometry.covering(0.0, 1, 8.0).scan([1.0]))
    ll_max = np.array([lf.max_log_beam_likelihood(one_beam)])
    assert fitness(ll_max, one_beam, lf)[0] == pytest.approx(1.0)


def corridor_grid() -> OccupancyGrid:
    """A wall 2 m ahead of the origin pose: x in [2.0, 2.1), all y; 0.05 m cells."""
    data = np.full((80, 80), FREE, dtype=np.int8)
    data[:, 40:42] = OCCUPIED
    return OccupancyGrid(data, 0.05, (0.0, -2.0, 0.0))


def test_beam_model_matches_the_mixture_by_hand() -> None:
    grid = corridor_grid()
    cfg = BeamModelConfig(max_beams=10, temper=1.0)  # the mixture itself, untempered
    model = BeamModel(grid, cfg)
    pose = np.array([[0.0, 0.025, 0.0]])  # expected range straight ahead: 2.0 m
    a_hit = cfg.z_hit / (cfg.sigma_hit_m * math.sqrt(2 * math.pi))
    c_rand = cfg.z_rand / 8.0

    def by_hand(r: float, expected: float, is_max: bool) -> float:
        z = r - expected
        p = a_hit * math.exp(-z * z / (2 * cfg.sigma_hit_m**2))
        if z < 0:
            p += cfg.z_short * cfg.lambda_short * math.exp(-cfg.lambda_short * r)
        p += cfg.z_max if is_max else c_rand
        return math.log(p)

    geom = LaserGeometry.covering(0.0, 1, 8.0)
    cases = [
        (2.01, False),  # a hit, 1 cm long (exactly 2.0 would sit on the short term's step)
        (1.97, False),  # a hit, 3 cm short: Gaussian plus the short term
        (2.3, False),  # long: Gaussian tail + random
        (1.2, False),  # short: an unexpected obstacle
        (8.0, True),  # max-range reading where a wall should be
        (float("inf"), True),  # also max range (REP 117: no return within range)
    ]
    for r, is_max in cases:
        prepared = model.prepare(geom.scan([r]))
        assert prepared.is_max.tolist() == [is_max]
        got = model.log_likelihood(pose, prepared)[0]
        want = by_hand(8.0 if is_max else r, 2.0, is_max)
        # The ray caster enters the wall up to a few 1e-9 m past its face (its DDA steps
        # overshoot cell boundaries by 1e-9 m); d log p / d r* is below 1 / m here, so the
        # values agree to ~1e-8.
        assert got == pytest.approx(want, abs=1e-7), (r, got, want)
    # Looking away from the wall, nothing is expected within range: a max-range reading is
    # the best possible reading (hit term at z = 0 plus z_max).
    away = np.array([[0.0, 0.025, np.pi]])
    prepared = model.prepare(geom.scan([8.0]))
    assert model.log_likelihood(away, prepared)[0] == pytest.approx(
        math.log(a_hit + cfg.z_max), rel=1e-9
    )


def test_likelihood_field_matches_the_mixture_by_hand() -> None:
    grid = corridor_grid()
    cfg = LikelihoodFieldConfig(max_beams=10, temper=1.0)  # the mixture itself, untempered
    model = LikelihoodFieldModel(grid, cfg)
    a_hit = cfg.z_hit / (cfg.sigma_hit_m * math.sqrt(2 * math.pi))
    c_rand = cfg.z_rand / 8.0
    geom = LaserGeometry.covering(0.0, 1, 8.0)
    pose = np.array([[0.0, 0.025, 0.0]])
    for r, d in [(2.01, 0.0), (1.72, 0.3), (1.0, 1.0), (4.5, 2.0), (3.0, 0.95)]:
        # End point at x = r; the nearest obstacle cell centre is at x = 2.025 (or 2.075
        # beyond the wall): d is the distance between cell centres; 4.5 m is off the map and
        # gets the 2 m cap.
        prepared = model.prepare(geom.scan([r]))
        got = model.log_likelihood(pose, prepared)[0]
        want = math.log(a_hit * math.exp(-d * d / (2 * cfg.sigma_hit_m**2)) + c_rand)
        assert got == pytest.approx(want, rel=1e-9, abs=1e-12), (r, got, want)


@pytest.mark.parametrize(
    ("offset", "centre"),
    [(None, 0.0), (0.0, 0.025)],  # the default (half a 5 cm cell), and ROS amcl's lookup
)
def test_the_likelihood_field_centres_a_wall_reading_on_the_pose_that_made_it(
    offset: float | None, centre: float
) -> None:
    """A beam ends on a wall's face, but the field measures to the occupied cell's centre,
    half a cell behind it (docs/sensor-models.md). Read half a cell farther, the poses that
    score best lie evenly about the pose that made the reading; as ROS amcl reads it, they lie
    half a cell ahead of it."""
    data = np.full((80, 80), FREE, dtype=np.int8)
    data[:, 40] = OCCUPIED  # a wall one cell thick, its face at x = 2.0
    grid = OccupancyGrid(data, 0.05, (0.0, -2.0, 0.0))
    model = LikelihoodFieldModel(
        grid, LikelihoodFieldConfig(max_beams=1, temper=1.0, end_point_offset_m=offset)
    )
    prepared = model.prepare(LaserGeometry.covering(0.0, 1, 8.0).scan([2.0]))
    shifts = np.round(np.arange(-0.1, 0.1001, 0.001), 3)  # the pose moved along the beam
    poses = np.column_stack([shifts + 1e-6, np.full_like(shifts, 0.025), np.zeros_like(shifts)])
    scores = model.log_likelihood(poses, prepared)
    best = shifts[scores >= scores.max() - 1e-12]
    assert best.max() - best.min() == pytest.approx(0.049, abs=0.0011)  # one cell
    assert (best.min() + best.max()) / 2 == pytest.approx(centre, abs=0.0011)


def test_the_end_point_offset_is_checked() -> None:
    with pytest.raises(ValueError, match="end_point_offset_m"):
        LikelihoodFieldConfig(end_point_offset_m=-0.01)
    with pytest.raises(ValueError, match="end_point_offset_m"):
        LikelihoodFieldConfig(end_point_offset_m=math.nan)


def scan_with(ranges: np.ndarray, base: LaserScan) -> LaserScan:
    return replace(base, ranges=np.asarray(ranges, dtype=np.float64))


def test_likelihood_field_skips_max_range_readings(office_log: SimulatedLog) -> None:
    grid = get_world("small-office")
    model = LikelihoodFieldModel(grid, LikelihoodFieldConfig(max_beams=181))
    scan = office_log.scan(100)
    rng = np.random.default_rng(24)
    poses = np.vstack([office_log.true_poses[100], grid.sample_free_poses(100, rng)])
    ranges = scan.ranges.copy()
    chosen = rng.choice(ranges.size, 30, replace=False)
    scores = []
    # REP 117: max range and +inf are "no return"; beyond range_max, below range_min and
    # -inf are invalid. The likelihood field drops all of them.
    for value in (scan.range_max, np.inf, 1e6, 0.0, -np.inf, -1.0):
        r = ranges.copy()
        r[chosen] = value
        prepared = model.prepare(scan_with(r, scan))
        usable = (r >= scan.range_min) & (r < scan.range_max)
        assert prepared.n_beams == np.count_nonzero(usable) <= ranges.size - chosen.size
        scores.append(model.log_likelihood(poses, prepared))
    for s in scores[1:]:
        assert np.array_equal(s, scores[0])
    # ... exactly as if those beams had not been measured at all.
    r = ranges.copy()
    r[chosen] = np.nan
    assert np.array_equal(model.log_likelihood(poses, model.prepare(scan_with(r, scan))), scores[0])


def test_beam_model_scores_max_range_readings_with_z_max(office_log: SimulatedLog) -> None:
    grid = get_world("small-office")
    cfg = BeamModelConfig(max_beams=181)
    model = BeamModel(grid, cfg)
    scan = office_log.scan(100)
    rng = np.random.default_rng(25)
    poses = np.vstack([office_log.true_poses[100], grid.sample_free_poses(50, rng)])
    chosen = rng.choice(scan.n_beams, 30, replace=False)
    results = []
    for value in (scan.range_max, np.inf):  # REP 117: both mean "no return within range"
        r = scan.ranges.copy()
        r[chosen] = value
        prepared = model.prepare(scan_with(r, scan))
        assert prepared.n_beams == scan.n_beams  # kept, unlike the likelihood field
        results.append(model.log_likelihood(poses, prepared))
    for s in results[1:]:
        assert np.array_equal(s, results[0])
    # A smaller z_max makes every pose less likely (max-range readings where the map expects
    # a wall are explained only by z_max), so they really are scored with the z_max term; the
    # scan without the injected max-range readings does not depend on z_max at all here.
    small_max = BeamModel(grid, replace(cfg, z_max=1e-6))
    r = scan.ranges.copy()
    r[chosen] = scan.range_max
    lowered = small_max.log_likelihood(poses, small_max.prepare(scan_with(r, scan)))
    assert np.all(lowered < results[0])
    clean = scan.ranges < scan.range_max
    if clean.all():
        np.testing.assert_allclose(
            small_max.log_likelihood(poses, small_max.prepare(scan)),
            model.log_likelihood(poses, model.prepare(scan)),
            rtol=1e-12,
        )


@pytest.mark.parametrize("model_name", list(MODELS))
def test_nan_ranges_are_skipped(model_name: str, office_log: SimulatedLog) -> None:
    grid = get_world("small-office")
    model: Model = (
        LikelihoodFieldModel(grid, LikelihoodFieldConfig(max_beams=181))
        if model_name == "likelihood-field"
        else BeamModel(grid, BeamModelConfig(max_beams=181))
    )
    scan = office_log.scan(50)
    rng = np.random.default_rng(26)
    poses = np.vstack([office_log.true_poses[50], grid.sample_free_poses(20, rng)])
    r = scan.ranges.copy()
    nan_idx = rng.choice(r.size, 40, replace=False)
    r[nan_idx] = np.nan
    with_nan = scan_with(r, scan)
    prepared = model.prepare(with_nan)
    assert not np.any(np.isnan(prepared.ranges))
    assert not np.any(np.isin(prepared.source_indices, nan_idx))
    total = model.log_likelihood(poses, prepared)
    assert np.all(np.isfinite(total))
    # Beams are independent: the total equals the sum of one-beam scans over the non-NaN beams.
    angles = scan.angles
    per_beam = np.zeros(poses.shape[0])
    for j in range(r.size):
        is_max = r[j] <= scan.range_min or r[j] >= scan.range_max
        if np.isnan(r[j]) or (model_name == "likelihood-field" and is_max):
            continue
        one = LaserScan(np.array([r[j]]), angles[j], 0.0, scan.range_min, scan.range_max, scan.pose)
        per_beam += model.log_likelihood(poses, model.prepare(one))
    np.testing.assert_allclose(total, per_beam, rtol=1e-9)


def test_max_beams_subsampling_keeps_first_and_last_beam() -> None:
    for n_total, max_beams in [(181, 60), (181, 2), (1000, 37), (361, 180), (61, 60)]:
        idx = select_beam_indices(n_total, max_beams)
        assert idx[0] == 0 and idx[-1] == n_total - 1
        assert idx.size == max_beams
        assert np.all(np.diff(idx) > 0)
        gaps = np.diff(idx)
        assert gaps.max() - gaps.min() <= 1  # evenly spread
    assert np.array_equal(select_beam_indices(50, 60), np.arange(50))
    assert np.array_equal(select_beam_indices(181, 1), [90])
    with pytest.raises(ValueError):
        select_beam_indices(10, 0)


@pytest.mark.parametrize("model_name", list(MODELS))
def test_only_the_selected_beams_are_scored(model_name: str, office_log: SimulatedLog) -> None:
    grid = get_world("small-office")
    model = MODELS[model_name](grid)  # default max_beams = 60 of 181
    scan = office_log.scan(10)
    prepared = model.prepare(scan)
    assert prepared.source_indices[0] == 0 and prepared.source_indices[-1] == scan.n_beams - 1
    assert prepared.n_beams <= 60
    np.testing.assert_array_equal(prepared.bearings, scan.angles[prepared.source_indices])
    poses = office_log.true_poses[[10, 20, 30]]
    # Corrupting every beam that was not selected changes nothing.
    r = scan.ranges.copy()
    unselected = np.setdiff1d(np.arange(r.size), select_beam_indices(r.size, 60))
    r[unselected] = 0.5
    np.testing.assert_array_equal(
        model.log_likelihood(poses, model.prepare(scan_with(r, scan))),
        model.log_likelihood(poses, prepared),
    )


def test_prepare_scan_classifies_readings() -> None:
    geom = LaserGeometry.covering(np.pi, 7, 8.0, range_min=0.1)
    scan = geom.scan([1.0, np.nan, 8.0, np.inf, 0.05, -np.inf, 7.99])
    kept = prepare_scan(scan, 100, keep_max_range=True)
    # REP 117: NaN and -inf (too close) are no measurement, 0.05 < range_min is invalid;
    # range_max and +inf are "no return within range" (max-range readings).
    assert kept.source_indices.tolist() == [0, 2, 3, 6]
    assert kept.is_max.tolist() == [False, True, True, False]
    assert kept.ranges.tolist() == [1.0, 8.0, 8.0, 7.99]
    dropped = prepare_scan(scan, 100, keep_max_range=False)
    assert dropped.source_indices.tolist() == [0, 6]
    assert dropped.n_beams == 2


@pytest.mark.parametrize("model_name", list(MODELS))
def test_laser_mounting_pose_matters(model_name: str) -> None:
    # Simulate with the laser 0.5 m ahead of the robot's centre.
    offset = (0.5, 0.0, 0.0)
    laser = LaserGeometry.covering(np.pi, 181, 8.0, pose=offset)
    cfg = SimulationConfig(laser=laser)
    sc = paper_scenario(0, config=cfg)
    grid = sc.grid()
    log = Simulator(grid, cfg).run(sc.true_path()[::25], np.random.default_rng(27))
    assert log.laser.pose == offset
    model = MODELS[model_name](grid)
    for k in range(len(log)):
        right = log.scan(k)
        wrong = replace(right, pose=(0.0, 0.0, 0.0))
        truth = log.true_poses[k : k + 1]
        ll_right = model.log_likelihood(truth, model.prepare(right))[0]
        ll_wrong = model.log_likelihood(truth, model.prepare(wrong))[0]
        assert ll_right > ll_wrong
        # Ignoring the mounting is the same as moving the robot to where the laser is.
        at_laser = laser_poses(truth, offset)
        ll_shifted = model.log_likelihood(at_laser, model.prepare(wrong))[0]
        assert ll_shifted == pytest.approx(ll_right, abs=1e-6)


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ("LikelihoodFieldConfig", "max_occ_dist_m"),
        ("LikelihoodFieldConfig", "z_hit"),
        ("LikelihoodFieldConfig", "sigma_hit_m"),
        ("BeamModelConfig", "z_hit"),
        ("BeamModelConfig", "lambda_short"),
        ("BeamModelConfig", "z_short"),
    ],
)
def test_a_sensor_parameter_that_is_not_finite_is_refused_naming_it(
    config: str, field: str
) -> None:
    # inf passed the '> 0' checks: an OverflowError while building the field, or +inf / NaN
    # likelihoods that sent every filter back to global localisation at every scan
    import ceamcl.sensors.beam_model as beam
    import ceamcl.sensors.likelihood_field as lf

    cls = getattr(lf if config.startswith("Likelihood") else beam, config)
    for value in (float("inf"), float("nan")):
        with pytest.raises(ValueError, match=f"{field}: expected a finite number"):
            cls(**{field: value})
