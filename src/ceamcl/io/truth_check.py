"""How well a log's ground truth explains its own scans on the map the filters use.

A SLAM-corrected log is the ground truth of our real-log benchmarks, and its pose at a scan can
be wrong: the map built from the whole log then lacks what that scan shows (the log's other
visits cleared it), and every filter's error there measures the truth as much as the filter.
:func:`truth_fit` gives, for each scan with a true pose, the share of its end points that lie
within ``tol_m`` of an obstacle of the map when the scan is placed at the truth;
:func:`doubtful_truth` finds the stretches of at least ``min_scans`` scans with truth whose share
stays below ``below``. On fr079 raw with the map of freiburg-079-corrected the median share is
0.89 (5th percentile 0.63), and one stretch, scans 1148-1239, falls to 0.04-0.50: a room whose
walls the map does not hold where the truth puts them (docs/real-data.md).

The evaluation scores every scan as it is; this is a warning beside the scores, not a filter
on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.map_agreement import EXPLAINED_TOL_M, explained_share
from ceamcl.sensors.scan import LaserScan

__all__ = [
    "TRUTH_FIT_BELOW",
    "TRUTH_FIT_MIN_SCANS",
    "TRUTH_FIT_TOL_M",
    "LogWithTruth",
    "TruthDoubt",
    "doubtful_truth",
    "truth_fit",
]


class LogWithTruth(Protocol):
    """What the check reads of a log (a recorded or a simulated one)."""

    @property
    def true_poses(self) -> NDArray[np.float64] | None: ...

    def __len__(self) -> int: ...

    def scan(self, k: int) -> LaserScan: ...


#: An end point counts as explained within this distance of an obstacle of the map.
TRUTH_FIT_TOL_M = EXPLAINED_TOL_M
#: A scan's truth is doubtful below this share of explained end points ...
TRUTH_FIT_BELOW = 0.5
#: ... over at least this many consecutive scans with truth.
TRUTH_FIT_MIN_SCANS = 5


def truth_fit(
    log: LogWithTruth, grid: OccupancyGrid, *, tol_m: float = TRUTH_FIT_TOL_M
) -> NDArray[np.float64]:
    """For each scan, the share of its end points (usable readings short of the sensor's
    maximum) within ``tol_m`` of an occupied cell of ``grid`` when the scan is placed at the
    true pose (:func:`ceamcl.sensors.map_agreement.explained_share`, which the localisation
    state reads at the filter's pose); NaN at scans without a true pose or without such a
    reading (nothing to judge)."""
    out = np.full(len(log), np.nan)
    truth = log.true_poses
    if truth is None:
        return out
    for k in np.flatnonzero(np.all(np.isfinite(truth), axis=1)):
        out[k] = explained_share(grid, truth[k], log.scan(int(k)), tol_m)
    return out


@dataclass(frozen=True)
class TruthDoubt:
    """:func:`doubtful_truth`'s answer. ``stretches``: ``(first scan, last scan, lowest
    share)`` of each doubtful stretch (scan indices of the log); ``median``: the median share
    over the scans with a share (NaN without any)."""

    shares: NDArray[np.float64]
    median: float
    below: float
    min_scans: int
    stretches: tuple[tuple[int, int, float], ...]

    def mask(self, scans: int) -> NDArray[np.bool_]:
        """Which of a log's first ``scans`` scans lie in a doubtful stretch."""
        out = np.zeros(scans, dtype=bool)
        for first, last, _ in self.stretches:
            out[first : last + 1] = True
        return out

    def summary(self) -> str:
        """One sentence for a console or a report."""
        if math.isnan(self.median):
            return "ground truth vs the map: no scan with a true pose to judge"
        head = (
            f"ground truth vs the map: a median {100 * self.median:.0f} % of a scan's end "
            f"points within {TRUTH_FIT_TOL_M} m of the map's obstacles at the true pose"
        )
        if not self.stretches:
            return head + f"; no stretch below {100 * self.below:.0f} %"
        parts = ", ".join(f"{a}-{b} (down to {100 * lo:.0f} %)" for a, b, lo in self.stretches)
        return (
            head + f"; doubtful (below {100 * self.below:.0f} % for {self.min_scans} scans or "
            f"more) at scans {parts}: errors there measure the truth as much as the filter"
        )


def doubtful_truth(
    log: LogWithTruth,
    grid: OccupancyGrid,
    *,
    below: float = TRUTH_FIT_BELOW,
    min_scans: int = TRUTH_FIT_MIN_SCANS,
    tol_m: float = TRUTH_FIT_TOL_M,
) -> TruthDoubt:
    """The stretches where at least ``min_scans`` judged scans have a share of explained end
    points (:func:`truth_fit`) below ``below``, gaps of fewer than ``min_scans`` judged scans
    between them bridged."""
    shares = truth_fit(log, grid, tol_m=tol_m)
    judged = np.flatnonzero(np.isfinite(shares))
    if judged.size == 0:
        return TruthDoubt(shares, math.nan, below, min_scans, ())
    low = shares[judged] < below
    runs: list[list[int]] = []  # [first, end) positions in ``judged``, short gaps bridged
    for i in np.flatnonzero(low):
        if runs and i - runs[-1][1] < min_scans:
            runs[-1][1] = int(i) + 1
        else:
            runs.append([int(i), int(i) + 1])
    stretches = []
    for a, b in runs:
        if int(low[a:b].sum()) >= min_scans:
            span = judged[a:b]
            stretches.append((int(span[0]), int(span[-1]), float(shares[span].min())))
    return TruthDoubt(shares, float(np.median(shares[judged])), below, min_scans, tuple(stretches))
