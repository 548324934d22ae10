"""Know when you are lost: the localisation state a filter reports (issue 14).

``filter.state()`` answers "can I trust the pose?" with one of four states, a confidence in
[0, 1], the hypotheses it counted and their weights, and the reason in words:

* ``LOCALISED``: one hypothesis holds the weight and fits the scan;
* ``AMBIGUOUS``: several hypotheses fit the scan and share the weight (how many, and which);
* ``LOST``: nothing that holds weight fits the scan (the fitness collapsed after a kidnap, a
  scan from another map, readings that go through the map's walls from every such pose), the
  leading pose is spread too widely to be a pose, or the map has explained less than half of
  the scan at the leading pose for several updates running (:class:`MapAgreement`);
* ``INITIALISING``: the filter has not stepped since it was initialised: its hypotheses come
  from one scan, untested by any motion (at the global initialisation, CEAMCL's species and the
  baselines' clusters are places that happen to fit the first scan, the truth among them or
  not). A restart after a kidnap is not INITIALISING: the filter was lost and says so until
  its new hypotheses fit.

Every filter that lists its hypotheses (CEAMCL's species, the particle clusters of MCL, GMCL
and KLD-AMCL) is read by the same :func:`read_hypotheses`, so the comparison is fair: CEAMCL's
weights are its species' accumulated evidence (docs/ceamcl.md), the baselines' the particle
mass of each cluster; the fitness of each (``sensors.base.fitness``, the geometric mean of
per-beam likelihoods over their maximum, in (0, 1]) says whether it explains the scan. The Nav2
peer shows only a pose and a covariance; :func:`read_covariance` reads it as its users do today.

All thresholds live in :class:`StateThresholds`, with the measurements that chose them
(docs/state.md); they were chosen on seed 100 of the simulated scenarios and on
freiburg-079-corrected, disjoint from the base seed 0 and the logs that ``ceamcl experiment
state`` reports.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.base import Hypothesis, PoseEstimate, require_initialised
from ceamcl.sensors.map_agreement import EXPLAINED_TOL_M, end_points, explained_share
from ceamcl.sensors.scan import prepare_scan
from ceamcl.sensors.see_through import readings_through_walls

if TYPE_CHECKING:
    from ceamcl.filters.particles import ParticleSet
    from ceamcl.maps.grid import OccupancyGrid
    from ceamcl.sensors.scan import LaserScan, PreparedScan


class State(enum.Enum):
    """What a filter says of its own pose."""

    INITIALISING = "initialising"
    LOCALISED = "localised"
    AMBIGUOUS = "ambiguous"
    LOST = "lost"

    def __str__(self) -> str:
        return self.name


#: The states in a fixed order (tables, CSV rows, the colour band of plots).
STATES: tuple[State, ...] = (State.LOCALISED, State.AMBIGUOUS, State.LOST, State.INITIALISING)


@dataclass(frozen=True)
class StateThresholds:
    """Every threshold of the state, in one place (chosen on seed 100 of the simulated
    scenarios and on freiburg-079-corrected, docs/state.md).

    fit_min: a hypothesis *fits* the scan when its fitness is at least this. Measured on
        seed 100: a tracked pose scores 0.82-1.00 (CEAMCL's species, whose fitness is its
        fittest individual's; 0.70-0.98 with the mean over its individuals, which was read
        first) and 0.59-0.95 (a KLD-AMCL cluster, whose mean includes its spread particles);
        right after the small-office kidnap the leading hypothesis scores 0.25-0.27 (CEAMCL;
        0.18-0.26 with the mean).
    weight_min: a hypothesis *holds weight* when its share is at least this (smaller ones are
        leftovers: a KLD-AMCL cluster of a few particles, a species on its way out). A first
        version also called a leader with 90 % LOCALISED despite a fitting rival; on seed 100
        that said LOCALISED while a wrong place still held 6 %, so it was dropped.
    max_position_std_m: the leading pose is implausible (LOST) when its position standard
        deviation ``sqrt(var_x + var_y)`` exceeds this: a cloud, not a pose.
    fit_good: the confidence of a LOCALISED state grows with the leader's fitness up to this.
    covariance_position_std_m, covariance_heading_std_rad: for a filter read from its
        covariance (the Nav2 peer): LOCALISED when both standard deviations are at most these
        (half the experiments' tolerances 0.5 m and 0.3 rad), LOST otherwise.
    max_wall_crossing, wall_margin_m: a hypothesis does not fit the scan when more than
        ``max_wall_crossing`` of the scan's readings, seen from its pose, end more than
        ``wall_margin_m`` beyond the first occupied cell of the map along their ray
        (:func:`wall_crossing`): the laser sees through walls the map has there. On
        freiburg-079-corrected (not a scored log) 3 % of the readings do so at a right leader
        (median; 90th percentile 8.5 %) and 18 % at a wrong one.

    ``fit_min`` 0.55 and ``max_wall_crossing`` 0.2 were chosen together on
    freiburg-079-corrected: the pair with the highest LOST recall (0.77) among those that call
    at most 1 % of the scans where CEAMCL is right LOST (0.6 %); ``fit_min`` 0.45 alone gave
    0.49 (docs/state.md).

    explained_below, explained_updates, explained_tol_m: the map does not vouch for the
        leading pose (LOST, :class:`MapAgreement`) when fewer than ``explained_below`` of the
        scan's end points lie within ``explained_tol_m`` of the map's obstacles there
        (:func:`ceamcl.sensors.map_agreement.explained_share`) at ``explained_updates``
        consecutive updates. Chosen on freiburg-079-corrected (CEAMCL, seed 0) by the rule
        above among shares 0.30-0.50 and 1-10 updates: below 0.45 at 2 updates raised LOST
        recall there from 0.43 to 0.65 and called 0.75 % of the updates where CEAMCL is right
        LOST (0.56 % without the test). Below 0.4 at a single update tied it; two updates were
        preferred so that one scan alone (a crowd passing the laser) never decides. The
        ground-truth check's own values (below 0.5 for 5 updates) called 1.07 % LOST
        (docs/state.md).
    """

    fit_min: float = 0.55
    weight_min: float = 0.05
    max_position_std_m: float = 1.0
    fit_good: float = 0.8
    covariance_position_std_m: float = 0.25
    covariance_heading_std_rad: float = 0.15
    max_wall_crossing: float = 0.2
    wall_margin_m: float = 0.5
    explained_below: float = 0.45
    explained_updates: int = 2
    explained_tol_m: float = EXPLAINED_TOL_M


DEFAULT_THRESHOLDS = StateThresholds()


@dataclass(frozen=True)
class LocalisationState:
    """A filter's answer to "can I trust the pose?".

    state: :class:`State`. confidence: in [0, 1], how strongly the evidence supports
    ``state``. n_hypotheses: the hypotheses that hold weight and fit the scan (LOCALISED: 1;
    AMBIGUOUS: 2 or more; LOST: 0). weights: their shares, largest first. reason: in words.
    map_explained: the share of the scan's end points the map explains at the leading
    hypothesis (:class:`MapAgreement`; about 0.9 where the map holds what the robot sees),
    NaN where it was not judged (the Nav2 peer, INITIALISING, a scan without end points).
    """

    state: State
    confidence: float
    n_hypotheses: int
    weights: tuple[float, ...]
    reason: str
    map_explained: float = math.nan

    def row(self) -> dict[str, str | float | int]:
        """Flat fields for CSV and JSON (``state``, ``state_confidence``, ``state_hypotheses``,
        ``state_map_explained``)."""
        return {
            "state": self.state.name,
            "state_confidence": self.confidence,
            "state_hypotheses": self.n_hypotheses,
            "state_map_explained": self.map_explained,
        }


def initialising(
    reason: str = "initialised from one scan, not yet stepped",
) -> LocalisationState:
    """The state of a filter that has not stepped since its initialisation."""
    return LocalisationState(State.INITIALISING, 1.0, 0, (), reason)


def _clip01(x: float) -> float:
    return float(min(1.0, max(0.0, x))) if math.isfinite(x) else 0.0


def _position_std(covariance: np.ndarray) -> float:
    c = np.asarray(covariance, dtype=np.float64)
    var = float(c[0, 0] + c[1, 1])
    return math.sqrt(var) if math.isfinite(var) and var > 0 else (0.0 if var == 0 else math.inf)


#: The share of a scan's readings that pass through the map's walls, seen from a pose (3,).
Crossing = Callable[[NDArray[np.float64]], float]
#: Readings of a scan the wall-crossing test looks at (evenly spread, as the sensor models).
WALL_CROSSING_BEAMS = 60


def wall_crossing(
    grid: OccupancyGrid, scan: LaserScan | None, thresholds: StateThresholds = DEFAULT_THRESHOLDS
) -> Crossing | None:
    """For ``scan``: a function giving, for a pose, the share of its readings (60, evenly
    spread; max-range readings as the sensor's maximum) that end more than ``wall_margin_m``
    beyond the first occupied cell of ``grid`` along their ray (cast through unknown space, so
    only walls the map holds count). ``None`` without a scan or a usable reading. A pose that
    is not finite crosses everything."""
    if scan is None:
        return None
    prepared = prepare_scan(scan, WALL_CROSSING_BEAMS, keep_max_range=True)
    if prepared.n_beams == 0:
        return None
    margin = thresholds.wall_margin_m

    def share(pose: NDArray[np.float64]) -> float:
        p = np.asarray(pose, dtype=np.float64).reshape(1, 3)
        if not np.all(np.isfinite(p)):
            return 1.0
        return float(np.mean(readings_through_walls(grid, p, prepared, margin)))

    return share


_FLOAT_MAX = float(np.finfo(np.float64).max)


def _nan_to_num(x: float) -> float:
    """``np.nan_to_num`` of one number (NaN -> 0, +-inf -> +-the largest float), without its
    array machinery: the state is read after every update."""
    x = float(x)
    if math.isnan(x):
        return 0.0
    if math.isinf(x):
        return _FLOAT_MAX if x > 0 else -_FLOAT_MAX
    return x


def _shares(hypotheses: Sequence[Hypothesis]) -> NDArray[np.float64]:
    """The hypotheses' weights, NaN counting as 0, normalised when they sum above 0."""
    weights = np.array([_nan_to_num(h.weight) for h in hypotheses], dtype=np.float64)
    total = weights.sum()
    return weights / total if total > 0 else weights


def read_hypotheses(
    hypotheses: Sequence[Hypothesis],
    thresholds: StateThresholds = DEFAULT_THRESHOLDS,
    crossing: Crossing | None = None,
) -> LocalisationState:
    """The state of a filter from its hypotheses (weights sum to 1, fitness in (0, 1]).

    Candidates are the hypotheses that hold weight and fit the scan: fitness at least
    ``fit_min`` and, when ``crossing`` is given (:func:`wall_crossing` of the last scan), no
    more than ``max_wall_crossing`` of the readings through the map's walls. None, or none
    that is the heaviest hypothesis (where the estimate comes from): LOST. One:
    LOCALISED, unless its pose is spread wider than ``max_position_std_m`` (LOST). Several:
    AMBIGUOUS (a rival holding ``weight_min`` is a real alternative, as the experiment's true
    state counts it). NaN weights or fitness count as 0.
    """
    t = thresholds
    if not hypotheses:
        return LocalisationState(State.LOST, 1.0, 0, (), "no hypothesis left")
    weights = _shares(hypotheses)
    fit = np.array([_nan_to_num(h.fitness) for h in hypotheses], dtype=np.float64)
    order = np.argsort(-weights, kind="stable")  # order[0]: the heaviest, the first of equals
    holds = weights >= t.weight_min
    fitting = [int(i) for i in order if holds[i] and fit[i] >= t.fit_min]
    crossed = {}
    if crossing is not None:
        crossed = {i: crossing(np.asarray(hypotheses[i].pose)) for i in fitting}
    candidates = [i for i in fitting if crossed.get(i, 0.0) <= t.max_wall_crossing]
    if fitting and not candidates:
        lead = fitting[0]
        return LocalisationState(
            State.LOST,
            _clip01(crossed[lead] / (2.0 * t.max_wall_crossing)),
            0,
            (),
            f"the scan passes through the map's walls from every fitting hypothesis "
            f"({crossed[lead]:.0%} of the readings at the leading one > "
            f"{t.max_wall_crossing:.0%})",
        )
    heaviest = int(order[0])
    if candidates and candidates[0] != heaviest:
        # the estimate comes from the heaviest hypothesis, and it does not fit: a lighter one
        # that fits is where the filter may be going, not where it says the robot is
        if heaviest in crossed:  # it fits the scan, but the scan passes through walls from it
            confidence = crossed[heaviest] / (2.0 * t.max_wall_crossing)
            why = f"{crossed[heaviest]:.0%} of the readings pass through the map's walls"
        else:
            confidence = 1.0 - float(fit[heaviest]) / t.fit_min
            why = f"fitness {fit[heaviest]:.2f}"
        return LocalisationState(
            State.LOST,
            _clip01(confidence),
            0,
            (),
            f"the leading hypothesis ({weights[heaviest]:.0%} of the weight) does not fit the "
            f"scan ({why}); a lighter one ({weights[candidates[0]]:.0%}) does",
        )
    if not candidates and not holds.any():
        return LocalisationState(
            State.LOST,
            _clip01(1.0 - float(weights.max()) / t.weight_min),
            0,
            (),
            f"no hypothesis holds {t.weight_min:.0%} of the weight (the heaviest "
            f"{float(weights.max()):.1%}, over {len(hypotheses)}): the filter has no place yet",
        )
    if not candidates:
        best = float(fit[holds].max())
        return LocalisationState(
            State.LOST,
            _clip01(1.0 - best / t.fit_min),
            0,
            (),
            f"no hypothesis that holds weight fits the scan (best fitness {best:.2f} < "
            f"{t.fit_min:g})",
        )
    shares = tuple(float(weights[i]) for i in candidates)
    lead = candidates[0]
    if len(candidates) == 1:
        std = _position_std(hypotheses[lead].covariance)
        if std > t.max_position_std_m:
            return LocalisationState(
                State.LOST,
                _clip01(1.0 - t.max_position_std_m / std),
                0,
                (),
                f"the leading pose is spread over {std:.2f} m (> {t.max_position_std_m:g} m)",
            )
        confidence = shares[0] * min(1.0, float(fit[lead]) / t.fit_good)
        return LocalisationState(
            State.LOCALISED,
            _clip01(confidence),
            1,
            shares[:1],
            f"one hypothesis holds {shares[0]:.0%} of the weight and fits the scan "
            f"(fitness {fit[lead]:.2f})",
        )
    held = sum(shares)
    return LocalisationState(
        State.AMBIGUOUS,
        _clip01(held),
        len(candidates),
        shares,
        f"{len(candidates)} hypotheses fit the scan, weights "
        + ", ".join(f"{w:.0%}" for w in shares),
    )


class MapAgreement:
    """Does the map vouch for the leading pose? A filter's memory of how many consecutive
    updates the map has explained fewer than ``explained_below`` of the scan's end points at
    its leading hypothesis (:func:`ceamcl.sensors.map_agreement.explained_share`). At
    ``explained_updates`` of them, :meth:`apply` turns a LOCALISED or AMBIGUOUS state into
    LOST: whatever the fitness says, most of what the robot sees is not where the map puts
    it, update after update (a filter drifting in a room the map holds elsewhere, a map
    that no longer matches the building, readings from another map). One scan that does
    not agree (a crowd passing, a door opened) leaves the state alone.

    The fitness and the wall-crossing test see this only in part: the fitness is the
    calibrated likelihood's, which forgives end points a few decimetres from a wall, and
    readings that end short of the map's walls (people, furniture, a mis-mapped room)
    cross none. On freiburg-079-corrected a tracked pose has a median share of 0.90.

    Each filter keeps one, fed once per update: :meth:`observe` counts an update once,
    however often the state is read in it (``step``: the filter's update counter); an
    update left unread breaks the run of updates. The filter's own decisions (CEAMCL's
    recovery) read the state without it (docs/state.md).
    """

    def __init__(self, grid: OccupancyGrid, thresholds: StateThresholds = DEFAULT_THRESHOLDS):
        self.grid = grid
        self.thresholds = thresholds
        self.reset()

    def reset(self) -> None:
        """Forget every update (a new initialisation)."""
        self._step: int | None = None
        self._before = 0  # the run of updates before ``_step``
        self._streak = 0
        self._share = math.nan
        self._pose: NDArray[np.float64] | None = None
        self._hits: tuple[LaserScan, PreparedScan] | None = None

    def observe(
        self, step: int, scan: LaserScan | None, pose: NDArray[np.float64]
    ) -> tuple[int, float]:
        """Judge ``step``'s scan at ``pose``: returns the updates running below
        ``explained_below``, this one included, and the share (NaN: nothing to judge, which
        breaks the run). An update counts once: read again at the same pose, the first answer
        comes back; read at another leading pose (CEAMCL's recovery replaced its species after
        the first read), the update is judged again at that pose, in place of the first."""
        p = np.asarray(pose, dtype=np.float64)
        if self._judged(step, p):
            return self._streak, self._share
        t = self.thresholds
        share = self.share_at(step, scan, p)
        if self._step != step:
            running = self._step is not None and step == self._step + 1
            self._before = self._streak if running else 0
            self._step = step
        # no reading of the scan ends (a dead laser, open space): nothing vouches for the pose,
        # and such updates run on like unexplained ones; without a scan the run breaks
        below = share < t.explained_below or (scan is not None and math.isnan(share))
        self._streak = self._before + 1 if below else 0
        self._share = share
        self._pose = p.copy()
        return self._streak, share

    def share_at(self, step: int, scan: LaserScan | None, pose: NDArray[np.float64]) -> float:
        """The share :meth:`observe` gives ``step``'s scan at ``pose``, without counting the
        update: the share already judged when that update was read at that pose, else
        computed (NaN without a scan)."""
        p = np.asarray(pose, dtype=np.float64)
        if self._judged(step, p):
            return self._share
        if scan is None:
            return math.nan
        # the scan's end points, prepared once: the leading pose and the anchor's (CEAMCL,
        # departure 18) judge the same scan
        if self._hits is None or self._hits[0] is not scan:
            self._hits = (scan, end_points(scan))
        return explained_share(
            self.grid, p, scan, self.thresholds.explained_tol_m, hits=self._hits[1]
        )

    def _judged(self, step: int, pose: NDArray[np.float64]) -> bool:
        """Was ``step`` read at ``pose`` last?"""
        return self._step == step and self._pose is not None and np.array_equal(pose, self._pose)

    def apply(
        self,
        state: LocalisationState,
        step: int,
        scan: LaserScan | None,
        hypotheses: Sequence[Hypothesis],
    ) -> LocalisationState:
        """``state`` (read from ``hypotheses``) with the update's ``map_explained``, or LOST
        when the map has not vouched for the leading hypothesis (the heaviest, as
        :func:`read_hypotheses` reads it) for ``explained_updates`` updates. INITIALISING is
        left alone; every other state observes the update, so the run of updates goes on
        while the filter says LOST for another reason."""
        if state.state is State.INITIALISING or not hypotheses:
            return state
        lead = int(np.argmax(_shares(hypotheses)))  # the first of equals, as argsort's order
        streak, share = self.observe(step, scan, np.asarray(hypotheses[lead].pose))
        t = self.thresholds
        if state.state is State.LOST or streak < t.explained_updates:
            if scan is not None and math.isnan(share):  # an empty scan fits every pose
                why = f"{state.reason}; but no reading of this scan ends: nothing confirmed it"
                return replace(state, map_explained=share, reason=why)
            return replace(state, map_explained=share)
        if math.isnan(share):
            return LocalisationState(
                State.LOST,
                1.0,
                0,
                (),
                f"no reading of the scan ends on anything the map could hold, for {streak} "
                "updates running (a laser that returns nothing, or open space): nothing "
                "confirms the pose, whatever its fitness (an empty scan fits every pose)",
                share,
            )
        return LocalisationState(
            State.LOST,
            _clip01(1.0 - share / t.explained_below),
            0,
            (),
            f"the map explains {share:.0%} of the scan's end points at the leading pose, "
            f"below {t.explained_below:.0%} for {streak} updates running: it does not hold "
            f"what the robot sees there",
            share,
        )


def read_particles(
    particles: ParticleSet,
    steps: int,
    hypotheses: Callable[[], Sequence[Hypothesis]],
    thresholds: StateThresholds = DEFAULT_THRESHOLDS,
    crossing: Crossing | None = None,
    agreement: MapAgreement | None = None,
    scan: LaserScan | None = None,
) -> LocalisationState:
    """The state of a particle filter (MCL, GMCL, KLD-AMCL) from its clusters
    (``hypotheses()``, read by :func:`read_hypotheses` with ``crossing``), then, with an
    ``agreement``, the map's agreement with ``scan`` at step ``steps``
    (:meth:`MapAgreement.apply`); INITIALISING while it holds no particle or has not stepped
    (``steps``) since its initialisation."""
    if particles.n == 0:
        return initialising("no particles yet")
    if steps == 0:
        return initialising()
    hyps = hypotheses()
    state = read_hypotheses(hyps, thresholds, crossing)
    return state if agreement is None else agreement.apply(state, steps, scan, hyps)


class ParticleClusterState:
    """``state()`` for a particle filter (MCL, GMCL, KLD-AMCL): :func:`read_particles` over
    its clusters, readings through walls from :func:`wall_crossing` and the map's agreement
    with the last scan. The filter provides the attributes below and ``hypotheses()``."""

    name: str
    particle_set: ParticleSet
    t: int
    grid: OccupancyGrid
    last_scan: LaserScan | None
    map_agreement: MapAgreement
    #: optional: a filter that keeps it is refused before its initialisation; one that does
    #: not (a subclass written to docs/architecture.md) is read as it stands
    _initialised: bool

    def hypotheses(self) -> list[Hypothesis]:
        raise NotImplementedError

    def state(self, hypotheses: Sequence[Hypothesis] | None = None) -> LocalisationState:
        """Read from the particle clusters (``hypotheses`` when the caller has them already),
        then the map's agreement with the scans (:class:`MapAgreement`). Before the first
        initialisation: :class:`~ceamcl.errors.FilterStateError`."""
        require_initialised(self, "state")
        known = hypotheses
        return read_particles(
            self.particle_set,
            self.t,
            self.hypotheses if known is None else lambda: known,
            crossing=wall_crossing(self.grid, self.last_scan),
            agreement=self.map_agreement,
            scan=self.last_scan,
        )


def read_covariance(
    estimate: PoseEstimate, thresholds: StateThresholds = DEFAULT_THRESHOLDS
) -> LocalisationState:
    """The state of a filter that shows only a pose and its covariance (the Nav2 peer), as its
    users read it today: LOCALISED when the position and heading standard deviations are within
    ``covariance_position_std_m`` and ``covariance_heading_std_rad``, LOST otherwise. A
    covariance cannot tell several hypotheses from a wide one: never AMBIGUOUS."""
    t = thresholds
    c = np.asarray(estimate.covariance, dtype=np.float64)
    pos = _position_std(c)
    head = math.sqrt(c[2, 2]) if math.isfinite(c[2, 2]) and c[2, 2] >= 0 else math.inf
    ratio = max(pos / t.covariance_position_std_m, head / t.covariance_heading_std_rad)
    if not np.all(np.isfinite(estimate.pose)) or not math.isfinite(ratio):
        return LocalisationState(State.LOST, 1.0, 0, (), "the estimate or covariance is not finite")
    if ratio <= 1.0:
        return LocalisationState(
            State.LOCALISED,
            _clip01(1.0 - ratio / 2.0),
            1,
            (1.0,),
            f"covariance within bounds (position std {pos:.2f} m, heading std {head:.2f} rad)",
        )
    return LocalisationState(
        State.LOST,
        _clip01(1.0 - 1.0 / ratio),
        0,
        (),
        f"covariance too wide (position std {pos:.2f} m, heading std {head:.2f} rad)",
    )


def summarise_states(
    states: Sequence[LocalisationState | None], times: Sequence[float] | np.ndarray
) -> dict[str, object]:
    """The state over a run, for ``summary.json``: the final state, its confidence and reason,
    the share of steps in each state, and when the filter first said LOCALISED (``None``:
    never). Steps without a state are left out."""
    known = [(float(t), s) for t, s in zip(times, states, strict=True) if s is not None]
    if not known:
        return {}
    t0 = known[0][0]
    final = known[-1][1]
    first = next((t - t0 for t, s in known if s.state is State.LOCALISED), None)
    return {
        "final_state": final.state.name,
        "final_state_confidence": final.confidence,
        "final_state_hypotheses": final.n_hypotheses,
        "final_state_reason": final.reason,
        "first_localised_state_s": first,
        "state_shares": {
            st.name: sum(s.state is st for _, s in known) / len(known) for st in STATES
        },
    }


__all__ = [
    "DEFAULT_THRESHOLDS",
    "STATES",
    "LocalisationState",
    "MapAgreement",
    "State",
    "StateThresholds",
    "initialising",
    "read_covariance",
    "read_hypotheses",
    "read_particles",
    "summarise_states",
]
