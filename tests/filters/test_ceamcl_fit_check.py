"""Before a lone species' poor fit is reported (and the state says LOST), its evidence climb
looks for a pose of the species that fits (``CEAMCLConfig.confirm_fit_below``, docs/state.md)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.state import DEFAULT_THRESHOLDS
from ceamcl.maps.worlds import get_world
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel, OdometryNoise
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.simulation.scenarios import office_scenario

STILL = OdometryIncrement(0.0, 0.0, 0.0)
FIT_MIN = DEFAULT_THRESHOLDS.fit_min  # 0.55, the default of confirm_fit_below


def one_step(offset: tuple[float, float, float], bar: float | None, seed: int) -> CEAMCL:
    """A lone species of 300 samples, all at the true pose moved by ``offset``, weighs one scan
    taken at the true pose (the robot stands still: the motion model moves nothing)."""
    log = office_scenario().simulate(np.random.default_rng(1))
    world = get_world("small-office")
    # the climb alone: no look-around (departure 12, tests/filters/test_ceamcl_look_around.py)
    config = replace(CEAMCLConfig(), confirm_fit_below=bar, look_around_m=None)
    f = CEAMCL(
        world,
        OdometryMotionModel(OdometryNoise()),
        LikelihoodFieldModel(world),
        config,
        rng=np.random.default_rng(seed),
    )
    f.initialise_pose(log.true_poses[0] + np.array(offset), np.diag([1e-12, 1e-12, 1e-12]))
    f.step(STILL, log.scan(0))
    return f


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_poor_fit_is_confirmed_by_a_climb_before_it_is_reported(seed: int) -> None:
    offset = (0.0, 0.0, 0.25)  # every sample turned by 0.25 rad: a poor fit
    plain = one_step(offset, None, seed)
    (lone,) = plain.stats.values()
    best_individual = lone.best_fitness
    assert best_individual < FIT_MIN  # the case the climb is for
    assert plain.hypotheses()[0].fitness == pytest.approx(best_individual)
    checked = one_step(offset, FIT_MIN, seed)
    (lone,) = checked.stats.values()
    reported = checked.hypotheses()[0].fitness
    # the same samples (the climb moves none of them) ...
    assert lone.best_fitness == pytest.approx(best_individual)
    # ... but the hypothesis reports the fitness of the better pose the climb found near them
    assert reported > best_individual


@pytest.mark.parametrize("seed", [1, 2])
def test_a_good_fit_needs_no_climb(seed: int) -> None:
    """Nothing changes where the fittest individual already fits: same bits, same report."""
    plain = one_step((0.0, 0.0, 0.0), None, seed)
    checked = one_step((0.0, 0.0, 0.0), FIT_MIN, seed)
    assert checked.hypotheses()[0].fitness >= FIT_MIN
    np.testing.assert_array_equal(checked.particle_set.poses, plain.particle_set.poses)
    assert checked.hypotheses()[0].fitness == plain.hypotheses()[0].fitness
