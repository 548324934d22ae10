"""Scan readings as sensor_msgs/LaserScan and REP 117 define them, through every filter."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.errors import CeamclError
from ceamcl.filters import ALGORITHMS
from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.sensors.scan import (
    LaserGeometry,
    LaserScan,
    PreparedScan,
    classify_ranges,
    prepare_scan,
    prepare_scan_reference,
)
from tests.robustness._filters import assert_all_finite, small_filter, small_sensor
from tests.robustness.conftest import box_grid

GEOM = LaserGeometry.covering(np.pi, 9, 4.0, range_min=0.1)


def test_each_reading_class_follows_rep_117() -> None:
    readings = [1.0, np.nan, np.inf, -np.inf, 0.0, -1.0, 0.05, 4.0, 4.5, 0.1, 3.99]
    geom = LaserGeometry.covering(np.pi, len(readings), 4.0, range_min=0.1)
    scan = geom.scan(readings)
    usable, is_max = classify_ranges(scan.ranges, scan.range_min, scan.range_max)
    # hit: 1.0, range_min itself, 3.99; max range: +inf and exactly range_max.
    assert np.flatnonzero(usable & ~is_max).tolist() == [0, 9, 10]
    assert np.flatnonzero(is_max).tolist() == [2, 7]
    kept = prepare_scan(scan, 100, keep_max_range=True)
    assert kept.source_indices.tolist() == [0, 2, 7, 9, 10]
    assert kept.ranges.tolist() == [1.0, 4.0, 4.0, 0.1, 3.99]
    assert kept.is_max.tolist() == [False, True, True, False, False]
    assert (kept.n_nan, kept.n_too_close, kept.n_invalid, kept.n_max_range) == (1, 1, 4, 2)
    dropped = prepare_scan(scan, 100, keep_max_range=False)
    assert dropped.source_indices.tolist() == [0, 9, 10]
    assert dropped.n_beams == 3 and dropped.informative
    for prepared in (kept, dropped, prepare_scan(scan, 4, keep_max_range=True)):
        np.testing.assert_array_equal(prepared.bearings, scan.angles[prepared.source_indices])


def _fields(p: PreparedScan) -> tuple[object, ...]:
    arrays = (p.ranges, p.bearings, p.is_max, p.source_indices)
    counts = (p.range_max, p.laser_pose, p.n_beams, p.n_nan, p.n_too_close, p.n_invalid)
    return (
        tuple(a.tolist() for a in arrays)
        + tuple(a.dtype for a in arrays)
        + counts
        + (p.n_max_range,)
    )


@pytest.mark.parametrize("seed", range(6))
def test_the_compiled_preparation_equals_the_numpy_reference(seed: int) -> None:
    """Every reading class, every selection size, both max-range policies, field for field
    (dtypes included); the selected arrays are the scan's own values, never views into it."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, -1.0, 0.01, 8.0, 9.5])
    r = rng.uniform(0.0, 9.0, n)
    hit = rng.random(n) < 0.3
    r[hit] = rng.choice(specials, int(hit.sum()))
    scan = LaserScan(r, -2.0, 4.0 / max(n, 1), 0.02, 8.0, (0.1, -0.05, 0.2), 3.0)
    for max_beams in (1, 2, 7, 60, n, n + 5):
        for keep in (True, False):
            fast = prepare_scan(scan, max_beams, keep_max_range=keep)
            assert _fields(fast) == _fields(
                prepare_scan_reference(scan, max_beams, keep_max_range=keep)
            )
            before = scan.ranges.copy()
            fast.ranges[:] = -7.0
            np.testing.assert_array_equal(scan.ranges, before)


@pytest.mark.parametrize("model", ["likelihood-field", "beam"])
def test_invalid_readings_count_as_unmeasured(model: str) -> None:
    """Replacing a beam by NaN, -inf, 0, a negative or a beyond-maximum reading scores every
    pose exactly as leaving that beam out."""
    grid = box_grid()
    sensor = small_sensor(model, grid, max_beams=100)
    rng = np.random.default_rng(5)
    poses = grid.sample_free_poses(40, rng)
    base = np.array([1.0, 2.0, 1.5, 0.7, 2.5, 3.0, 1.2, 0.9, 2.2])
    without = LaserScan(np.delete(base, 3), GEOM.angle_min, GEOM.angle_increment, 0.1, 4.0)
    # The same beams with the original bearings: drop beam 3 by giving it a bad value instead.
    reference = None
    for bad in (np.nan, -np.inf, 0.0, -2.0, 0.05, 4.0001, 1e9):
        r = base.copy()
        r[3] = bad
        scored = sensor.log_likelihood(poses, sensor.prepare(GEOM.scan(r)))
        if reference is None:
            reference = scored
        np.testing.assert_array_equal(scored, reference)
    assert reference is not None
    # And the dropped beam really changed something compared to a valid reading there.
    assert not np.array_equal(
        reference, sensor.log_likelihood(poses, sensor.prepare(GEOM.scan(base)))
    )
    assert without.n_beams == 8


