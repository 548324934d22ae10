"""Physical sense of a log and a map together: warnings for inputs that run but cannot mean
what was intended (a map smaller than the robot, a sensor maximum that leaves no usable
reading). Each is one :class:`~ceamcl.errors.InputWarning` line naming the file or flag."""

from __future__ import annotations

import math
import warnings

import numpy as np

from ceamcl.errors import InputWarning
from ceamcl.io.recorded import RecordedLog
from ceamcl.maps.grid import OccupancyGrid

__all__ = ["ROBOT_RADIUS_M", "physical_warnings"]

#: Radius of the robot's footprint assumed by the checks (a Pioneer-sized indoor robot).
ROBOT_RADIUS_M = 0.2


def physical_warnings(log: RecordedLog, grid: OccupancyGrid, map_source: str) -> list[str]:
    """Warn (and return the messages) about a map that cannot hold the robot and a sensor
    maximum below one map cell or below every reading. (A maximum below the sensor's minimum
    is refused when the log is opened, :func:`ceamcl.io.logs.open_log`.)"""
    out: list[str] = []
    w, h = grid.size_m
    footprint = math.pi * ROBOT_RADIUS_M**2
    if min(w, h) < 2 * ROBOT_RADIUS_M or grid.free_area_m2 < footprint:
        out.append(
            f"{map_source}: the map ({w:g} m x {h:g} m, {grid.free_area_m2:g} m^2 free) is "
            f"smaller than the robot (radius {ROBOT_RADIUS_M} m); expected a map of the building"
        )
    if len(log):
        rmax = float(np.min(log.range_max))
        rmin = float(np.max(log.range_min))
        finite = log.ranges_flat[np.isfinite(log.ranges_flat)]
        usable = finite[(finite > rmin)]
        if rmax < grid.resolution:
            out.append(
                f"{log.path}: max range {rmax:g} m is shorter than one map cell "
                f"({grid.resolution:g} m): no reading can be scored"
            )
        elif usable.size and not np.any(usable < rmax):
            out.append(
                f"{log.path}: every reading is at or beyond the max range {rmax:g} m: the "
                "scans carry no hit (check --max-range)"
            )
    for message in out:
        warnings.warn(message, InputWarning, stacklevel=2)
    return out
