"""Regression benchmarks of the hot kernels (pytest-benchmark).

Run with ``make bench`` or ``pytest benchmarks --benchmark-enable``. With benchmarks disabled
(pyproject's default ``--benchmark-disable``) each body runs once: a quick smoke check.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.ceamcl.initialisation import best_in_parts, top_k_mean_per_cell
from ceamcl.maps.grid import FREE, OCCUPIED, OccupancyGrid
from ceamcl.maps.worlds import get_world
from ceamcl.motion import OdometryMotionModel
from ceamcl.sensors import BeamModel, BeamModelConfig, LikelihoodFieldModel
from ceamcl.sensors.raycast import cast_fan
from ceamcl.simulation import SimulatedLog, paper_scenario

Bench = Callable[..., Any]


@pytest.fixture(scope="module")
def hall() -> OccupancyGrid:
    return get_world("symmetric-hall")


@pytest.fixture(scope="module")
def log() -> SimulatedLog:
    return paper_scenario(0).simulate(np.random.default_rng(1))


@pytest.mark.parametrize("n", [1000, 5000, 20000])
@pytest.mark.parametrize("sensor", ["likelihood-field", "beam", "beam-exact"])
def test_sensor_log_likelihood(
    benchmark: Bench, hall: OccupancyGrid, log: SimulatedLog, sensor: str, n: int
) -> None:
    if sensor == "likelihood-field":
        model: Any = LikelihoodFieldModel(hall)
    else:
        exact = sensor == "beam-exact"
        model = BeamModel(hall, BeamModelConfig(ray_casting="exact" if exact else "table"))
    truth = log.true_poses[40]
    poses = truth + np.random.default_rng(2).normal(0.0, [0.3, 0.3, 0.1], (n, 3))
    prepared = model.prepare(log.scan(40))
    model.log_likelihood(poses, prepared)  # compile, fill the table entries
    out = benchmark(model.log_likelihood, poses, prepared)
    assert out.shape == (n,) and np.all(np.isfinite(out))


def test_cast_fan_exact(benchmark: Bench, hall: OccupancyGrid) -> None:
    poses = hall.sample_free_poses(2000, np.random.default_rng(3))
    bearings = np.linspace(-np.pi / 2, np.pi / 2, 60)
    out = benchmark(cast_fan, hall, poses, bearings, 8.0)
    assert out.shape == (2000, 60)


def test_top_k_mean_per_cell(benchmark: Bench) -> None:
    rng = np.random.default_rng(4)
    cell = rng.integers(0, 22_500, 1_000_000)
    value = rng.random(1_000_000)
    out = benchmark(top_k_mean_per_cell, cell, value, 22_500, 3)
    assert out.shape == (22_500,)


def test_best_in_parts(benchmark: Bench) -> None:
    rng = np.random.default_rng(5)
    part = rng.integers(1, 17, 1_000_000).astype(np.int32)
    score = rng.normal(size=1_000_000)
    sizes = np.full(16, 500, dtype=np.int64)
    out = benchmark(best_in_parts, part, score, sizes)
    assert len(out) == 16


def test_ceamcl_initialisation_1m(benchmark: Bench, hall: OccupancyGrid, log: SimulatedLog) -> None:
    def init() -> int:
        f = CEAMCL(
            hall,
            OdometryMotionModel(),
            LikelihoodFieldModel(hall),
            CEAMCLConfig(),
            rng=np.random.default_rng(6),
        )
        f.initialise_global(log.scan(0))
        return int(f.poses.shape[0])

    assert benchmark.pedantic(init, rounds=3, iterations=1) > 0


def test_likelihood_field_on_a_large_map(benchmark: Bench, log: SimulatedLog) -> None:
    """CEAMCL's test poses on a real building's scale: 250,000 poses (one ``test_batch``) read
    a 1,800 x 1,000-cell map at random, where the table's size decides the time (its cells are
    a 2-byte index since 2026-11-27; docs/performance.md, "Likelihood field")."""
    rng = np.random.default_rng(7)
    data = np.where(rng.random((1800, 1000)) < 0.02, OCCUPIED, FREE).astype(np.int8)
    grid = OccupancyGrid(data, 0.05)
    model = LikelihoodFieldModel(grid)
    poses = grid.sample_free_poses(250_000, rng)
    prepared = model.prepare(log.scan(0))
    model.log_likelihood(poses[:10], prepared)  # the distance field and the table
    out = benchmark(model.log_likelihood, poses, prepared)
    assert out.shape == (250_000,) and np.all(np.isfinite(out))
