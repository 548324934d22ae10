"""2D ray casting on an occupancy grid.

:func:`cast_rays` marches each ray on the grid's distance field (sphere tracing): far from
obstacles it leaps by the clearance ``d - sqrt(2) * resolution``, which can never jump over a
blocking cell; near obstacles it steps exactly from cell boundary to cell boundary (DDA), so
the returned range is where the ray enters the first blocking cell. Rays that leave the map or
travel ``max_range`` return ``max_range`` (no return). Blocking cells are occupied or unknown,
as in ROS amcl's ``map_calc_range``. Compiled with Numba, parallel over rays.

:func:`cast_rays_reference` is the brute-force reference: tiny fixed steps along each ray.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors._compile import serial_and_parallel

_EPS_M = 1e-9


@numba.njit(cache=True, fastmath=False, inline="always")
def _march(
    x: float,
    y: float,
    theta: float,
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> float:
    h, w = blocking.shape
    dx = math.cos(theta)
    dy = math.sin(theta)
    leap_margin = 1.4143 * res
    t = 0.0
    while t < max_range:
        px = x + t * dx
        py = y + t * dy
        fx = px / res
        fy = py / res
        if fx < 0.0 or fy < 0.0:
            return max_range
        ix = int(fx)
        iy = int(fy)
        # A point on a cell boundary (up to round-off between px / res and ix * res) belongs to
        # the cell the ray is entering. Otherwise the DDA step below is <= 0 and a ray running
        # (nearly) along that boundary advances by only _EPS_M per iteration.
        if dx > 0.0 and (ix + 1) * res <= px:
            ix += 1
        elif dx < 0.0 and ix * res >= px:
            ix -= 1
        if dy > 0.0 and (iy + 1) * res <= py:
            iy += 1
        elif dy < 0.0 and iy * res >= py:
            iy -= 1
        if ix < 0 or iy < 0 or ix >= w or iy >= h:
            return max_range
        if blocking[iy, ix]:
            return t
        d = dist[iy, ix]
        if d > 2.0 * res:
            t += d - leap_margin
            continue
        # DDA: go to the next cell boundary along the ray.
        tx = math.inf
        ty = math.inf
        if dx > 0.0:
            tx = ((ix + 1) * res - px) / dx
        elif dx < 0.0:
            tx = (ix * res - px) / dx
        if dy > 0.0:
            ty = ((iy + 1) * res - py) / dy
        elif dy < 0.0:
            ty = (iy * res - py) / dy
        t += min(tx, ty) + _EPS_M
    return max_range


@numba.njit(cache=True, inline="always")
def _mounted_pose(
    x: float, y: float, theta: float, mount_x: float, mount_y: float, mount_yaw: float
) -> tuple[float, float, float]:
    """Pose of a sensor mounted at ``(mount_x, mount_y, mount_yaw)`` on a body at
    ``(x, y, theta)`` (the compiled form of :func:`ceamcl.sensors.scan.laser_poses`)."""
    c = math.cos(theta)
    s = math.sin(theta)
    return x + c * mount_x - s * mount_y, y + s * mount_x + c * mount_y, theta + mount_yaw


@numba.njit(cache=True, parallel=True)
def _cast_many(
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    thetas: NDArray[np.float64],
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> NDArray[np.float64]:
    n = xs.shape[0]
    out = np.empty(n)
    for i in numba.prange(n):
        out[i] = _march(xs[i], ys[i], thetas[i], blocking, dist, res, max_range)
    return out


def _cast_fan_py(
    poses: NDArray[np.float64],
    bearings: NDArray[np.float64],
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> NDArray[np.float64]:
    n = poses.shape[0]
    m = bearings.shape[0]
    out = np.empty((n, m))
    for i in numba.prange(n):
        for j in range(m):
            out[i, j] = _march(
                poses[i, 0], poses[i, 1], poses[i, 2] + bearings[j], blocking, dist, res, max_range
            )
    return out


_cast_fan_serial, _cast_fan_parallel = serial_and_parallel(_cast_fan_py)
#: Fewer rays than this are cast on one thread: a parallel launch costs more than it saves
#: (the crossing point on 2 cores: about five poses of 60 readings).
PARALLEL_MIN_RAYS = 256


def cast_rays(
    grid: OccupancyGrid,
    origins: ArrayLike,
    angles: ArrayLike,
    max_range: float,
) -> NDArray[np.float64]:
    """Range to the first blocking cell for rays from world points ``origins`` ``(N, 2)`` at
    world headings ``angles`` ``(N,)``; ``max_range`` where nothing is hit."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
    mx, my = grid.world_to_map(o[:, 0], o[:, 1])
    ma = a - grid.origin[2]
    return _cast_many(
        np.ascontiguousarray(mx),
        np.ascontiguousarray(my),
        np.ascontiguousarray(ma),
        grid.blocking_mask,
        grid.distance_to_blocking,
        grid.resolution,
        float(max_range),
    )


