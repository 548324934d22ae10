"""One seed, one trajectory: every algorithm is reproducible bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters import ALGORITHMS, make_filter
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation import office_scenario
from ceamcl.simulation.simulator import SimulatedLog

STEPS = 40


@pytest.fixture(scope="module")
def short_log() -> SimulatedLog:
    full = office_scenario().simulate(np.random.default_rng(2024))
    return SimulatedLog(
        full.times[:STEPS],
        full.true_poses[:STEPS],
        full.odometry[:STEPS],
        full.ranges[:STEPS],
        full.laser,
        full.world,
    )


def run(algorithm: str, log: SimulatedLog, seed: int) -> RunResult:
    grid = office_scenario().grid()
    return run_filter(make_filter(algorithm, grid, np.random.default_rng(seed)), log)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_same_seed_same_trajectory_bit_for_bit(algorithm: str, short_log: SimulatedLog) -> None:
    a = run(algorithm, short_log, 7)
    b = run(algorithm, short_log, 7)
    assert a.estimates.tobytes() == b.estimates.tobytes()
    assert a.final_particles.poses.tobytes() == b.final_particles.poses.tobytes()
    assert a.final_particles.weights.tobytes() == b.final_particles.weights.tobytes()
    assert [d.n_particles for d in a.diagnostics] == [d.n_particles for d in b.diagnostics]
    assert all(x.tobytes() == y.tobytes() for x, y in zip(a.hypotheses, b.hypotheses, strict=True))
    c = run(algorithm, short_log, 8)
    assert c.final_particles.poses.tobytes() != a.final_particles.poses.tobytes()
    assert c.estimates.tobytes() != a.estimates.tobytes()
