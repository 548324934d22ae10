"""Occupancy grid: cells, world <-> cell transforms, free space, distance field, sampling.

Conventions follow ROS ``nav_msgs/OccupancyGrid``: ``data[iy, ix]`` holds 0 (free), 100
(occupied) or -1 (unknown); row 0 is the row at the map origin (lowest y), so an image on disk
is flipped vertically relative to this array. The origin is the pose ``(x, y, yaw)`` of the
corner of cell (0, 0) in the world frame; a non-zero yaw is honoured everywhere (ROS amcl
ignores it, we do not).
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import wrap
from ceamcl.errors import MapFormatError, check_rng
from ceamcl.maps.distance import distance_cells, distance_from_squared, squared_distance_cells

T = TypeVar("T")

FREE = 0
OCCUPIED = 100
UNKNOWN = -1


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A 2D occupancy grid map.

    Attributes:
        data: ``(height, width)`` int8 array of 0 (free), 100 (occupied), -1 (unknown);
            intermediate values 1..99 (probabilities from ``scale`` mode) count as occupied
            when >= 65 and free when <= 19, like ROS amcl, and unknown otherwise.
        resolution: cell side in metres.
        origin: ``(x, y, yaw)`` of the corner of cell (0, 0) in the world frame.
    """

    data: NDArray[np.int8]
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = field(default="map", compare=False)

    def __post_init__(self) -> None:
        data = np.asarray(self.data)
        if data.ndim != 2 or data.shape[0] < 1 or data.shape[1] < 1:
            raise MapFormatError(f"map data: expected a non-empty 2D array, got shape {data.shape}")
        if not np.isfinite(self.resolution) or self.resolution <= 0:
            raise MapFormatError(f"resolution: expected a positive number, got {self.resolution}")
        if len(self.origin) != 3 or not all(np.isfinite(v) for v in self.origin):
            raise MapFormatError(
                f"origin: expected three finite numbers [x, y, yaw], got {self.origin}"
            )
        if data.dtype.kind not in "iub":
            raise MapFormatError(
                f"map data: expected whole numbers -1 (unknown) or 0..100, got {data.dtype}"
            )
        bad = (data < -1) | (data > 100)
        if bad.any():  # a cast to int8 wrapped them: 255 became unknown, 200 became -56
            r, c = (int(v) for v in np.argwhere(bad)[0])
            raise MapFormatError(
                f"map data: expected -1 (unknown) or 0..100 (occupancy in percent), got "
                f"{int(data[r, c])} at row {r}, column {c} ({int(bad.sum())} such cells)"
            )
        data = np.ascontiguousarray(data, dtype=np.int8)
        data.setflags(write=False)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "resolution", float(self.resolution))
        object.__setattr__(self, "origin", tuple(float(v) for v in self.origin))

    # ------------------------------------------------------------------ shape and equality
    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height of the map in metres."""
        return self.width * self.resolution, self.height * self.resolution

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return (
            self.data.shape == other.data.shape
            and bool(np.array_equal(self.data, other.data))
            and bool(np.isclose(self.resolution, other.resolution, rtol=1e-9, atol=0))
            and bool(np.allclose(self.origin, other.origin, rtol=0, atol=1e-9))
        )

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------ pickling
    @cached_property
    def digest(self) -> str:
        """A digest of the cells, resolution and origin: equal grids have equal digests."""
        h = hashlib.blake2b(digest_size=16)
        h.update(repr((self.data.shape, self.resolution, self.origin)).encode())
        h.update(self.data.tobytes())
        return h.hexdigest()

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled as its cells alone, without the layers derived from them (masks, distance
        fields, :meth:`derived`): a worker process that receives trial after trial on one map
        was sent them with every trial (657 MB a trial on fr-clinic's 40 million cells, for
        40 MB of cells), and the command's peak memory grew by 1.2 GB for them. Where the
        receiving process already holds the same grid, it gets that one back, layers and all
        (:func:`_unpickled`)."""
        return (_unpickled, (self.data, self.resolution, self.origin, self.name, self.digest))

    def __copy__(self) -> OccupancyGrid:
        return self  # immutable: its cells are read-only and its layers derive from them

    def __deepcopy__(self, memo: dict[int, Any]) -> OccupancyGrid:
        return self  # a deep copy of a filter shares its map, as filters of one map do

    # ------------------------------------------------------------------ cell classes
    @cached_property
    def occupied_mask(self) -> NDArray[np.bool_]:
        """Cells that are obstacles (value >= 65, as ROS amcl's ``occupied_thresh``)."""
        return self.data >= 65

    @cached_property
    def free_mask(self) -> NDArray[np.bool_]:
        """Cells known to be free (0 <= value <= 19)."""
        return (self.data >= 0) & (self.data <= 19)

    @cached_property
    def unknown_mask(self) -> NDArray[np.bool_]:
        return ~(self.occupied_mask | self.free_mask)

    @cached_property
    def blocking_mask(self) -> NDArray[np.bool_]:
        """Cells that stop a laser beam: occupied or unknown (as ROS amcl's ray caster)."""
        return ~self.free_mask

    @cached_property
    def free_cells(self) -> NDArray[np.intp]:
        """Flat indices of the free cells, for uniform sampling over free space."""
        return np.flatnonzero(self.free_mask)

    @property
    def free_area_m2(self) -> float:
        return float(self.free_cells.size) * self.resolution**2

    # ------------------------------------------------------------------ distance fields
    @cached_property
    def squared_cells_to_occupied(self) -> NDArray[np.int32] | None:
        """Squared Euclidean distance in cells from each cell centre to the nearest occupied
        cell centre (exact, integer; :mod:`ceamcl.maps.distance`); ``None`` without obstacles.
        Computed once per map; the likelihood field tabulates its per-cell values from it."""
        if not self.occupied_mask.any():
            return None
        return squared_distance_cells(self.occupied_mask)

    @cached_property
    def distance_to_occupied(self) -> NDArray[np.float64]:
        """Euclidean distance in metres from each cell centre to the nearest occupied cell centre.

        Computed once per map (exact EDT). A map without obstacles gets +inf everywhere.
        """
        sq = self.squared_cells_to_occupied
        if sq is None:
            return np.full(self.occupied_mask.shape, np.inf)
        return distance_from_squared(sq, self.resolution)

    @cached_property
    def distance_to_blocking(self) -> NDArray[np.float64]:
        """Distance to the nearest occupied or unknown cell; the ray caster marches on it."""
        return distance_cells(self.blocking_mask, self.resolution)

    # ------------------------------------------------------------------ transforms
    def world_to_map(
        self, x: ArrayLike, y: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World coordinates to metric coordinates in the grid frame (corner of cell (0,0) at 0)."""
        ox, oy, oyaw = self.origin
        dx = np.asarray(x, dtype=np.float64) - ox
        dy = np.asarray(y, dtype=np.float64) - oy
        if oyaw == 0.0:
            return dx, dy
        c, s = np.cos(oyaw), np.sin(oyaw)
        return c * dx + s * dy, -s * dx + c * dy

    def map_to_world(
        self, mx: ArrayLike, my: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        ox, oy, oyaw = self.origin
        mx_ = np.asarray(mx, dtype=np.float64)
        my_ = np.asarray(my, dtype=np.float64)
        if oyaw == 0.0:
            return mx_ + ox, my_ + oy
        c, s = np.cos(oyaw), np.sin(oyaw)
        return ox + c * mx_ - s * my_, oy + s * mx_ + c * my_

    def poses_to_map(self, poses: ArrayLike) -> NDArray[np.float64]:
        """``(N, 3)`` world poses to the grid frame (heading relative to the grid's x axis)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        out = np.empty_like(p)
        out[:, 0], out[:, 1] = self.world_to_map(p[:, 0], p[:, 1])
        out[:, 2] = wrap(p[:, 2] - self.origin[2])
        return out

    def world_to_cell(
        self, x: ArrayLike, y: ArrayLike
    ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Cell indices ``(ix, iy)`` containing the world points (may lie outside the grid)."""
        mx, my = self.world_to_map(x, y)
        return (
            np.floor(mx / self.resolution).astype(np.intp),
            np.floor(my / self.resolution).astype(np.intp),
        )

    def cell_to_world(
        self, ix: ArrayLike, iy: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World coordinates of cell centres."""
        mx = (np.asarray(ix, dtype=np.float64) + 0.5) * self.resolution
        my = (np.asarray(iy, dtype=np.float64) + 0.5) * self.resolution
        return self.map_to_world(mx, my)

    def in_bounds(self, ix: ArrayLike, iy: ArrayLike) -> NDArray[np.bool_]:
        ix_ = np.asarray(ix)
        iy_ = np.asarray(iy)
        return (ix_ >= 0) & (ix_ < self.width) & (iy_ >= 0) & (iy_ < self.height)

    def is_free(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.bool_]:
        """Whether world points fall in known-free cells (points off the map are not free)."""
        ix, iy = self.world_to_cell(x, y)
        inside = self.in_bounds(ix, iy)
        out = np.zeros(np.shape(ix), dtype=bool)
        out[inside] = self.free_mask[iy[inside], ix[inside]]
        return out

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` of the map's corners in the world frame."""
        w, h = self.size_m
        xs, ys = self.map_to_world(np.array([0.0, w, w, 0.0]), np.array([0.0, 0.0, h, h]))
        return float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max())

    # ------------------------------------------------------------------ sampling
    def sample_free_poses(self, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """``n`` poses uniform over free space (uniform in area) with uniform headings."""
        check_rng(rng)
        if n < 0:
            raise ValueError(f"n: expected a non-negative count, got {n}")
        cells = self.free_cells
        if cells.size == 0:
            raise MapFormatError(f"map {self.name!r} has no free cell to sample poses from")
        pick = cells[rng.integers(0, cells.size, size=n)]
        iy, ix = np.divmod(pick, self.width)
        mx = (ix + rng.random(n)) * self.resolution
        my = (iy + rng.random(n)) * self.resolution
        x, y = self.map_to_world(mx, my)
        theta = wrap(rng.uniform(-np.pi, np.pi, size=n))
        return np.column_stack([x, y, theta])

    def derived(self, key: Hashable, make: Callable[[], T]) -> T:
        """What ``make`` derives from the grid, computed once per ``key`` and kept with the
        grid (the grid never changes, as its distance fields are kept): a summary several
        filters of one map share, e.g. the heading density's map normals."""
        cache: dict[Hashable, Any] = self.__dict__.setdefault("_derived", {})
        if key not in cache:
            cache[key] = make()
        return cache[key]

    def with_data(self, data: ArrayLike, name: str | None = None) -> OccupancyGrid:
        """A copy with other cell values (same geometry)."""
        return OccupancyGrid(
            np.asarray(data, dtype=np.int8),
            self.resolution,
            self.origin,
            name=self.name if name is None else name,
        )


#: The grid this process unpickled last: a worker running trial after trial on a map computes
#: its distance fields once rather than at every trial. One is kept, with the layers its
#: filters derived, as the memory budget counts them per worker
#: (:data:`ceamcl.budget.FILTER_CELL_BYTES`); a worker given another map lets it go.
_LAST_UNPICKLED: list[OccupancyGrid] = []
_LAST_UNPICKLED_LOCK = threading.Lock()


def _unpickled(
    data: NDArray[np.int8],
    resolution: float,
    origin: tuple[float, float, float],
    name: str,
    digest: str,
) -> OccupancyGrid:
    """The grid :meth:`OccupancyGrid.__reduce__` pickled: the one this process unpickled last
    if it has the same digest and name, or a new one (then kept in its place)."""
    with _LAST_UNPICKLED_LOCK:
        last = _LAST_UNPICKLED[0] if _LAST_UNPICKLED else None
    if last is not None and last.digest == digest and last.name == name:
        return last
    grid = OccupancyGrid(data, resolution, origin, name=name)
    if grid.digest == digest:  # a grid this code pickled (else keep nothing for it)
        with _LAST_UNPICKLED_LOCK:
            _LAST_UNPICKLED[:] = [grid]
    return grid