def test_scan_with_bad_limits_is_a_project_error() -> None:
    for kwargs in (
        {"range_min": 0.0, "range_max": 0.0},
        {"range_min": 0.0, "range_max": float("nan")},
        {"range_min": -1.0, "range_max": 4.0},
        {"range_min": 5.0, "range_max": 4.0},
        {"range_min": 0.0, "range_max": float("inf")},
    ):
        with pytest.raises(CeamclError, match="scan: range_"):
            LaserScan(np.ones(3), 0.0, 0.1, **kwargs)
    with pytest.raises(CeamclError, match="angle_increment"):
        LaserScan(np.ones(3), 0.0, float("nan"), 0.0, 4.0)
    with pytest.raises(CeamclError, match="ranges"):
        LaserScan(np.array(["a", "b"]), 0.0, 0.1, 0.0, 4.0)
    # a 2-D array is not read as one scan of twice the beams at the wrong bearings
    with pytest.raises(CeamclError, match=r"ranges: expected a 1-D .* shape \(181, 2\)"):
        LaserScan(np.ones((181, 2)), 0.0, 0.1, 0.0, 4.0)
    assert LaserScan(2.0, 0.0, 0.1, 0.0, 4.0).n_beams == 1  # one number is one reading


NO_INFORMATION = {
    "all NaN": [np.nan] * 9,
    "all -inf": [-np.inf] * 9,
    "all invalid": [0.0, -1.0, 0.05, 5.0, 1e9, 0.0, -0.0, 4.5, 100.0],
    "empty": [],
}


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("case", list(NO_INFORMATION))
def test_a_scan_without_usable_beams_leaves_the_weights_unchanged(
    algorithm: str, case: str
) -> None:
    grid = box_grid()
    sensor = small_sensor("likelihood-field", grid)
    f = small_filter(algorithm, grid, np.random.default_rng(7), sensor, resample_ess_fraction=0.0)
    good = GEOM.scan([1.0, 2.0, 1.5, 0.7, 2.5, 3.0, 1.2, 0.9, 2.2])
    f.initialise_global(good)
    f.step(OdometryIncrement(0.0, 0.0, 0.0), good)
    empty = (
        GEOM.scan(NO_INFORMATION[case])
        if NO_INFORMATION[case]
        else LaserScan(np.zeros(0), 0.0, 0.01, 0.1, 4.0)
    )
    assert sensor.prepare(empty).n_beams == 0
    # CEAMCL applies the dN of the last real scan at the start of the next step (the paper's
    # order); from then on nothing changes while the laser says nothing.
    f.step(OdometryIncrement(0.0, 0.0, 0.0), empty)
    before = f.particles()
    hyps_before = [(h.label, h.n_particles, h.fitness) for h in f.hypotheses()]
    for _ in range(3):
        diag = f.step(OdometryIncrement(0.0, 0.0, 0.0), empty)
        assert not diag.reinitialised
        assert diag.likelihood_evaluations == 0  # the scan was not used at all
        assert_all_finite(f)
    after = f.particles()
    if algorithm in ("mcl", "gmcl"):
        # No motion (a zero increment has zero noise), no resampling, no weighting, no
        # genetic operators: particles and weights are exactly as they were.
        np.testing.assert_array_equal(after.poses, before.poses)
        np.testing.assert_array_equal(after.weights, before.weights)
    if algorithm == "ceamcl":
        # Sizes freeze and every species keeps its size and its fitness.
        assert [(h.label, h.n_particles, h.fitness) for h in f.hypotheses()] == hyps_before
        assert after.poses.shape == before.poses.shape


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("model", ["likelihood-field", "beam"])
def test_global_start_on_a_scan_without_usable_beams(algorithm: str, model: str) -> None:
    grid = box_grid()
    sensor = small_sensor(model, grid)
    f = small_filter(algorithm, grid, np.random.default_rng(8), sensor)
    f.initialise_global(GEOM.scan([np.nan] * 9))
    assert f.particles().poses.shape[0] > 0
    assert_all_finite(f)
    # Particles spread over the free space: no information, no preference.
    xy = f.particles().poses[:, :2]
    assert np.ptp(xy[:, 0]) > 1.0 and np.ptp(xy[:, 1]) > 1.0
