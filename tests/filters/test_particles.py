"""Tests of the particle core (``ceamcl.filters.particles``): the container and the steps
every filter composes."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from ceamcl.errors import LogFormatError
from ceamcl.filters.evolution import EvolutionConfig
from ceamcl.filters.particles import (
    ParticleSet,
    evolve,
    gaussian,
    propagate,
    resample,
    resample_within_labels,
    reweight,
    uniform,
    usable,
)
from ceamcl.maps.worlds import symmetric_hall
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel, OdometryNoise
from ceamcl.sensors import LikelihoodFieldModel
from ceamcl.sensors.scan import LaserScan, PreparedScan

TRUTH = np.array([3.0, 2.0, 0.4])


class Constant:
    """A sensor model whose log-likelihood is a fixed value per pose (by x)."""

    def __init__(self, value: float | None = None) -> None:
        self.value = value

    def prepare(self, scan: LaserScan) -> PreparedScan:
        return LikelihoodFieldModel(symmetric_hall()).prepare(scan)

    def log_likelihood(self, poses: NDArray[np.float64], prepared: PreparedScan) -> NDArray:
        if self.value is not None:
            return np.full(poses.shape[0], self.value)
        return -np.abs(poses[:, 0] - TRUTH[0])

    temper = 1.0
    scoring = "product"

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        return 0.0


def scan() -> LaserScan:
    angles = np.linspace(-1.5, 1.5, 30)
    return LaserScan(np.full(angles.size, 2.0), -1.5, float(angles[1] - angles[0]), 0.1, 8.0)


def test_uniform_particles_lie_in_free_space_with_equal_weights() -> None:
    grid = symmetric_hall()
    ps = uniform(grid, 500, np.random.default_rng(0))
    assert ps.n == 500 and ps.poses.shape == (500, 3)
    assert np.all(grid.is_free(ps.poses[:, 0], ps.poses[:, 1]))
    np.testing.assert_allclose(ps.weights, 1 / 500)
    assert np.all(ps.loglik == 0) and np.all(ps.fitness == 1) and np.all(ps.labels == 0)


def test_gaussian_particles_have_the_moments_asked_for() -> None:
    cov = np.diag([0.04, 0.01, 0.0025])
    ps = gaussian(TRUTH, cov, 40_000, np.random.default_rng(1))
    # Standard error of a mean: sd / 200; of a variance: var * sqrt(2 / n) ~ var / 141.
    np.testing.assert_allclose(ps.poses.mean(axis=0), TRUTH, atol=5 * 0.2 / 200)
    np.testing.assert_allclose(ps.poses.var(axis=0), np.diag(cov), rtol=5 / 141)


def test_propagate_moves_every_particle_and_refuses_nan_odometry() -> None:
    ps = ParticleSet.from_poses(np.tile(TRUTH, (100, 1)))
    motion = OdometryMotionModel(OdometryNoise(0.0, 0.0, 0.0, 0.0))
    propagate(ps, motion, OdometryIncrement(0.0, 1.0, 0.0), np.random.default_rng(2))
    np.testing.assert_allclose(ps.poses[:, 0], TRUTH[0] + np.cos(TRUTH[2]))
    with pytest.raises(LogFormatError, match="odometry increment"):
        propagate(ps, motion, OdometryIncrement(0.0, float("nan"), 0.0), np.random.default_rng(2))


def test_reweight_multiplies_weights_by_likelihoods() -> None:
    poses = np.column_stack([np.linspace(2.0, 4.0, 5), np.full(5, 2.0), np.zeros(5)])
    ps = ParticleSet.from_poses(poses)
    prepared = Constant().prepare(scan())
    assert reweight(ps, Constant(), prepared)  # type: ignore[arg-type]
    want = np.exp(-np.abs(poses[:, 0] - TRUTH[0]))
    np.testing.assert_allclose(ps.weights, want / want.sum())
    assert ps.fitness.max() == pytest.approx(1.0)  # the pose at the truth's x


@pytest.mark.parametrize("value", [-np.inf, np.nan, np.inf])
def test_reweight_says_impossible_and_keeps_the_weights(value: float) -> None:
    ps = uniform(symmetric_hall(), 50, np.random.default_rng(3))
    before = ps.log_weights.copy()
    prepared = Constant().prepare(scan())
    assert not reweight(ps, Constant(value), prepared)  # type: ignore[arg-type]
    np.testing.assert_array_equal(ps.log_weights, before)
    assert np.all(ps.loglik == -np.inf)


def test_usable_refuses_a_missing_scan_and_one_without_beams() -> None:
    sensor = LikelihoodFieldModel(symmetric_hall())
    assert usable(sensor, None) is None
    empty = LaserScan(np.full(30, np.nan), -1.5, 0.1, 0.1, 8.0)
    assert usable(sensor, empty) is None
    got = usable(sensor, scan())
    assert got is not None and got.n_beams > 0


def test_resample_draws_by_weight_and_equalises_weights() -> None:
    poses = np.column_stack([np.arange(4.0), np.zeros(4), np.zeros(4)])
    ps = ParticleSet.from_poses(poses)
    ps.log_weights = np.array([np.log(0.7), np.log(0.3), -np.inf, -np.inf])
    for scheme in ("systematic", "multinomial"):
        q = ParticleSet.from_poses(poses.copy())
        q.log_weights = ps.log_weights.copy()
        resample(q, 1000, np.random.default_rng(4), scheme)
        counts = np.bincount(q.poses[:, 0].astype(int), minlength=4)
        assert counts[2] == counts[3] == 0
        assert abs(counts[0] - 700) < 5 * np.sqrt(1000 * 0.21)
        np.testing.assert_allclose(q.weights, 1 / 1000)


def test_resample_within_labels_keeps_each_label_to_its_target() -> None:
    rng = np.random.default_rng(5)
    poses = rng.normal(size=(30, 3))
    ps = ParticleSet.from_poses(poses, np.repeat(np.array([4, 7, 9]), 10))
    ps.loglik = rng.normal(size=30)
    members = resample_within_labels(ps, {4: 3, 7: 12}, rng)  # 9 keeps its size
    assert {k: v.size for k, v in members.items()} == {4: 3, 7: 12, 9: 10}
    for label, idx in members.items():
        assert np.all(ps.labels[idx] == label)
    assert ps.n == 25


def test_evolve_never_lowers_the_best_likelihood_and_stores_the_new_ones() -> None:
    rng = np.random.default_rng(6)
    sensor = Constant()
    poses = np.column_stack([rng.uniform(1, 5, 200), np.full(200, 2.0), np.zeros(200)])
    ps = ParticleSet.from_poses(poses)
    prepared = sensor.prepare(scan())
    reweight(ps, sensor, prepared)  # type: ignore[arg-type]
    best = ps.loglik.max()
    evals = evolve(ps, [np.arange(200)], EvolutionConfig(), sensor, prepared, rng)  # type: ignore[arg-type]
    assert evals > 0 and ps.loglik.max() >= best
    np.testing.assert_allclose(ps.loglik, sensor.log_likelihood(ps.poses, prepared))
