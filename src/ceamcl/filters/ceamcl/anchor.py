"""The filter's last confident pose, carried on by the odometry (docs/ceamcl.md, departure 14).

At an update where the state (as the recovery reads it) says LOCALISED, the leading pose is a
*candidate*; it becomes the *anchor* when the map explains that update's scan there
(:class:`~ceamcl.filters.state.MapAgreement`'s share at least its ``explained_below``). The
odometry carries both between updates; beyond ``reach_m`` of travel (``recovery_anchor_m``)
each is forgotten. A candidate is judged when the next one arrives or when a recovery asks for
the anchor, by then from the share the state's reading of that update already computed
(:meth:`~ceamcl.filters.state.MapAgreement.share_at`), so an update pays for no second look at
the map.

While the filter's state says LOST and the leading species has left the anchor, the anchor is
the filter's estimate (:meth:`ConfidentPose.coasting`): the pose the odometry has carried from
the last place the map vouched for, with a covariance that grows with the travel
(:data:`DRIFT_SD_M_PER_M`, :data:`DRIFT_SD_RAD_PER_M`). "Left" is measured against the
odometry's drift envelope (departure 17, :class:`DriftEnvelope`): a few standard deviations of
that covariance, so a species that slides along a room the map holds poorly is caught within a
metre or two; without an envelope, as departure 15 first had it, only after a recovery has
fired and beyond the recovery's drift reach (another place, not a drift).

With an envelope, a LOCALISED pose beyond it of the held anchor does not replace the anchor at
once: a species that slid while the map explained little can fit the next scans better where
it slid to than at the truth. It becomes the anchor once such disagreement has lasted
``conflict_m`` of travel (the anchor, not the species, may be the one that drifted).

With a *contest* (departure 38), a candidate more than :data:`CHAIN_M` from the anchor, inside
the envelope or beyond it, does not replace the anchor at an update where the anchor's own
place fits the scan better than the leading species: a place that won a few cluttered scans
takes the estimate, not the pose the odometry carries.
"""

from __future__ import annotations

import inspect
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.state import MapAgreement
from ceamcl.motion.odometry import OdometryIncrement, apply_increment
from ceamcl.sensors.scan import LaserScan


@dataclass
class _Carried:
    pose: NDArray[np.float64]  # where the odometry has carried it since
    travel: float  # metres travelled since


@dataclass
class _Candidate(_Carried):
    judged_at: NDArray[np.float64]  # the leading pose at its update
    scan: LaserScan | None
    step: int
    anchor_then: NDArray[np.float64] | None  # the anchor's pose at that update


C = TypeVar("C", bound=_Carried)

#: The coasting estimate's standard deviations: at the anchor (a tracked pose's spread), then
#: growing with each metre travelled. Position: per axis, from freiburg-079's raw odometry
#: dead-reckoned from the corrected poses (root mean square drift 0.15, 0.35, 0.71 and 1.61 m
#: after 2, 5, 10 and 20 m: about 0.075 m a metre, 0.053 per axis, rounded up); heading: its
#: median heading drift (0.055 rad after 2 m, 0.29 rad after 20 m). docs/ceamcl.md, departure 15.
BASE_SD_M = 0.1
BASE_SD_RAD = 0.05
DRIFT_SD_M_PER_M = 0.06
DRIFT_SD_RAD_PER_M = 0.015

#: Departure 17 adds the heading's random walk, whose lateral effect grows as travel^1.5 (a
#: wrong heading carries the pose sideways): variance ``HEADING_Q`` rad^2 a metre, from the
#: same drift (0.08 rad standard deviation after 2 m) ...
HEADING_Q = 0.0033
#: ... and as the odometry shows it while the filter runs: each time the map vouches for a pose
#: at least this many metres of travel after the last sample, the heading the odometry carried
#: from there is compared with it ...
DRIFT_BASELINE_M = 1.0
#: ... and the variance a metre it implies beyond the anchor's own spread (``BASE_SD_RAD``, at
#: both ends) enters a running mean with this weight; the larger of it and ``HEADING_Q`` is used.
DRIFT_MEMORY = 0.3
#: Poses the map vouches for beyond the anchor's envelope are "the same place" while each
#: lies within this many metres of the one before, carried on by the odometry (departure 17):
#: a species that follows the scans while the odometry is wrong moves less than this between
#: updates (fr079's unsigned odometry backing up: 0.5 m at Nav2's pace); another place a
#: recovery proposes lies metres away.
CHAIN_M = 1.0


def drift_sd_m(travel: float, heading_q: float | None = None) -> float:
    """The anchor's position standard deviation (per axis) after ``travel`` metres: 0.1 m plus
    0.06 m a metre (departure 15, ``heading_q=None``), or with the heading's random walk of
    variance ``heading_q`` a metre as well (departure 17)."""
    if heading_q is None:
        return BASE_SD_M + DRIFT_SD_M_PER_M * travel
    linear = DRIFT_SD_M_PER_M * travel
    return float(np.sqrt(BASE_SD_M**2 + linear**2 + heading_q * travel**3 / 3.0))


