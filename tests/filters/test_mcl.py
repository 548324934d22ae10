"""Tests of Monte Carlo localisation (``ceamcl.filters.mcl``) on simulated runs."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from ceamcl.filters import MCL, MCLConfig, make_filter
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel, increment_between
from ceamcl.runner import run_filter, timed_step
from ceamcl.sensors import LaserScan, LikelihoodFieldConfig, LikelihoodFieldModel, PreparedScan
from ceamcl.simulation import SimulatedLog, office_scenario, paper_scenario


def generators(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent simulation and filter generators from one seed."""
    sim, filt = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(sim), np.random.default_rng(filt)


def head(log: SimulatedLog, n: int) -> SimulatedLog:
    return SimulatedLog(
        log.times[:n], log.true_poses[:n], log.odometry[:n], log.ranges[:n], log.laser, log.world
    )


def test_tracking_from_a_known_start_on_marked_hall() -> None:
    sc = paper_scenario(0, "marked-hall")
    grid = sc.grid()
    sim_rng, filter_rng = generators(50)
    log = sc.simulate(sim_rng, grid)
    f = make_filter("mcl", grid, filter_rng)
    f.initialise_pose(log.true_poses[0], np.diag([0.1**2, 0.1**2, 0.05**2]))
    est0 = f.estimate()
    # 5000 particles from N(start, 0.1 m): the mean is within 5 SE = 5 * 0.1 / sqrt(5000).
    assert np.hypot(*(est0.pose[:2] - log.true_poses[0, :2])) < 5 * 0.1 * np.sqrt(2 / 5000)
    np.testing.assert_allclose(np.sqrt(np.diag(est0.covariance)), [0.1, 0.1, 0.05], rtol=0.05)
    errors = np.zeros(len(log))
    heading_errors = np.zeros(len(log))
    for k in range(1, len(log)):
        inc = increment_between(log.odometry[k - 1], log.odometry[k])
        diag = timed_step(f, k, inc, log.scan(k))
        assert diag.step == k and not diag.reinitialised
        e = f.estimate().pose
        errors[k] = np.hypot(*(e[:2] - log.true_poses[k, :2]))
        heading_errors[k] = abs(np.angle(np.exp(1j * (e[2] - log.true_poses[k, 2]))))
    settled = log.times >= 10.0
    assert settled.sum() > 200
    assert errors[settled].max() < 0.2
    assert heading_errors[settled].max() < 0.1
    # Odometry alone drifts; the filter does better than dead reckoning at the end.
    odom_error = np.hypot(*(log.odometry[-1, :2] - log.true_poses[-1, :2]))
    assert errors[-1] < max(odom_error, 0.05)


# Plain MCL has no recovery (no random particles): when, after the first scan, no particle lies
# near the truth, it can lock onto a look-alike place in the office corridor and stay there. With
# this seeding (SeedSequence(seed).spawn(2)) about 7 of 60 seeds failed in a survey (final error
# > 0.3 m), so a single run fails with probability ~0.1 and three runs all succeed with ~0.7.
# The seeds below are simply the first three; the test is deterministic. The survey used the
# textbook product of beams (temper 1), so does this test: with the default tempering (0.2) a
# survey of 12 seeds failed 2 (docs/sensor-models.md), against 0 of 12 untempered.
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_global_localisation_on_small_office(seed: int) -> None:
    sc = office_scenario()
    grid = sc.grid()
    sim_rng, filter_rng = generators(seed)
    log = sc.simulate(sim_rng, grid)
    sensor = LikelihoodFieldModel(grid, LikelihoodFieldConfig(temper=1.0))
    f = make_filter("mcl", grid, filter_rng, n_particles=5000, sensor=sensor)
    result = run_filter(f, log)
    assert result.steps == len(log)
    errors = result.position_errors
    assert errors is not None
    assert result.initial_particles.poses.shape == (5000, 3)
    assert errors[-1] < 0.3
    heading = result.heading_errors
    assert heading is not None and heading[-1] < 0.1


