"""Issue 14's behaviour of the localisation state on whole runs (CEAMCL): a kidnap turns it
LOST within seconds and back to LOCALISED; the symmetric hall keeps it AMBIGUOUS with four
hypotheses until the mark is seen; scans of another map give LOST, never a confident pose.
Seeds 1-3: disjoint from seed 100, on which the thresholds were chosen."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.state import State
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation.scenarios import kidnapped_scenario, office_scenario, paper_scenario
from ceamcl.simulation.simulator import SimulatedLog


def states(result: RunResult) -> list[State]:
    out = []
    for s in result.states:
        assert s is not None
        out.append(s.state)
    return out


def run(name: str, log: SimulatedLog, world_grid_of: str, seed: int) -> RunResult:
    from ceamcl.maps.worlds import get_world

    return run_filter(make_filter(name, get_world(world_grid_of), np.random.default_rng(seed)), log)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_kidnap_turns_the_state_lost_within_seconds_then_localised_again(seed: int) -> None:
    log = kidnapped_scenario().simulate(np.random.default_rng(seed))
    (kidnap,) = log.kidnapped_at
    result = run("ceamcl", log, "small-office", seed)
    said = states(result)
    assert said[0] is State.INITIALISING
    assert all(s is State.LOCALISED for s in said[kidnap - 50 : kidnap])  # tracking: 5 s
    lost = [k for k in range(kidnap, len(said)) if said[k] is State.LOST]
    assert lost, "never said LOST after the kidnap"
    assert log.times[lost[0]] - log.times[kidnap] <= 2.0
    # relocalised within 10 s, and says LOCALISED from then on while the estimate is right
    back = kidnap + 100
    assert all(s is State.LOCALISED for s in said[back:])
    err = result.position_errors
    assert err is not None and err[back:].max() < 0.5
    # the whole run: LOCALISED is never said while the estimate is wrong
    wrong = err > 0.5
    assert not any(s is State.LOCALISED and w for s, w in zip(said, wrong, strict=True))


def test_the_symmetric_hall_stays_ambiguous_with_four_hypotheses() -> None:
    log = paper_scenario(0, "symmetric-hall").simulate(np.random.default_rng(3))
    result = run("ceamcl", log, "symmetric-hall", 3)
    said = states(result)
    assert State.LOCALISED not in said and State.LOST not in said
    settled = [s for s in result.states[150:] if s is not None]  # after 15 s
    four = [s.state is State.AMBIGUOUS and s.n_hypotheses == 4 for s in settled]
    assert np.mean(four) >= 0.95
    assert all(len(s.weights) == s.n_hypotheses for s in settled)


def marked_hall_run() -> tuple[RunResult, int]:
    """CEAMCL on marked-hall (seed 3), and the first step where the mark is in view (where
    the scans of the marked and the plain hall differ, same seed, same noise)."""
    marked = paper_scenario(0, "marked-hall").simulate(np.random.default_rng(3))
    plain = paper_scenario(0, "symmetric-hall").simulate(np.random.default_rng(3))
    seen = int(np.flatnonzero(np.any(np.abs(marked.ranges - plain.ranges) > 0.05, axis=1))[0])
    assert seen > 20
    return run("ceamcl", marked, "marked-hall", 3), seen


def test_marked_hall_is_ambiguous_until_the_mark_is_seen_then_localised() -> None:
    result, seen = marked_hall_run()
    said = states(result)
    assert all(s is State.AMBIGUOUS for s in said[1:seen])
    # decided within 3 s of seeing the mark, and right
    decided = seen + 30
    assert all(s is State.LOCALISED for s in said[decided:])
    err = result.position_errors
    assert err is not None and err[decided:].max() < 0.5


def test_marked_hall_counts_four_hypotheses_at_every_step_before_the_mark() -> None:
    result, seen = marked_hall_run()
    before = [s.n_hypotheses for s in result.states[1:seen] if s is not None]
    assert min(before) >= 4


# KLD-AMCL scores as ROS amcl (1 + sum pz^3): on scans no pose can explain its fitness, the
# order-3 power mean of pz / pz_max, stays about 0.5, above fit_min, held up by a few beams
# near a wall. It was a known gap (an xfail here) until the state's wall-crossing test: the
# round room's 7.5 m readings go through the office's walls from every pose, so it says LOST.
@pytest.mark.parametrize("name", ["ceamcl", "kld-amcl-recovery", "mcl"])
def test_scans_of_another_map_give_lost_not_a_confident_pose(name: str) -> None:
    # Tracked on small-office for 3 s, then the scans come from another map: a round room of
    # radius 7.5 m, which no pose of the 10 x 8 m office can see (every beam inconsistent).
    log = office_scenario().simulate(np.random.default_rng(1))
    n, switch = 80, 30
    ranges = log.ranges[:n].copy()
    ranges[switch:] = 7.5 + 0.02 * np.random.default_rng(5).standard_normal((n - switch, 181))
    log = SimulatedLog(log.times[:n], log.true_poses[:n], log.odometry[:n], ranges, log.laser)
    from ceamcl.maps.worlds import get_world

    f = make_filter(name, get_world("small-office"), np.random.default_rng(1))
    result = run_filter(f, log, initial_pose=(log.true_poses[0], np.diag([0.01, 0.01, 0.003])))
    said = states(result)
    assert all(s is State.LOCALISED for s in said[1:switch])
    # LOST within 1 s (KLD-AMCL updates only after 0.2 m or 0.5 rad of motion), then LOST
    # at every step: never a confident pose
    assert all(s is State.LOST for s in said[switch + 10 :])
    assert State.LOCALISED not in said[switch + 10 :]


@pytest.mark.parametrize("name", ["ceamcl", "mcl", "kld-amcl-recovery"])
def test_a_room_the_map_holds_elsewhere_gives_lost_then_localised_again(name: str) -> None:
    # Tracked on small-office; for 3 s every reading ends 0.2 m short, as in a room whose
    # walls the map holds 0.2 m further out (a room mapped from a wrong pose, furniture moved
    # along the walls). The fitness forgives end points that near a wall, and no reading
    # passes through one: only the map's agreement with the scan sees it.
    log = office_scenario().simulate(np.random.default_rng(1))
    n, first, last = 90, 30, 60
    ranges = log.ranges[:n].copy()
    ranges[first:last] = np.maximum(ranges[first:last] - 0.2, 0.05)
    log = SimulatedLog(log.times[:n], log.true_poses[:n], log.odometry[:n], ranges, log.laser)
    from ceamcl.filters.state import DEFAULT_THRESHOLDS
    from ceamcl.maps.worlds import get_world

    f = make_filter(name, get_world("small-office"), np.random.default_rng(1))
    result = run_filter(f, log, initial_pose=(log.true_poses[0], np.diag([0.01, 0.01, 0.003])))
    said = states(result)
    assert all(s is State.LOCALISED for s in said[1:first])
    # LOST at the update the run of disagreeing scans reaches, for the map's reason
    raised = first + DEFAULT_THRESHOLDS.explained_updates - 1
    s = result.states[raised]
    assert s is not None and s.state is State.LOST and "the map explains" in s.reason, s
    assert max(result.position_errors[:n]) < 0.3  # the filter was right: the map disagreed
    if name != "kld-amcl-recovery":  # its own clusters' wall test keeps it LOST longer
        assert all(s is State.LOCALISED for s in said[last + 3 :])


def test_a_crowd_hiding_a_third_of_the_scan_leaves_a_tracked_pose_localised() -> None:
    # The other side of the map's agreement: readings that end short on people the map does
    # not hold (blocks of 3-11 beams ending 0.5-2 m away, 30 % of every scan) are unexplained
    # end points too, and must not make a tracked pose LOST (docs/state.md).
    log = office_scenario().simulate(np.random.default_rng(1))
    n = 80
    rng = np.random.default_rng(7)
    ranges = log.ranges[:n].copy()
    m = ranges.shape[1]
    for k in range(n):
        hidden = np.zeros(m, dtype=bool)
        while hidden.mean() < 0.3:
            c, w = rng.integers(0, m), rng.integers(3, 12)
            hidden[c : c + w] = True
        near = rng.uniform(0.5, 2.0) + 0.05 * rng.standard_normal(int(hidden.sum()))
        ranges[k, hidden] = np.minimum(ranges[k, hidden], near)
    log = SimulatedLog(log.times[:n], log.true_poses[:n], log.odometry[:n], ranges, log.laser)
    from ceamcl.maps.worlds import get_world

    f = make_filter("ceamcl", get_world("small-office"), np.random.default_rng(1))
    result = run_filter(f, log, initial_pose=(log.true_poses[0], np.diag([0.01, 0.01, 0.003])))
    assert all(s is State.LOCALISED for s in states(result)[1:])
    assert max(result.position_errors) < 0.2