def cast_fan(
    grid: OccupancyGrid,
    sensor_poses: ArrayLike,
    bearings: ArrayLike,
    max_range: float,
    *,
    through_unknown: bool = False,
) -> NDArray[np.float64]:
    """Ranges ``(N, M)``: from each sensor pose ``(N, 3)`` along each bearing ``(M,)``.
    ``through_unknown``: only occupied cells stop a ray (the farthest the map allows)."""
    mp = grid.poses_to_map(sensor_poses)
    if through_unknown:
        blocking, dist = grid.occupied_mask, grid.distance_to_occupied
    else:
        blocking, dist = grid.blocking_mask, grid.distance_to_blocking
    b = np.ascontiguousarray(np.asarray(bearings, dtype=np.float64).reshape(-1))
    kernel = _cast_fan_parallel if mp.shape[0] * b.size >= PARALLEL_MIN_RAYS else _cast_fan_serial
    return kernel(
        np.ascontiguousarray(mp),
        b,
        blocking,
        dist,
        grid.resolution,
        float(max_range),
    )


def cast_rays_reference(
    grid: OccupancyGrid,
    origins: ArrayLike,
    angles: ArrayLike,
    max_range: float,
    step_fraction: float = 0.02,
) -> NDArray[np.float64]:
    """Brute force: sample each ray every ``step_fraction * resolution`` metres."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
    step = step_fraction * grid.resolution
    ts = np.arange(0.0, max_range, step)
    out = np.full(o.shape[0], float(max_range))
    for i in range(o.shape[0]):
        xs = o[i, 0] + ts * np.cos(a[i])
        ys = o[i, 1] + ts * np.sin(a[i])
        ix, iy = grid.world_to_cell(xs, ys)
        inside = grid.in_bounds(ix, iy)
        blocked = np.zeros(ts.size, dtype=bool)
        blocked[inside] = grid.blocking_mask[iy[inside], ix[inside]]
        stop = ~inside | blocked
        if stop.any():
            k = int(np.argmax(stop))
            out[i] = ts[k] if blocked[k] else max_range
    return out


# ---------------------------------------------------------------------------------------------
# Ray-cast lookup table (expected range per (cell, discretised heading)), filled lazily.

#: Slot values of :attr:`RangeTable.slot` other than row numbers.
SLOT_UNASSIGNED = -1  # free cell without a row (yet, or the memory budget is spent): cast exactly
SLOT_BLOCKING = -2  # occupied or unknown cell: every ray from it has range 0
_UNCAST = -1.0  # table entry not cast yet


@numba.njit(cache=True, fastmath=False)
def _cast_entry(
    ix: int,
    iy: int,
    k: int,
    n_angles: int,
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> np.float32:
    """Table entry ``(cell (ix, iy), heading bin k)``: the exact range from the cell centre at
    heading ``2 pi k / n_angles``, in cells, as float32. Compiled on its own without fastmath
    (never inlined), so an entry has the same value whichever kernel fills it."""
    theta = (2.0 * math.pi / n_angles) * k
    t = _march((ix + 0.5) * res, (iy + 0.5) * res, theta, blocking, dist, res, max_range)
    return np.float32(t / res)


@numba.njit(cache=True)
def _assign_rows(
    poses: NDArray[np.float64],
    offset_x: float,
    offset_y: float,
    slot: NDArray[np.int32],
    res: float,
    n_rows: int,
    capacity: int,
) -> tuple[int, int]:
    """Give a table row to every free cell holding a point ``pose + R(theta) offset``, while
    rows last. Returns ``(rows in use, rows still wanted)``; cells left without a row keep
    ``SLOT_UNASSIGNED``.
    """
    h, w = slot.shape
    wanted = 0
    for i in range(poses.shape[0]):
        px, py, _ = _mounted_pose(poses[i, 0], poses[i, 1], poses[i, 2], offset_x, offset_y, 0.0)
        fx = px / res
        fy = py / res
        if not (fx >= 0.0 and fy >= 0.0 and fx < w and fy < h):
            continue
        ix = int(fx)
        iy = int(fy)
        if slot[iy, ix] == -1:
            if n_rows < capacity:
                slot[iy, ix] = n_rows
                n_rows += 1
            else:
                wanted += 1
                slot[iy, ix] = -3  # counted once; reset below
    if wanted:
        for iy in range(h):
            for ix in range(w):
                if slot[iy, ix] == -3:
                    slot[iy, ix] = -1
    return n_rows, wanted


@numba.njit(cache=True, inline="always")
def _table_range(
    x: float,
    y: float,
    theta: float,
    slot: NDArray[np.int32],
    rows: NDArray[np.float32],
    cos_k: NDArray[np.float64],
    sin_k: NDArray[np.float64],
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> float:
    """Expected range of the ray from map-frame point ``(x, y)`` at heading ``theta`` from the
    table (filling a missing entry on the way); exact cast for cells without a row.

    The table holds the range from the cell centre along the nearest heading bin; the range is
    moved to the actual start point to first order, ``r - (p - c) . u``, which is exact for a
    ray that hits a flat face and removes the 0.7-cell position error."""
    h, w = slot.shape
    fx = x / res
    fy = y / res
    if not (fx >= 0.0 and fy >= 0.0 and fx < w and fy < h):
        return max_range
    ix = int(fx)
    iy = int(fy)
    s = slot[iy, ix]
    if s == -2:
        return 0.0
    if s < 0:
        return _march(x, y, theta, blocking, dist, res, max_range)
    n_angles = rows.shape[1]
    k = math.floor(theta * (n_angles / (2.0 * math.pi)) + 0.5) % n_angles
    v = rows[s, k]
    if v < 0.0:  # not cast yet (a negative sentinel rather than NaN)
        v = _cast_entry(ix, iy, k, n_angles, blocking, dist, res, max_range)
        rows[s, k] = v  # benign race: every thread writes the same value
    e = v * res
    if e >= max_range:
        return max_range
    e -= (x - (ix + 0.5) * res) * cos_k[k] + (y - (iy + 0.5) * res) * sin_k[k]
    return min(max(e, 0.0), max_range)


@numba.njit(cache=True, parallel=True)
def _fill_rows(
    cells_x: NDArray[np.int64],
    cells_y: NDArray[np.int64],
    slot: NDArray[np.int32],
    rows: NDArray[np.float32],
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> None:
    n_angles = rows.shape[1]
    for i in numba.prange(cells_x.shape[0]):
        s = slot[cells_y[i], cells_x[i]]
        if s < 0:
            continue
        for k in range(n_angles):
            if rows[s, k] < 0.0:
                rows[s, k] = _cast_entry(
                    cells_x[i], cells_y[i], k, n_angles, blocking, dist, res, max_range
                )


@numba.njit(cache=True, parallel=True)
def _table_fan(
    poses: NDArray[np.float64],
    bearings: NDArray[np.float64],
    slot: NDArray[np.int32],
    rows: NDArray[np.float32],
    cos_k: NDArray[np.float64],
    sin_k: NDArray[np.float64],
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    max_range: float,
) -> NDArray[np.float64]:
    n = poses.shape[0]
    m = bearings.shape[0]
    out = np.empty((n, m))
    for i in numba.prange(n):
        for j in range(m):
            out[i, j] = _table_range(
                poses[i, 0],
                poses[i, 1],
                poses[i, 2] + bearings[j],
                slot,
                rows,
                cos_k,
                sin_k,
                blocking,
                dist,
                res,
                max_range,
            )
    return out


class RangeTable:
    """Expected ranges per (free cell, heading bin), as fast localisers precompute them.

    ``n_angles`` heading bins over the full turn (360: 1 degree). Entries are the exact range
    from the cell centre (:func:`_march`), stored in cells as float32 (relative error 6e-8).
    A lookup takes the nearest heading bin and moves the range from the cell centre to the
    actual start point (see :func:`_table_range`). Rows are given to cells when a pose first
    lands in them and entries are cast when first read, so a tracking filter only pays for
    the cells it visits; :meth:`fill` casts every free cell at once (in parallel).

    Memory is bounded: at most ``max_bytes`` of rows; cells beyond that are cast exactly on
    every call (same results up to the table's approximation, only slower).
    """

    def __init__(
        self, grid: OccupancyGrid, max_range: float, n_angles: int = 360, max_bytes: int = 1 << 28
    ) -> None:
        if n_angles < 4:
            raise ValueError(f"n_angles: expected >= 4, got {n_angles}")
        self.grid = grid
        self.max_range = float(max_range)
        self.n_angles = int(n_angles)
        self.row_bytes = 4 * self.n_angles
        self.max_rows = int(min(max_bytes // self.row_bytes, int(np.count_nonzero(grid.free_mask))))
        slot = np.full(grid.data.shape, SLOT_UNASSIGNED, dtype=np.int32)
        slot[grid.blocking_mask] = SLOT_BLOCKING
        self.slot = slot
        self.rows = np.full((min(1024, self.max_rows), self.n_angles), _UNCAST, dtype=np.float32)
        self.n_rows = 0
        angles = (2.0 * np.pi / self.n_angles) * np.arange(self.n_angles)
        self.cos_k = np.ascontiguousarray(np.cos(angles))
        self.sin_k = np.ascontiguousarray(np.sin(angles))

    @property
    def nbytes(self) -> int:
        """Bytes held: the rows allocated and the slot map."""
        return int(self.rows.nbytes + self.slot.nbytes)

    @property
    def filled_fraction(self) -> float:
        """Share of the allocated rows' entries cast so far."""
        if self.n_rows == 0:
            return 0.0
        return float(np.mean(self.rows[: self.n_rows] >= 0.0))

    def reserve(
        self, poses_map: NDArray[np.float64], offset: tuple[float, float] = (0.0, 0.0)
    ) -> None:
        """Give rows to the free cells holding the points ``offset`` (in each pose's frame) of
        grid-frame poses ``(N, 3)``: the laser's cells for robot poses and its mounting
        offset."""
        p = np.ascontiguousarray(poses_map, dtype=np.float64).reshape(-1, 3)
        res = self.grid.resolution
        while True:
            self.n_rows, wanted = _assign_rows(
                p,
                float(offset[0]),
                float(offset[1]),
                self.slot,
                res,
                self.n_rows,
                self.rows.shape[0],
            )
            if wanted == 0 or self.rows.shape[0] >= self.max_rows:
                return
            cap = min(max(2 * self.rows.shape[0], self.n_rows + wanted), self.max_rows)
            grown = np.full((cap, self.n_angles), _UNCAST, dtype=np.float32)
            grown[: self.n_rows] = self.rows[: self.n_rows]
            self.rows = grown

    def fill(self) -> None:
        """Cast every entry of every free cell (as far as the memory budget allows)."""
        iy, ix = np.nonzero(self.grid.free_mask)
        res = self.grid.resolution
        self.reserve(np.column_stack([(ix + 0.5) * res, (iy + 0.5) * res, np.zeros(ix.size)]))
        _fill_rows(
            ix.astype(np.int64),
            iy.astype(np.int64),
            self.slot,
            self.rows,
            self.grid.blocking_mask,
            self.grid.distance_to_blocking,
            self.grid.resolution,
            self.max_range,
        )

    def cast_fan(
        self, sensor_poses_map: NDArray[np.float64], bearings: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Table ranges ``(N, M)`` from grid-frame sensor poses ``(N, 3)`` along ``bearings``."""
        p = np.ascontiguousarray(sensor_poses_map, dtype=np.float64).reshape(-1, 3)
        self.reserve(p)
        return _table_fan(
            p,
            np.ascontiguousarray(bearings, dtype=np.float64),
            self.slot,
            self.rows,
            self.cos_k,
            self.sin_k,
            self.grid.blocking_mask,
            self.grid.distance_to_blocking,
            self.grid.resolution,
            self.max_range,
        )