@dataclass(frozen=True)
class DriftEnvelope:
    """How far a pose may lie from the anchor and still be the anchor's place drifted
    (departure 17): ``sd`` standard deviations of the anchor's drift (:func:`drift_sd_m`), at
    least ``min_m``; a LOCALISED pose beyond it replaces the anchor once the disagreement has
    lasted ``conflict_m`` metres of travel."""

    sd: float
    min_m: float
    conflict_m: float

    def reach_m(self, travel: float, heading_q: float = HEADING_Q) -> float:
        """The envelope's radius after ``travel`` metres, the odometry's heading drifting
        with variance ``heading_q`` a metre."""
        return max(self.min_m, self.sd * drift_sd_m(travel, heading_q))


class _WeakMethod:
    """A bound method that holds its object weakly. The filter that owns a
    :class:`ConfidentPose` hands it its own methods; a strong reference back would make a cycle
    that keeps a finished filter (its likelihood field: 307 MiB on a 40-million-cell map) alive
    until the cyclic garbage collector runs, which in a worker running trial after trial was
    several trials later. Copied or pickled, it refers to the copy of its object."""

    __slots__ = ("_ref",)

    def __init__(self, method: Callable[..., Any]) -> None:
        self._ref = weakref.WeakMethod(method)

    def __call__(self, *args: Any) -> Any:
        method = self._ref()
        if method is None:
            raise ReferenceError("the filter that owns this anchor is gone")
        return method(*args)

    def __reduce__(self) -> tuple[type[_WeakMethod], tuple[Any]]:
        return (_WeakMethod, (self._ref(),))


