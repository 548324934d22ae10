"""Readings through walls: what the likelihood field does not see (docs/ceamcl.md).

The likelihood field scores a beam by the distance from its end point to the nearest
obstacle, whatever lies between the sensor and that end point. A pose in the wrong place, or
turned the wrong way in a room of the right shape, can therefore explain a scan about as well
as the true pose while a quarter of its readings pass through the map's walls.

:func:`readings_through_walls` finds those readings: a reading goes *through a wall* when it
ends more than ``margin_m`` beyond the first occupied cell along its ray. Rays are cast through
unknown space, so only walls the map holds count. Max-range readings count as readings to the
sensor's maximum (nothing was seen before it).

:func:`see_through_penalty` is what such a pose loses in the likelihood field: each reading
through a wall is scored as a reading nothing in the map explains (the model's random term,
``z_rand / range_max``), as the beam model would score it; a max-range reading through a wall
loses what a perfectly explained beam scores. A ``tolerance`` share of the readings, those with
the largest losses, is forgiven: maps and buildings disagree (a door closed in the map and open
in the world, glass, a ray that grazes a corner a few centimetres away).

CEAMCL applies the penalty to one pose per species and step, in its evidence
(:class:`~ceamcl.filters.ceamcl.config.CEAMCLConfig`, ``see_through_margin_m``); the state
(:func:`ceamcl.filters.state.wall_crossing`) counts the same readings.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import wrap_one
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors._compile import serial_and_parallel
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.sensors.raycast import PARALLEL_MIN_RAYS, _march, _mounted_pose, cast_fan
from ceamcl.sensors.scan import LaserScan, PreparedScan, laser_poses, prepare_scan


def readings_through_walls(
    grid: OccupancyGrid, poses: ArrayLike, prepared: PreparedScan, margin_m: float
) -> NDArray[np.bool_]:
    """``(N, M)``: whether each prepared reading, seen from each robot pose ``(N, 3)``, ends
    more than ``margin_m`` beyond the first occupied cell of ``grid`` along its ray (module
    docstring). Poses must be finite.

    Compiled in one pass (:func:`_through_walls_py`) with the operations of
    :func:`readings_through_walls_reference` (the laser's pose, the grid's frame, the ray cast
    through unknown space, the comparison), which it equals: the state reads it at every
    update for one pose, where the NumPy steps around the cast cost as much as the cast."""
    p = np.ascontiguousarray(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
    bearings = np.ascontiguousarray(prepared.bearings, dtype=np.float64)
    rays = p.shape[0] * bearings.size
    kernel = _through_walls_parallel if rays >= PARALLEL_MIN_RAYS else _through_walls_serial
    through: NDArray[np.bool_] = kernel(
        p,
        np.asarray(prepared.laser_pose, dtype=np.float64).reshape(3),
        np.asarray(grid.origin, dtype=np.float64).reshape(3),
        bearings,
        np.ascontiguousarray(prepared.ranges, dtype=np.float64),
        grid.occupied_mask,
        grid.distance_to_occupied,
        float(grid.resolution),
        float(prepared.range_max),
        float(margin_m),
    )
    return through


def _through_walls_py(  # type: ignore[no-untyped-def]  # pragma: no cover
    poses, laser, origin, bearings, ranges, occupied, dist, res, max_range, margin
):
    """:func:`readings_through_walls_reference` pose by pose and ray by ray: ``laser_poses``,
    ``OccupancyGrid.poses_to_map``, ``cast_fan(..., through_unknown=True)`` and the comparison,
    operation for operation."""
    n, m = poses.shape[0], bearings.size
    lx, ly, lyaw = laser[0], laser[1], laser[2]
    ox, oy, oyaw = origin[0], origin[1], origin[2]
    co, so = np.cos(oyaw), np.sin(oyaw)
    out = np.empty((n, m), dtype=np.bool_)
    for i in numba.prange(n):
        x, y, yaw = _mounted_pose(poses[i, 0], poses[i, 1], poses[i, 2], lx, ly, lyaw)
        dx, dy = x - ox, y - oy
        if oyaw != 0.0:
            dx, dy = co * dx + so * dy, -so * dx + co * dy
        heading = wrap_one(yaw - oyaw)
        for j in range(m):
            expected = _march(dx, dy, heading + bearings[j], occupied, dist, res, max_range)
            out[i, j] = ranges[j] > expected + margin
    return out


_through_walls_serial, _through_walls_parallel = serial_and_parallel(_through_walls_py)


def readings_through_walls_reference(
    grid: OccupancyGrid, poses: ArrayLike, prepared: PreparedScan, margin_m: float
) -> NDArray[np.bool_]:
    """:func:`readings_through_walls` in NumPy and the ray caster (the reference it equals)."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    expected = cast_fan(
        grid,
        laser_poses(p, prepared.laser_pose),
        prepared.bearings,
        prepared.range_max,
        through_unknown=True,
    )
    through: NDArray[np.bool_] = prepared.ranges[None, :] > expected + margin_m
    return through


def see_through_penalty(
    grid: OccupancyGrid,
    sensor: SensorModel,
    poses: ArrayLike,
    scan: LaserScan,
    margin_m: float,
    tolerance: float,
) -> NDArray[np.float64]:
    """Per pose ``(N, 3)``, a number ``<= 0``: the tempered log-likelihood that the readings
    of ``scan`` (the beams ``sensor`` evaluates, and its max-range readings) passing through a
    wall of ``grid`` lose, the ``tolerance`` share of the beams with the largest losses
    forgiven (module docstring). Zero for a pose that is not finite (its likelihood already
    says it is impossible), for models that see walls themselves (the beam model) or score as
    amcl does, and for a scan without usable beams."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(p.shape[0])
    if not isinstance(sensor, LikelihoodFieldModel) or sensor.scoring != "product":
        return out
    prepared = prepare_scan(scan, sensor.config.max_beams, keep_max_range=True)
    finite = np.all(np.isfinite(p), axis=1)
    if prepared.n_beams == 0 or not finite.any():
        return out
    q = p[finite]
    value = np.where(
        prepared.is_max[None, :],
        sensor.max_log_beam_likelihood(prepared),
        sensor.beam_values(q, prepared),
    )
    through = readings_through_walls(grid, q, prepared, margin_m)
    lost = np.where(through, value - sensor.unexplained_value(prepared), 0.0)
    kept = lost.shape[1] - int(np.floor(tolerance * prepared.n_beams))
    lost = np.sort(lost, axis=1)[:, : max(kept, 0)]
    out[finite] = -sensor.temper * np.sum(lost, axis=1)
    return out
