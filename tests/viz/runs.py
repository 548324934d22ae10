"""Short simulated runs shared by the tests of the visual outputs (animation, report, MCAP)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ceamcl.demo import seeded_generators
from ceamcl.filters import make_filter
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation.scenarios import paper_scenario
from ceamcl.simulation.simulator import SimulatedLog

STEPS = 41  # 4 s of the paper's run at 10 Hz
SNAPSHOT_EVERY = 5


def first_steps(log: SimulatedLog, n: int) -> SimulatedLog:
    """The first ``n`` entries of a simulated log."""
    return SimulatedLog(
        log.times[:n], log.true_poses[:n], log.odometry[:n], log.ranges[:n], log.laser, log.world
    )


@lru_cache(maxsize=4)
def short_run(
    algorithm: str = "ceamcl", seed: int = 7
) -> tuple[RunResult, OccupancyGrid, SimulatedLog]:
    """The first 4 s of the paper's run (symmetric hall, room 0), particles kept every 5 steps.

    Cached: treat the returned objects as read-only.
    """
    sc = paper_scenario(0, "symmetric-hall")
    grid = sc.grid()
    sim_rng, filter_rng = seeded_generators(seed, 2)
    log = first_steps(sc.simulate(sim_rng, grid), STEPS)
    n_particles = 400 if algorithm != "ceamcl" else None
    f = make_filter(algorithm, grid, filter_rng, n_particles=n_particles)
    result = run_filter(f, log, snapshot_every=SNAPSHOT_EVERY)
    assert result.steps == STEPS and np.all(np.isfinite(result.estimates))
    return result, grid, log
