"""Occupancy grid mapping with known poses (Probabilistic Robotics, sec. 9.2, Table 9.1).

Every cell keeps the log-odds of being occupied, starting at 0 (p = 0.5, unknown). Each beam
is traced through the grid from the laser to its end point with an exact grid traversal
(Amanatides and Woo), and the inverse sensor model adds

* ``l_free = log(p_free / (1 - p_free))`` (< 0) to every cell the beam passes through, and
* ``l_occ = log(p_occ / (1 - p_occ))`` (> 0) to the cell holding the end point,

each sum clamped to ``[-l_clamp, l_clamp]`` so a cell can change its mind (eq. 9.7 with the
prior's log-odds 0). Readings are classified as in gmapping:

* a reading within ``max_range_m`` (the usable range) is a hit;
* a reading beyond it, but short of the sensor's maximum, clears free space up to
  ``max_range_m`` and marks no hit (the far end is too uncertain to trust);
* a no-return reading (at or beyond the sensor's maximum, or +inf) clears free space up to
  ``no_return_free_m`` (or the sensor's maximum, if shorter) and marks no hit;
* a reading at or below the sensor's minimum (-inf included) is ignored, and so is NaN: REP 117
  makes NaN an erroneous reading, not "no return", so it clears nothing.

Before the grid is allocated its size (the extent of the poses and end points at
``resolution_m``) is checked against the memory budget (:mod:`ceamcl.budget`).

A cell becomes occupied (100) when its probability reaches ``occupied_prob`` and free (0) when
it falls to ``free_prob``; cells in between, and cells no beam reached, are unknown (-1). The
thresholds are those :func:`ceamcl.maps.ros_io.save_map` writes, so the saved map loads back
unchanged. The grid covers every laser pose and traced end point plus ``margin_m``.

The traversal is a Numba kernel over all beams of the log (sequential, since beams update the
same cells); the per-beam geometry is computed with NumPy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from ceamcl import budget
from ceamcl.errors import LogFormatError
from ceamcl.io.recorded import RobotLog
from ceamcl.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from ceamcl.maps.ros_io import SAVE_FREE_THRESH, SAVE_OCCUPIED_THRESH

__all__ = ["MapStats", "MappingConfig", "build_map", "log_odds_map"]


@dataclass(frozen=True)
class MappingConfig:
    """Settings of the occupancy grid mapper (module docstring).

    resolution_m: cell side.
    max_range_m: usable range; longer readings clear free space up to it and mark no hit.
    no_return_free_m: how far a no-return reading clears free space.
    p_occ, p_free: inverse sensor model at the end point and along the beam.
    l_clamp: bound on each cell's log-odds.
    occupied_prob, free_prob: thresholds of the final map.
    margin_m: free border around everything the beams reached.
    beam_stride: use every ``beam_stride``-th beam (1 = all).
    """

    resolution_m: float = 0.05
    max_range_m: float = 25.0
    no_return_free_m: float = 10.0
    p_occ: float = 0.7
    p_free: float = 0.4
    l_clamp: float = 8.0
    occupied_prob: float = SAVE_OCCUPIED_THRESH
    free_prob: float = SAVE_FREE_THRESH
    margin_m: float = 1.0
    beam_stride: int = 1

    def __post_init__(self) -> None:
        checks = {
            "resolution_m": self.resolution_m > 0 and math.isfinite(self.resolution_m),
            "max_range_m": self.max_range_m > 0 and math.isfinite(self.max_range_m),
            "no_return_free_m": 0 <= self.no_return_free_m < math.inf,
            "p_occ": 0.5 < self.p_occ < 1,
            "p_free": 0 < self.p_free < 0.5,
            "l_clamp": self.l_clamp > 0,
            "occupied_prob": 0.5 < self.occupied_prob < 1,
            "free_prob": 0 < self.free_prob < 0.5,
            "margin_m": self.margin_m >= 0,
            "beam_stride": self.beam_stride >= 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"{name}: value {getattr(self, name)!r} is out of range")

    @property
    def l_occ(self) -> float:
        return math.log(self.p_occ / (1.0 - self.p_occ))

    @property
    def l_free(self) -> float:
        return math.log(self.p_free / (1.0 - self.p_free))


@dataclass(frozen=True)
class MapStats:
    """What went into a map: beams traced, hits, no-return beams, cells by class."""

    scans: int
    beams: int
    hits: int
    no_return: int
    cells_free: int
    cells_occupied: int
    cells_unknown: int
    free_area_m2: float
    size_m: tuple[float, float]


@numba.njit(cache=True)
def _trace(
    x0: NDArray[np.float64],
    y0: NDArray[np.float64],
    x1: NDArray[np.float64],
    y1: NDArray[np.float64],
    hit: NDArray[np.bool_],
    logodds: NDArray[np.float32],
    l_free: float,
    l_occ: float,
    l_clamp: float,
) -> None:
    """Add the inverse sensor model of each beam (coordinates in cells) to ``logodds``."""
    h, w = logodds.shape
    for b in range(x0.shape[0]):
        ix = math.floor(x0[b])
        iy = math.floor(y0[b])
        ex = math.floor(x1[b])
        ey = math.floor(y1[b])
        dx = x1[b] - x0[b]
        dy = y1[b] - y0[b]
        step_x = 1 if dx > 0 else -1
        step_y = 1 if dy > 0 else -1
        t_dx = abs(1.0 / dx) if dx != 0.0 else math.inf
        t_dy = abs(1.0 / dy) if dy != 0.0 else math.inf
        t_x = ((ix + 1 - x0[b]) if dx > 0 else (x0[b] - ix)) * t_dx if dx != 0.0 else math.inf
        t_y = ((iy + 1 - y0[b]) if dy > 0 else (y0[b] - iy)) * t_dy if dy != 0.0 else math.inf
        n = abs(ex - ix) + abs(ey - iy)
        for _ in range(n):
            if 0 <= ix < w and 0 <= iy < h:
                v = logodds[iy, ix] + l_free
                logodds[iy, ix] = max(v, -l_clamp)
            if t_x < t_y:
                ix += step_x
                t_x += t_dx
            else:
                iy += step_y
                t_y += t_dy
        if 0 <= ex < w and 0 <= ey < h:
            if hit[b]:
                v = logodds[ey, ex] + l_occ
                logodds[ey, ex] = min(v, l_clamp)
            else:
                v = logodds[ey, ex] + l_free
                logodds[ey, ex] = max(v, -l_clamp)


def _beams(
    log: RobotLog, laser_world: NDArray[np.float64], cfg: MappingConfig
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], int]:
    """Start points ``(B, 2)``, end points ``(B, 2)``, hit flags, no-return count."""
    starts, ends, hits = [], [], []
    no_return = 0
    for k in range(len(log)):
        scan = log.scan(k)
        idx = np.arange(0, scan.n_beams, cfg.beam_stride)
        r = scan.ranges[idx]
        bearing = laser_world[k, 2] + scan.angles[idx]
        valid = ~(r <= scan.range_min) & ~np.isnan(r)  # REP 117: NaN is an error, dropped
        nr = r >= scan.range_max
        no_return += int(np.count_nonzero(nr & valid))
        is_hit = valid & ~nr & (r <= cfg.max_range_m)
        clear = min(cfg.no_return_free_m, scan.range_max)
        length = np.where(nr, clear, np.minimum(np.nan_to_num(r), cfg.max_range_m))
        keep = valid & (length > 0)
        length, bearing, is_hit = length[keep], bearing[keep], is_hit[keep]
        ends.append(
            np.column_stack(
                [
                    laser_world[k, 0] + length * np.cos(bearing),
                    laser_world[k, 1] + length * np.sin(bearing),
                ]
            )
        )
        starts.append(np.repeat(laser_world[k : k + 1, :2], length.size, axis=0))
        hits.append(is_hit)
    if not starts:
        empty = np.zeros((0, 2))
        return empty, empty, np.zeros(0, dtype=bool), 0
    return np.concatenate(starts), np.concatenate(ends), np.concatenate(hits), no_return


def log_odds_map(
    log: RobotLog,
    laser_world: NDArray[np.float64],
    config: MappingConfig | None = None,
) -> tuple[NDArray[np.float32], tuple[float, float, float], MapStats]:
    """Log-odds grid ``(H, W)`` of a log, the grid's origin and the statistics.

    ``laser_world[k]`` is the laser's world pose at scan ``k``.
    """
    logodds, _, origin, stats = _map(log, laser_world, config or MappingConfig())
    return logodds, origin, stats


def _map(
    log: RobotLog, laser_world: NDArray[np.float64], cfg: MappingConfig
) -> tuple[NDArray[np.float32], NDArray[np.int8], tuple[float, float, float], MapStats]:
    """:func:`log_odds_map` and the classified cells."""
    if len(log) == 0:
        raise ValueError("log_odds_map: the log has no scans")
    start, end, hit, no_return = _beams(log, laser_world, cfg)
    if hit.size == 0:
        raise LogFormatError(
            f"{getattr(log, 'path', 'log')}: no usable reading in {len(log)} scans (all NaN, "
            "-inf or at or below the sensor's minimum); nothing to build a map from"
        )
    pts = np.vstack([laser_world[:, :2], end]) if end.size else laser_world[:, :2]
    res = cfg.resolution_m
    x_min, y_min = pts.min(axis=0) - cfg.margin_m
    x_max, y_max = pts.max(axis=0) + cfg.margin_m
    x_min, y_min = math.floor(x_min / res) * res, math.floor(y_min / res) * res
    width_m, height_m = float(x_max - x_min), float(y_max - y_min)
    budget.require(
        f"{getattr(log, 'path', 'log')}: map built at resolution {res:g} m over the log's "
        f"{width_m:.0f} m x {height_m:.0f} m",
        math.ceil(width_m / res) * math.ceil(height_m / res),
        budget.MAP_CELL_BYTES,
        "map cells",
    )
    width = max(1, math.ceil(width_m / res))
    height = max(1, math.ceil(height_m / res))
    logodds = np.zeros((height, width), dtype=np.float32)
    _trace(
        (start[:, 0] - x_min) / res,
        (start[:, 1] - y_min) / res,
        (end[:, 0] - x_min) / res,
        (end[:, 1] - y_min) / res,
        hit,
        logodds,
        cfg.l_free,
        cfg.l_occ,
        cfg.l_clamp,
    )
    origin = (float(x_min), float(y_min), 0.0)
    data = classify(logodds, cfg)
    stats = MapStats(
        scans=len(log),
        beams=int(hit.size),
        hits=int(hit.sum()),
        no_return=no_return,
        cells_free=int(np.count_nonzero(data == FREE)),
        cells_occupied=int(np.count_nonzero(data == OCCUPIED)),
        cells_unknown=int(np.count_nonzero(data == UNKNOWN)),
        free_area_m2=float(np.count_nonzero(data == FREE)) * res * res,
        size_m=(width * res, height * res),
    )
    return logodds, data, origin, stats


def classify(logodds: NDArray[np.float32], config: MappingConfig) -> NDArray[np.int8]:
    """Trinary cell values from log-odds with the config's probability thresholds."""
    l_occ_t = math.log(config.occupied_prob / (1.0 - config.occupied_prob))
    l_free_t = math.log(config.free_prob / (1.0 - config.free_prob))
    data = np.full(logodds.shape, UNKNOWN, dtype=np.int8)
    data[logodds >= l_occ_t] = OCCUPIED
    data[logodds <= l_free_t] = FREE
    return data


def build_map(
    log: RobotLog,
    laser_world: NDArray[np.float64],
    config: MappingConfig | None = None,
    *,
    name: str = "map",
) -> tuple[OccupancyGrid, MapStats]:
    """The occupancy grid of a log from the laser's world poses (module docstring)."""
    cfg = config or MappingConfig()
    _, data, origin, stats = _map(log, laser_world, cfg)
    return OccupancyGrid(data, cfg.resolution_m, origin, name=name), stats