def _weakly(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn``, holding its object weakly when it is a bound method (:class:`_WeakMethod`)."""
    return _WeakMethod(fn) if inspect.ismethod(fn) else fn


class ConfidentPose:
    """The anchor (``None`` when there is none within ``reach_m`` of travel) and at most one
    candidate waiting to be judged."""

    def __init__(
        self,
        agreement: MapAgreement,
        envelope: Callable[[], DriftEnvelope | None],
        contest: Callable[[int, NDArray[np.float64]], bool] | None = None,
    ) -> None:
        self.agreement = agreement
        self.envelope = _weakly(envelope)  # read at each use: the filter's config may change
        # departure 38: whether, at update ``step``, the anchor's place (its pose then) fits
        # the scan better than the leading species
        self.contest = None if contest is None else _weakly(contest)
        # the heading variance a metre the odometry has shown (a property of the robot: a new
        # start keeps it)
        self._heading_q = HEADING_Q
        self.reset()

    def heading_q(self) -> float:
        """The heading variance a metre of travel the anchor is given: the odometry's as
        measured (:data:`DRIFT_BASELINE_M`, :data:`DRIFT_MEMORY`), never below
        :data:`HEADING_Q` (freiburg-079's raw odometry)."""
        return max(HEADING_Q, self._heading_q)

    def reset(self) -> None:
        """Forget both (a new start)."""
        self._probe: _Carried | None = None  # the pose the last drift sample started from
        self._anchor: _Carried | None = None
        self._candidate: _Candidate | None = None
        self._searching = False
        # the last LOCALISED pose the map vouched for beyond the anchor's envelope, carried on;
        # its travel: metres since the first of its chain (CHAIN_M)
        self._challenger: _Carried | None = None

    def propose(self, pose: NDArray[np.float64], scan: LaserScan | None, step: int) -> None:
        """A LOCALISED update's leading pose; the candidate before it is judged first."""
        self._judge()
        p = np.array(pose, dtype=np.float64)
        then = None if self._anchor is None else self._anchor.pose.copy()
        self._candidate = _Candidate(p.copy(), 0.0, p, scan, step, then)

    def carry(self, increment: OdometryIncrement, reach_m: float | None) -> None:
        """Move both by the odometry; forget whichever has travelled beyond ``reach_m``
        (``None``: both)."""
        trans = abs(float(increment.trans))
        self._anchor = self._moved(self._anchor, increment, trans, reach_m)
        self._candidate = self._moved(self._candidate, increment, trans, reach_m)
        self._probe = self._moved(self._probe, increment, trans, reach_m)
        self._challenger = self._moved(self._challenger, increment, trans, reach_m)

    def anchor(self) -> tuple[NDArray[np.float64], float] | None:
        """The anchor's pose and the metres travelled since it was confident, the waiting
        candidate judged first."""
        self._judge()
        if self._anchor is None:
            return None
        return self._anchor.pose.copy(), self._anchor.travel

    def held(self) -> bool:
        """Whether an anchor is held, as it stands (no waiting candidate judged)."""
        return self._anchor is not None

    def search(self) -> None:
        """A recovery fired: the filter is looking elsewhere for the robot, and its leading
        species may be a place the recovery proposed, not the pose it tracked, until the map
        vouches for a pose again (a new anchor)."""
        self._searching = True

    def coasting(
        self, drift_reach_m: float | None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], float | None] | None:
        """The anchor as an estimate: its pose, a 3 x 3 covariance, diagonal, whose standard
        deviations grow with the travel since the anchor was confident, and the distance
        beyond which a leading species has left it (``None``: any distance). With an
        envelope, that distance is the envelope's; without one (departure 15), only while
        the filter searches (:meth:`search`), and ``drift_reach_m``. ``None``: no anchor, or
        not searching."""
        envelope = self.envelope()
        if envelope is None and not self._searching:
            return None  # judging a waiting candidate could only end a search
        held = self.anchor()
        if held is None or (envelope is None and not self._searching):
            return None
        pose, travel = held
        if envelope is None:  # departure 15
            sd_m = drift_sd_m(travel)
            sd_rad = BASE_SD_RAD + DRIFT_SD_RAD_PER_M * travel
            return pose, np.diag([sd_m**2, sd_m**2, sd_rad**2]), drift_reach_m
        q = self.heading_q()
        sd_m = drift_sd_m(travel, q)
        var_rad = BASE_SD_RAD**2 + q * travel
        return pose, np.diag([sd_m**2, sd_m**2, var_rad]), envelope.reach_m(travel, q)

    @staticmethod
    def _moved(
        c: C | None, increment: OdometryIncrement, trans: float, reach_m: float | None
    ) -> C | None:
        if c is None:
            return None
        c.travel += trans
        if reach_m is None or c.travel > reach_m:
            return None
        c.pose = apply_increment(c.pose, increment.rot1, increment.trans, increment.rot2)[0]
        return c

    def _judge(self) -> None:
        c, self._candidate = self._candidate, None
        if c is None:
            return
        share = self.agreement.share_at(c.step, c.scan, c.judged_at)
        if not share >= self.agreement.thresholds.explained_below:  # NaN: not judged, not kept
            return
        if self._anchor is not None and not self._prevails(c, self._anchor):
            return  # not yet: the species may be the one that slid
        self._anchor = _Carried(c.pose, c.travel)
        self._searching = False
        self._challenger = None
        self._sample_drift(c)

    def _sample_drift(self, c: _Candidate) -> None:
        """The new anchor ``c`` against the pose the odometry carried from the last sample's
        (:data:`DRIFT_BASELINE_M` or more before): the heading variance a metre their gap
        implies beyond the anchor's own spread (:data:`BASE_SD_RAD` at both ends) enters the
        running mean (:data:`DRIFT_MEMORY`); ``c`` starts the next sample."""
        if self.envelope() is None:
            return  # departure 15 alone: the drift of freiburg-079's odometry
        probe = self._probe
        if probe is not None:
            travel = probe.travel - c.travel  # the probe's travel at c's update
            if travel < DRIFT_BASELINE_M:
                return
            turned = math.remainder(float(c.pose[2] - probe.pose[2]), 2.0 * math.pi)
            q = max(0.0, turned**2 - 2.0 * BASE_SD_RAD**2) / travel
            self._heading_q = (1.0 - DRIFT_MEMORY) * self._heading_q + DRIFT_MEMORY * q
        self._probe = _Carried(c.pose.copy(), c.travel)

    def _prevails(self, c: _Candidate, anchor: _Carried) -> bool:
        """Whether candidate ``c`` (the map vouches for it) replaces the held ``anchor``: at
        once within the anchor's envelope (or without an envelope); beyond it, once the
        same place (the challenger: each candidate within :data:`CHAIN_M` of the one before,
        carried on) has disagreed with the anchor over ``conflict_m`` metres of travel. A
        candidate elsewhere starts a new challenger. Never, with a contest, at an update where
        the anchor's place fits better than a candidate more than ``CHAIN_M`` from it
        (departure 38)."""
        envelope = self.envelope()
        if envelope is None:
            return True
        apart = _apart(c, anchor)
        if (
            self.contest is not None
            and c.anchor_then is not None
            and apart > CHAIN_M
            and self.contest(c.step, c.anchor_then)
        ):
            return False
        q = self.heading_q()
        if apart <= envelope.reach_m(anchor.travel - c.travel, q):
            self._challenger = None
            return True
        rival = self._challenger
        if rival is None or _apart(c, rival) > CHAIN_M:
            self._challenger = _Carried(c.pose.copy(), c.travel)
            return envelope.conflict_m <= 0.0
        rival.pose = c.pose.copy()  # the place moves on with the scans, not the odometry
        return rival.travel - c.travel >= envelope.conflict_m


def _apart(c: _Carried, other: _Carried) -> float:
    """Metres between two carried poses' positions."""
    return float(np.hypot(c.pose[0] - other.pose[0], c.pose[1] - other.pose[1]))
