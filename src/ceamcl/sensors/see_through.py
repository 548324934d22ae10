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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.sensors.raycast import cast_fan
from ceamcl.sensors.scan import LaserScan, PreparedScan, laser_poses, prepare_scan


def readings_through_walls(
    grid: OccupancyGrid, poses: ArrayLike, prepared: PreparedScan, margin_m: float
) -> NDArray[np.bool_]:
    """``(N, M)``: whether each prepared reading, seen from each robot pose ``(N, 3)``, ends
    more than ``margin_m`` beyond the first occupied cell of ``grid`` along its ray (module
    docstring). Poses must be finite."""
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
