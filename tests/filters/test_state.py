"""The localisation state read from hypotheses and covariances (issue 14,
:mod:`ceamcl.filters.state`) and ``state()`` on every registered filter."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ceamcl.filters import make_filter, registry
from ceamcl.filters.base import Hypothesis, PoseEstimate
from ceamcl.filters.state import (
    DEFAULT_THRESHOLDS,
    LocalisationState,
    State,
    read_covariance,
    read_hypotheses,
)
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.sensors.scan import LaserScan
from ceamcl.simulation.scenarios import office_scenario

TIGHT = np.diag([0.01, 0.01, 0.001])


def hyp(weight: float, fitness: float, x: float = 0.0, cov: np.ndarray = TIGHT) -> Hypothesis:
    return Hypothesis(np.array([x, 0.0, 0.0]), cov, 100, weight, fitness, 0)


def test_one_fitting_hypothesis_holding_the_weight_is_localised() -> None:
    s = read_hypotheses([hyp(0.97, 0.9), hyp(0.03, 0.9, x=5.0)])
    assert s.state is State.LOCALISED
    assert s.n_hypotheses == 1 and s.weights == pytest.approx((0.97,))
    assert 0.9 < s.confidence <= 1.0
    assert "fits the scan" in s.reason


def test_several_fitting_hypotheses_sharing_the_weight_are_ambiguous() -> None:
    s = read_hypotheses([hyp(0.26, 0.9), hyp(0.25, 0.85, 3), hyp(0.25, 0.9, 6), hyp(0.24, 0.8, 9)])
    assert s.state is State.AMBIGUOUS
    assert s.n_hypotheses == 4
    assert s.weights == pytest.approx((0.26, 0.25, 0.25, 0.24))
    assert "4 hypotheses" in s.reason


def test_a_rival_that_does_not_fit_the_scan_does_not_make_it_ambiguous() -> None:
    s = read_hypotheses([hyp(0.6, 0.9), hyp(0.4, 0.2, x=5.0)])
    assert s.state is State.LOCALISED


def test_a_fitting_rival_holding_weight_makes_it_ambiguous_a_smaller_one_does_not() -> None:
    assert read_hypotheses([hyp(0.97, 0.9), hyp(0.03, 0.9, 5)]).state is State.LOCALISED
    s = read_hypotheses([hyp(0.93, 0.9), hyp(0.07, 0.9, 5)])
    assert s.state is State.AMBIGUOUS and s.n_hypotheses == 2


def test_nothing_that_fits_the_scan_is_lost() -> None:
    s = read_hypotheses([hyp(0.99, 0.2), hyp(0.01, 0.9, x=5.0)])  # the fitting one holds 1 %
    assert s.state is State.LOST
    assert s.n_hypotheses == 0
    assert s.confidence == pytest.approx(1 - 0.2 / DEFAULT_THRESHOLDS.fit_min)


def test_a_pose_spread_over_metres_is_lost() -> None:
    wide = np.diag([4.0, 4.0, 0.1])
    s = read_hypotheses([hyp(1.0, 0.9, cov=wide)])
    assert s.state is State.LOST
    assert "spread" in s.reason


def test_nan_weights_and_fitness_and_no_hypotheses_give_a_state_not_nan() -> None:
    s = read_hypotheses([hyp(float("nan"), float("nan")), hyp(1.0, float("nan"))])
    assert s.state is State.LOST and np.isfinite(s.confidence)
    assert read_hypotheses([]).state is State.LOST
    zero = read_hypotheses([hyp(0.0, 0.9), hyp(0.0, 0.9, 5)])  # no weight at all
    assert zero.state is State.LOST and np.isfinite(zero.confidence)


def test_covariance_reading_as_nav2_users_do() -> None:
    small = read_covariance(PoseEstimate(np.zeros(3), np.diag([0.01, 0.01, 0.005])))
    assert small.state is State.LOCALISED and 0 < small.confidence <= 1
    wide = read_covariance(PoseEstimate(np.zeros(3), np.diag([1.0, 1.0, 0.005])))
    assert wide.state is State.LOST
    turned = read_covariance(PoseEstimate(np.zeros(3), np.diag([0.01, 0.01, 0.5])))
    assert turned.state is State.LOST
    bad = read_covariance(PoseEstimate(np.zeros(3), np.full((3, 3), np.nan)))
    assert bad.state is State.LOST and bad.confidence == 1.0


def test_state_row_has_the_csv_columns() -> None:
    s = LocalisationState(State.AMBIGUOUS, 0.5, 2, (0.5, 0.5), "x")
    row = s.row()
    judged = row.pop("state_map_explained")
    assert isinstance(judged, float) and np.isnan(judged)  # from hypotheses alone: not judged
    assert row == {"state": "AMBIGUOUS", "state_confidence": 0.5, "state_hypotheses": 2}


@pytest.mark.parametrize("name", registry.names())
def test_every_filter_reports_a_state_initialising_then_localised_when_tracking(
    name: str,
) -> None:
    if registry.unavailable_reason(name):
        pytest.skip(registry.unavailable_reason(name) or "")
    sc = office_scenario()
    log = sc.simulate(np.random.default_rng(1))
    grid = sc.grid()
    f = make_filter(name, grid, np.random.default_rng(2))
    f.initialise_global(log.scan(0))
    assert f.state().state is State.INITIALISING
    f.initialise_pose(log.true_poses[0], np.diag([0.01, 0.01, 0.002]))
    for _ in range(1, 15):
        f.step(OdometryIncrement(0.0, 0.0, 0.0), log.scan(0))
    s = f.state()
    assert s.state is State.LOCALISED, s.reason
    assert 0.0 <= s.confidence <= 1.0


def test_a_lighter_fitting_hypothesis_does_not_vouch_for_the_estimate() -> None:
    # the estimate comes from the heaviest hypothesis; it does not fit (a restart's first step
    # after a kidnap: the old place keeps its weight while a new species fits)
    s = read_hypotheses([hyp(0.6, 0.31), hyp(0.2, 0.82, x=5.0), hyp(0.2, 0.35, x=9.0)])
    assert s.state is State.LOST and "leading hypothesis (60%" in s.reason
    assert s.n_hypotheses == 0 and 0.0 < s.confidence < 1.0
    # once the fitting one leads, it is LOCALISED
    s = read_hypotheses([hyp(0.2, 0.31), hyp(0.6, 0.82, x=5.0), hyp(0.2, 0.35, x=9.0)])
    assert s.state is State.LOCALISED and s.weights == pytest.approx((0.6,))


# ------------------------------------------------------------------ the wall-crossing test
def test_a_fitting_hypothesis_whose_scan_goes_through_walls_does_not_count() -> None:
    lead, rival = hyp(0.7, 0.9), hyp(0.3, 0.9, x=5.0)
    through = {0.0: 0.0, 5.0: 0.5}  # share of readings through walls, by x
    s = read_hypotheses([lead, rival], crossing=lambda pose: through[float(pose[0])])
    assert s.state is State.LOCALISED and s.weights == pytest.approx((0.7,))
    # the estimate's own hypothesis sees through the walls: the lighter rival that does not is
    # no reason to trust the estimate
    through = {0.0: 0.5, 5.0: 0.0}
    s = read_hypotheses([lead, rival], crossing=lambda pose: through[float(pose[0])])
    assert s.state is State.LOST and "lighter" in s.reason
    assert "walls" in s.reason and s.confidence == 1.0  # as for a lone leader, below
    alone = read_hypotheses([hyp(1.0, 0.95)], crossing=lambda pose: 0.5)
    assert alone.state is State.LOST and "walls" in alone.reason and alone.confidence == 1.0
    t = DEFAULT_THRESHOLDS.max_wall_crossing
    assert read_hypotheses([hyp(1.0, 0.95)], crossing=lambda pose: t).state is State.LOCALISED


def test_wall_crossing_is_small_at_the_true_pose_and_large_where_the_scan_sees_through() -> None:
    from ceamcl.filters.state import wall_crossing
    from ceamcl.maps.worlds import get_world

    log = office_scenario().simulate(np.random.default_rng(2))
    grid = get_world("small-office")
    k = 10
    crossing = wall_crossing(grid, log.scan(k))
    assert crossing is not None
    truth = log.true_poses[k]
    assert crossing(truth) <= 0.05
    # the same scan from half a turn away: long readings now run into the walls behind
    turned = truth + np.array([0.0, 0.0, np.pi])
    assert crossing(turned) > DEFAULT_THRESHOLDS.max_wall_crossing
    assert crossing(np.array([np.nan, 0.0, 0.0])) == 1.0
    empty = log.scan(k)
    empty = type(empty)(**{**empty.__dict__, "ranges": np.full_like(empty.ranges, np.nan)})
    assert wall_crossing(grid, empty) is None


# ------------------------------------------------------------------ the map's agreement
def _office_scan() -> tuple[OccupancyGrid, LaserScan, np.ndarray]:
    from ceamcl.maps.worlds import get_world

    log = office_scenario().simulate(np.random.default_rng(2))
    return get_world("small-office"), log.scan(10), log.true_poses[10]


def test_the_map_explains_most_of_a_scan_at_the_true_pose_and_little_half_a_metre_off() -> None:
    from ceamcl.sensors.map_agreement import explained_share

    grid, scan, truth = _office_scan()
    assert explained_share(grid, truth, scan) >= 0.9
    off = truth + np.array([0.5, 0.3, 0.0])
    assert explained_share(grid, off, scan) < DEFAULT_THRESHOLDS.explained_below
    assert np.isnan(explained_share(grid, np.array([np.nan, 0.0, 0.0]), scan))


def test_map_agreement_turns_a_localised_state_lost_after_its_run_of_updates() -> None:
    from ceamcl.filters.state import MapAgreement

    grid, scan, truth = _office_scan()
    off = truth + np.array([0.5, 0.3, 0.0])
    localised = read_hypotheses([hyp(1.0, 0.9)])
    ambiguous = read_hypotheses([hyp(0.5, 0.9), hyp(0.5, 0.9, x=5.0)])
    n = DEFAULT_THRESHOLDS.explained_updates
    assert n >= 2
    agreement = MapAgreement(grid)

    def at(pose: np.ndarray) -> list[Hypothesis]:
        return [Hypothesis(pose, TIGHT, 100, 1.0, 0.9, 0)]

    def is_localised(s: LocalisationState) -> bool:
        return s.state is State.LOCALISED and s.reason == localised.reason

    # the map explains the scan: the state is the same, with the share it measured
    s = agreement.apply(localised, 1, scan, at(truth))
    assert is_localised(s) and s.map_explained >= 0.9
    # it does not, update after update: LOST at the n-th, with the share in the reason
    for step in range(2, 2 + n - 1):
        s = agreement.apply(localised, step, scan, at(off))
        assert is_localised(s) and s.map_explained < DEFAULT_THRESHOLDS.explained_below
        # read again in the same update: counted once
        assert is_localised(agreement.apply(localised, step, scan, at(off)))
    s = agreement.apply(ambiguous, 1 + n, scan, at(off))
    assert s.state is State.LOST and "the map explains" in s.reason
    assert s.n_hypotheses == 0 and 0.0 < s.confidence <= 1.0
    assert s.map_explained < DEFAULT_THRESHOLDS.explained_below
    # the same update read at another leading pose (CEAMCL's recovery replaced its species
    # after the first read) is judged again there, in place of the first reading
    s = agreement.apply(localised, 1 + n, scan, at(truth))
    assert is_localised(s) and s.map_explained >= 0.9
    assert agreement.apply(localised, 1 + n, scan, at(off)).state is State.LOST
    # an update where it agrees again ends the run
    assert is_localised(agreement.apply(localised, 2 + n, scan, at(truth)))
    # an update the filter did not read breaks the run (the count is of consecutive updates)
    agreement.reset()
    for step in range(1, n):
        agreement.apply(localised, 2 * step, scan, at(off))
    assert is_localised(agreement.apply(localised, 2 * n, scan, at(off)))
    # INITIALISING is never turned, and no hypothesis leaves the state as it is
    init = LocalisationState(State.INITIALISING, 1.0, 0, (), "")
    assert agreement.apply(init, 100, scan, at(off)) is init
    assert agreement.apply(localised, 101, scan, []) is localised
    # the leading hypothesis is the heaviest, NaN weights counting as 0
    agreement.reset()
    lead_off = [
        Hypothesis(truth, TIGHT, 100, float("nan"), 0.9, 0),
        Hypothesis(off, TIGHT, 100, 0.4, 0.9, 1),
    ]
    for step in range(1, n + 1):
        s = agreement.apply(localised, step, scan, lead_off)
    assert s.state is State.LOST


def test_the_map_judges_nothing_in_a_scan_without_beams_or_readings() -> None:
    from ceamcl.sensors.map_agreement import explained_share

    grid, scan, truth = _office_scan()
    empty = LaserScan(**{**scan.__dict__, "ranges": np.zeros(0)})
    assert np.isnan(explained_share(grid, truth, empty))
    blind = LaserScan(**{**scan.__dict__, "ranges": np.full_like(scan.ranges, np.nan)})
    assert np.isnan(explained_share(grid, truth, blind))


def test_a_laser_that_returns_nothing_confirms_nothing() -> None:
    """An empty scan fits every pose (fitness 1): a filter whose laser went dead read
    LOCALISED with confidence 1.00 'fits the scan' for ever. The update says nothing
    confirmed it, and a run of such updates is LOST, as a run the map does not explain."""
    from ceamcl.filters.state import MapAgreement

    grid, scan, truth = _office_scan()
    blind = LaserScan(**{**scan.__dict__, "ranges": np.full_like(scan.ranges, np.nan)})
    localised = read_hypotheses([hyp(1.0, 1.0)])
    at = [Hypothesis(truth, TIGHT, 100, 1.0, 1.0, 0)]
    agreement = MapAgreement(grid)
    n = DEFAULT_THRESHOLDS.explained_updates
    for step in range(1, n):
        s = agreement.apply(localised, step, blind, at)
        assert s.state is State.LOCALISED and "nothing confirmed it" in s.reason
    s = agreement.apply(localised, n, blind, at)
    assert s.state is State.LOST and "no reading of the scan ends" in s.reason
    assert s.confidence == 1.0
    # a scan that ends on walls again ends the run
    assert agreement.apply(localised, n + 1, scan, at).state is State.LOCALISED
    # no scan at all (an update without one) breaks the run, as before
    agreement.reset()
    for step in range(1, n + 2):
        s = agreement.apply(localised, step, None, at)
    assert s.state is State.LOCALISED


def test_weight_spread_thin_is_lost_for_that_reason() -> None:
    """It read 'no hypothesis that holds weight fits the scan (best fitness 0.93 < 0.55)'
    when every hypothesis fitted and none held 5 % of the weight."""
    thin = [hyp(1.0 / 40, 0.93, x=float(i)) for i in range(40)]
    s = read_hypotheses(thin)
    assert s.state is State.LOST and "no hypothesis holds 5% of the weight" in s.reason
    assert "fitness" not in s.reason


def test_map_agreement_share_at_reuses_a_read_and_counts_nothing() -> None:
    """``share_at`` (CEAMCL's last confident pose, docs/ceamcl.md departure 14): the share the
    read of that update measured at that pose, else computed, and the run of updates stays as
    the reads left it."""
    from ceamcl.filters.state import MapAgreement
    from ceamcl.sensors.map_agreement import explained_share

    grid, scan, truth = _office_scan()
    off = truth + np.array([0.5, 0.3, 0.0])
    localised = read_hypotheses([hyp(1.0, 0.9)])
    agreement = MapAgreement(grid)
    s = agreement.apply(localised, 1, scan, [Hypothesis(off, TIGHT, 100, 1.0, 0.9, 0)])
    assert agreement.share_at(1, scan, off) == s.map_explained
    tol = DEFAULT_THRESHOLDS.explained_tol_m
    assert agreement.share_at(1, scan, truth) == explained_share(grid, truth, scan, tol)
    assert agreement.share_at(2, scan, off) == explained_share(grid, off, scan, tol)
    assert math.isnan(agreement.share_at(2, None, off))
    # nothing counted: the next update still continues the run of one
    streak, _ = agreement.observe(2, scan, off)
    assert streak == 2


@pytest.mark.parametrize("read_between", [False, True])
def test_ceamcl_counts_the_maps_disagreement_at_every_update_read_or_not(
    read_between: bool,
) -> None:
    """The map's agreement counts consecutive updates (:class:`MapAgreement`); CEAMCL reads it
    at the end of every update itself, so a caller that reads the state only now and then (a
    node that publishes at some updates, a script that reads at the end) finds the same run of
    updates, and the filter reports the same, as one that reads at every update. Tracked at the
    truth, then given a scan the map explains poorly at ``explained_updates`` updates while
    standing still: LOST by the map at the first read, read between or not."""
    from ceamcl.filters.ceamcl import CEAMCL
    from ceamcl.sensors.map_agreement import explained_share

    sc = office_scenario()
    log = sc.simulate(np.random.default_rng(2))
    grid = sc.grid()
    f = make_filter("ceamcl", grid, np.random.default_rng(3))
    assert isinstance(f, CEAMCL)
    still = OdometryIncrement(0.0, 0.0, 0.0)
    truth = log.true_poses[10]
    f.initialise_pose(truth, np.diag([0.01, 0.01, 0.002]))
    for _ in range(3):
        f.step(still, log.scan(10))
    assert f.state().state is State.LOCALISED
    # the same scan with its ranges 15 % short (a map that no longer matches the room): it
    # still fits (the likelihood forgives decimetres), but the map explains little of it
    short = replace(log.scan(10), ranges=log.scan(10).ranges * 0.85)
    assert explained_share(grid, truth, short) < DEFAULT_THRESHOLDS.explained_below
    for _ in range(DEFAULT_THRESHOLDS.explained_updates):
        f.step(still, short)
        if read_between:
            f.state()
    s = f.state()
    assert s.state is State.LOST and "the map explains" in s.reason, s.reason