def test_same_seed_gives_identical_estimates() -> None:
    sc = office_scenario()
    grid = sc.grid()
    log = head(sc.simulate(np.random.default_rng(51), grid), 60)
    runs = []
    for _ in range(2):
        f = make_filter("mcl", grid, np.random.default_rng(52), n_particles=2000)
        runs.append(run_filter(f, log))
    a, b = runs
    assert np.array_equal(a.estimates, b.estimates)
    assert np.array_equal(a.final_particles.poses, b.final_particles.poses)
    assert all(np.array_equal(x, y) for x, y in zip(a.hypotheses, b.hypotheses, strict=True))
    f = make_filter("mcl", grid, np.random.default_rng(53), n_particles=2000)
    c = run_filter(f, log)
    assert not np.array_equal(a.estimates, c.estimates)


def check_hypotheses(f: MCL, n: int) -> int:
    hyps = f.hypotheses()
    weights = np.array([h.weight for h in hyps])
    assert weights.sum() == pytest.approx(1.0, abs=1e-9)
    assert np.all(np.diff(weights) <= 0.0)
    assert sum(h.n_particles for h in hyps) == n
    assert len({h.label for h in hyps}) == len(hyps)
    for h in hyps:
        assert 0.0 < h.fitness <= 1.0
        assert np.all(np.linalg.eigvalsh(h.covariance) >= -1e-12)
    snap = f.particles()
    np.testing.assert_allclose(snap.weights.sum(), 1.0)
    assert snap.labels.shape == (n,)
    assert set(np.unique(snap.labels)) == {h.label for h in hyps}
    return len(hyps)


def test_hypotheses_weights_sum_to_one_and_are_sorted() -> None:
    sc = paper_scenario(0)
    grid = sc.grid()
    sim_rng, filter_rng = generators(54)
    log = head(sc.simulate(sim_rng, grid), 20)
    n = 3000
    f = make_filter("mcl", grid, filter_rng, n_particles=n)
    assert isinstance(f, MCL)
    # A broad cloud over the hall: many clusters of equal-weight particles.
    f.initialise_pose([7.5, 7.5, 0.0], np.diag([3.0**2, 3.0**2, 1.0]))
    assert check_hypotheses(f, n) > 1
    # Weighted by a few scans (not necessarily resampled): still consistent.
    for k in range(1, len(log)):
        f.step(increment_between(log.odometry[k - 1], log.odometry[k]), log.scan(k))
        check_hypotheses(f, n)
    # And from a global start.
    f.initialise_global(log.scan(0))
    check_hypotheses(f, n)


class NaNSensor:
    """A broken sensor model: every pose scores NaN."""

    def __init__(self, grid: OccupancyGrid) -> None:
        self.inner = LikelihoodFieldModel(grid)

    def prepare(self, scan: LaserScan) -> PreparedScan:
        return self.inner.prepare(scan)

    def log_likelihood(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        return np.full(np.asarray(poses).reshape(-1, 3).shape[0], np.nan)

    temper = 1.0
    scoring = "product"

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        return self.inner.max_log_beam_likelihood(prepared)


def test_impossible_weights_reinitialise_without_nan() -> None:
    sc = office_scenario()
    grid = sc.grid()
    log = head(sc.simulate(np.random.default_rng(55), grid), 3)
    f = MCL(
        grid,
        OdometryMotionModel(),
        NaNSensor(grid),
        MCLConfig(n_particles=500),
        rng=np.random.default_rng(56),
    )
    f.initialise_pose(log.true_poses[0], np.diag([0.01, 0.01, 0.01]))
    diag = f.step(increment_between(log.odometry[0], log.odometry[1]), log.scan(1))
    assert diag.reinitialised
    w = f.weights
    np.testing.assert_allclose(w, 1.0 / 500)
    assert np.all(
        grid.is_free(f.particle_set.poses[:, 0], f.particle_set.poses[:, 1])
    )  # spread over free space again
    assert np.all(np.isfinite(f.estimate().pose))


def test_step_without_scan_only_predicts() -> None:
    sc = office_scenario()
    grid = sc.grid()
    f = make_filter("mcl", grid, np.random.default_rng(57), n_particles=4000)
    start = np.array([3.0, 4.25, 0.0])
    f.initialise_pose(start, np.diag([1e-4, 1e-4, 1e-4]))
    before = f.particles().weights
    diag = f.step(OdometryIncrement(0.0, 0.5, 0.0), None)
    assert diag.likelihood_evaluations == 0
    np.testing.assert_array_equal(f.particles().weights, before)
    # The cloud moved 0.5 m along x on average (SE of the mean ~ 0.23 / sqrt(4000)).
    assert f.estimate().pose[0] == pytest.approx(3.5, abs=0.02)
