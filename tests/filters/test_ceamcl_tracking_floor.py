"""A lone species below the tracking floor (``delta * tracking_epsilon_m2`` = 120 samples)
grows to it at once; while species compete, eq. 9 alone sets every size
(``CEAMCLConfig.fill_tracking_floor``, docs/ceamcl.md departure 8)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCLConfig
from ceamcl.filters.ceamcl.phases import CompetitionConfig, compete, species_stats
from ceamcl.filters.ceamcl.species import SpeciesStats
from ceamcl.filters.particles import ParticleSet
from ceamcl.maps.worlds import get_world
from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.simulation.scenarios import office_scenario

STILL = OdometryIncrement(0.0, 0.0, 0.0)


def sizes_after_tracking(fill: bool, steps: int = 3) -> list[int]:
    """A lone species of 40 samples at the true pose, stepped with scans from there."""
    log = office_scenario().simulate(np.random.default_rng(1))
    world = get_world("small-office")
    config = replace(CEAMCLConfig(), tracking_samples=40, fill_tracking_floor=fill)
    f = make_filter("ceamcl", world, np.random.default_rng(0), config=config)
    f.initialise_pose(log.true_poses[0], np.diag([0.01, 0.01, 0.005]))
    sizes = []
    for _ in range(steps):
        f.step(STILL, log.scan(0))
        sizes.append(f.particle_set.n)
    return sizes


def test_a_lone_species_below_the_floor_reaches_it_at_the_next_step() -> None:
    config = CEAMCLConfig()
    floor = round(config.delta_per_m2 * (config.tracking_epsilon_m2 or 0.0))
    assert floor == 120
    filled = sizes_after_tracking(fill=True)
    logistic = sizes_after_tracking(fill=False)
    # step 1 uses the initialisation's dN (none); the competition after it fills the floor
    assert filled == [40, floor, floor]
    # eq. 9 alone: r = 0.2 adds a few samples a step (40, 45, 50 with this seed)
    assert logistic[0] == 40 and logistic[-1] < 60


def _stats(sizes: list[int]) -> dict[int, SpeciesStats]:
    rng = np.random.default_rng(3)
    poses = np.vstack(
        [rng.normal([2.0 + 4 * i, 2.0, 0.0], 0.02, (n, 3)) for i, n in enumerate(sizes)]
    )
    labels = np.concatenate([np.full(n, i) for i, n in enumerate(sizes)])
    ps = ParticleSet.from_poses(poses, labels.astype(np.int64))
    ps.loglik = np.zeros(ps.n)
    ps.fitness = np.full(ps.n, 0.9)
    return species_stats(ps)


@pytest.mark.parametrize("fill", [True, False])
def test_competing_species_follow_eq9_alone(fill: bool) -> None:
    cfg = CompetitionConfig(0.2, 0.5, 80.0, 1.5, fill)
    lone = compete(_stats([30]), cfg).dn[0]
    two = compete(_stats([30, 30]), cfg).dn
    plain = CompetitionConfig(0.2, 0.5, 80.0, 1.5, False)
    assert two == compete(_stats([30, 30]), plain).dn  # competition untouched
    if fill:
        assert lone == pytest.approx(120 - 30)
    else:
        assert 0 < lone < 10  # r N (1 - N / K) with K = 120
