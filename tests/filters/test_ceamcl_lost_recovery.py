"""A filter that stays lost looks again (``recovery_lost_updates``, docs/ceamcl.md departure
10). The kidnap test sees a *fall* of the fitness; a filter that is wrong from the start, or
that a recovery left on a wrong place, never shows one, while its own state says LOST at every
update. After ``recovery_lost_updates`` such updates CEAMCL recovers (a second opinion, as
departure 9) and finds the robot."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.state import State
from ceamcl.motion.odometry import increment_between
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation.scenarios import office_scenario

#: a pose in the north-east room of small-office, far from the tour's start
WRONG = np.array([5.5, 6.5, 0.0])
SECONDS_LOST = 10  # what the kidnap test alone leaves a filter started wrong (below)


def started_wrong(seed: int, config: CEAMCLConfig) -> RunResult:
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(seed))
    f = make_filter("ceamcl", grid, np.random.default_rng(seed + 100), config=config)
    assert isinstance(f, CEAMCL)
    cov = np.diag([0.1**2, 0.1**2, 0.05**2])
    return run_filter(f, log, initial_pose=(WRONG, cov))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_filter_that_stays_lost_looks_again_and_finds_the_robot(seed: int) -> None:
    config = CEAMCLConfig()
    n = config.recovery_lost_updates
    assert n is not None
    result = started_wrong(seed, config)
    err = result.position_errors
    assert err is not None
    states = [d.state.state if d.state else None for d in result.diagnostics]
    recoveries = [k for k, d in enumerate(result.diagnostics) if d.reinitialised]
    assert recoveries, "no recovery in a filter that said LOST"
    first = recoveries[0]
    # it fired at the n-th update in a row that said LOST (step 0 is the first: the tracking
    # start's update with the first scan), not before
    assert first >= n - 1
    assert all(s is State.LOST for s in states[first - n + 1 : first])
    assert err[:first].min() > 2.0  # the start was wrong until then
    assert err[-10:].max() < 0.5  # found, and held to the end
    assert all(s is State.LOCALISED for s in states[-5:])


def test_without_it_a_filter_started_wrong_stays_lost_for_seconds() -> None:
    """The kidnap test alone: no fall to see, so the filter says LOST and stays wrong (in this
    run for 25.6 s, until the wrong place's fitness falls further as the robot drives on)."""
    result = started_wrong(0, replace(CEAMCLConfig(), recovery_lost_updates=None))
    err = result.position_errors
    assert err is not None
    early = result.diagnostics[: SECONDS_LOST * 10]
    assert not any(d.reinitialised for d in early)
    assert err[: len(early)].min() > 2.0
    assert all(d.state and d.state.state is State.LOST for d in early[1:])


def test_the_read_made_during_a_step_is_the_one_callers_get_after_it() -> None:
    """The step reads the state to count LOST updates; the runner's read after the step gets
    the same hypotheses and state as a fresh read would, and a new start clears it."""
    sc = office_scenario()
    log = sc.simulate(np.random.default_rng(0))
    f = make_filter("ceamcl", sc.grid(), np.random.default_rng(1))
    assert isinstance(f, CEAMCL)
    f.initialise_pose(log.true_poses[0], np.diag([0.05**2, 0.05**2, 0.03**2]))
    for k in range(1, 6):
        f.step(increment_between(log.odometry[k - 1], log.odometry[k]), log.scan(k))
        given = f.hypotheses()
        said = f.state(given)
        f._read = None  # a fresh read
        fresh = f.hypotheses()
        assert [(h.label, h.weight, h.fitness) for h in given] == [
            (h.label, h.weight, h.fitness) for h in fresh
        ]
        assert all(np.array_equal(a.pose, b.pose) for a, b in zip(given, fresh, strict=True))
        assert f.state(fresh) == said
    f.initialise_pose(WRONG, np.diag([0.1**2, 0.1**2, 0.05**2]))
    assert f.state().state is State.INITIALISING


@pytest.mark.parametrize("init_is_a_search", [True, False])
def test_a_lost_streak_right_after_the_global_search_waits_as_after_a_recovery(
    init_is_a_search: bool,
) -> None:
    """Departure 30: the global initialisation is a search of the whole map, so a LOST streak
    from its first update waits twice ``recovery_lost_updates`` before the recovery searches
    the map again, as a streak after a recovery does; ``init_is_a_search=False``: it fires at
    the third LOST update. Here every scan after the first is noise."""
    sc = office_scenario()
    log = sc.simulate(np.random.default_rng(0))
    config = replace(CEAMCLConfig(), init_is_a_search=init_is_a_search)
    f = make_filter("ceamcl", sc.grid(), np.random.default_rng(1), config=config)
    assert isinstance(f, CEAMCL)
    f.initialise_global(log.scan(0))
    first = log.scan(0)
    noise = np.random.default_rng(2).uniform(0.3, 0.9 * first.range_max, first.ranges.shape)
    crowd = replace(first, ranges=noise)  # readings no place of the map explains
    fired = None
    for k in range(1, 10):
        record = f.step(increment_between(log.odometry[0], log.odometry[0]), crowd)
        if record.reinitialised:
            fired = k
            break
        assert f.state().state is State.LOST
    n = config.recovery_lost_updates
    assert n is not None
    assert fired == (2 * n if init_is_a_search else n)
