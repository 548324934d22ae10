"""How much of a scan the map explains at a pose.

A scan's *end points* are its readings that end short of the sensor's maximum; one is
*explained* at a pose when it lies within ``tol_m`` of an obstacle of the map there
(:func:`ceamcl.sensors.beam_skip.near_obstacle`, the test beam skipping makes). The share of
explained end points is the plainest measure of agreement between a scan, a pose and a map:
about 0.9 on the real logs at a pose the filter has right (median), and below one half where
the map does not hold what the robot sees, whatever the pose. Two readers use it:

* the benchmark's check of a log's ground truth (:func:`ceamcl.io.truth_check.truth_fit`), at
  the true pose;
* the localisation state (:class:`ceamcl.filters.state.MapAgreement`), at the filter's leading
  pose: a pose the map cannot vouch for, update after update, is not a localised pose.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.beam_skip import near_obstacle
from ceamcl.sensors.scan import LaserScan, PreparedScan, prepare_scan

#: An end point counts as explained within this distance of an obstacle of the map (m).
EXPLAINED_TOL_M = 0.15


def end_points(scan: LaserScan) -> PreparedScan:
    """The readings of ``scan`` that :func:`explained_share` judges: every usable reading short
    of the maximum (a caller that judges one scan at several poses prepares them once); none
    for a scan without beams."""
    return prepare_scan(scan, max(scan.n_beams, 1), keep_max_range=False)


def explained_share(
    grid: OccupancyGrid,
    pose: ArrayLike,
    scan: LaserScan,
    tol_m: float = EXPLAINED_TOL_M,
    hits: PreparedScan | None = None,
) -> float:
    """The share of ``scan``'s end points (every usable reading short of the maximum) within
    ``tol_m`` of an occupied cell of ``grid`` when the scan is taken at ``pose`` (3,); NaN when
    no reading ends (a scan without beams too) or the pose is not finite (nothing to judge).
    ``hits``: :func:`end_points` of ``scan``, when already prepared."""
    p = np.asarray(pose, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(p)) or scan.n_beams == 0:
        return math.nan
    if hits is None:
        hits = end_points(scan)
    if hits.n_beams == 0:
        return math.nan
    return float(near_obstacle(grid, p, hits, tol_m).mean())


__all__ = ["EXPLAINED_TOL_M", "end_points", "explained_share"]
