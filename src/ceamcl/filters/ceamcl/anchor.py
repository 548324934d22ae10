"""The filter's last confident pose, carried on by the odometry (docs/ceamcl.md, departure 14).

At an update where the state (as the recovery reads it) says LOCALISED, the leading pose is a
*candidate*; it becomes the *anchor* when the map explains that update's scan there
(:class:`~ceamcl.filters.state.MapAgreement`'s share at least its ``explained_below``). The
odometry carries both between updates; beyond ``reach_m`` of travel (``recovery_anchor_m``)
each is forgotten. A candidate is judged when the next one arrives or when a recovery asks for
the anchor, by then from the share the state's reading of that update already computed
(:meth:`~ceamcl.filters.state.MapAgreement.share_at`), so an update pays for no second look at
the map.

While the filter's state says LOST, a recovery has fired since the anchor was set and the
leading species stands beyond the recovery's drift reach of it, the anchor is the filter's
estimate (departure 15, :meth:`ConfidentPose.coasting`): the pose the odometry has carried from
the last place the map vouched for, with a covariance that grows with the travel
(:data:`DRIFT_SD_M_PER_M`, :data:`DRIFT_SD_RAD_PER_M`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

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


class ConfidentPose:
    """The anchor (``None`` when there is none within ``reach_m`` of travel) and at most one
    candidate waiting to be judged."""

    def __init__(self, agreement: MapAgreement) -> None:
        self.agreement = agreement
        self.reset()

    def reset(self) -> None:
        """Forget both (a new start)."""
        self._anchor: _Carried | None = None
        self._candidate: _Candidate | None = None
        self._searching = False

    def propose(self, pose: NDArray[np.float64], scan: LaserScan | None, step: int) -> None:
        """A LOCALISED update's leading pose; the candidate before it is judged first."""
        self._judge()
        p = np.array(pose, dtype=np.float64)
        self._candidate = _Candidate(p.copy(), 0.0, p, scan, step)

    def carry(self, increment: OdometryIncrement, reach_m: float | None) -> None:
        """Move both by the odometry; forget whichever has travelled beyond ``reach_m``
        (``None``: both)."""
        trans = abs(float(increment.trans))
        self._anchor = self._moved(self._anchor, increment, trans, reach_m)
        self._candidate = self._moved(self._candidate, increment, trans, reach_m)

    def anchor(self) -> tuple[NDArray[np.float64], float] | None:
        """The anchor's pose and the metres travelled since it was confident, the waiting
        candidate judged first."""
        self._judge()
        if self._anchor is None:
            return None
        return self._anchor.pose.copy(), self._anchor.travel

    def search(self) -> None:
        """A recovery fired: the filter is looking elsewhere for the robot, and its leading
        species may be a place the recovery proposed, not the pose it tracked, until the map
        vouches for a pose again (a new anchor)."""
        self._searching = True

    def coasting(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The anchor as an estimate while the filter searches (:meth:`search`): its pose and
        a 3 x 3 covariance, diagonal, whose standard deviations grow with the travel since the
        anchor was confident (``None``: no anchor, or not searching)."""
        if not self._searching:
            return None  # judging a waiting candidate could only end a search
        held = self.anchor()
        if held is None or not self._searching:
            return None
        pose, travel = held
        sd_m = BASE_SD_M + DRIFT_SD_M_PER_M * travel
        sd_rad = BASE_SD_RAD + DRIFT_SD_RAD_PER_M * travel
        return pose, np.diag([sd_m**2, sd_m**2, sd_rad**2])

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
        if share >= self.agreement.thresholds.explained_below:  # NaN: not judged, not kept
            self._anchor = _Carried(c.pose, c.travel)
            self._searching = False
