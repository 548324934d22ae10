"""The likelihood-field sensor model (Probabilistic Robotics, sec. 6.4, Table 6.3).

Each beam end point is projected into the map; its likelihood is a mixture of a Gaussian in
the distance ``d`` to the nearest obstacle and a uniform term:

    p(z_k | x) = z_hit * N(d; 0, sigma_hit^2) + z_rand / range_max

``d`` is read from the map's distance field (computed once per map), capped at
``max_occ_dist_m`` (ROS amcl's ``laser_likelihood_max_dist``); end points off the map get the
cap, and max-range readings are skipped (as in ROS amcl). With ``scoring="product"`` (the
default) beams are combined as a product (a sum of logs), as the textbook does; with
``scoring="ros"`` as ROS amcl does, ``log(1 + sum_k pz_k^3)`` with amcl's ``pz`` (no
``1 / (sqrt(2 pi) sigma_hit)`` on the Gaussian; :mod:`ceamcl.sensors.scoring`).

**The cell behind the face.** A reading ends on an obstacle's face, but the field measures to
the *centre* of the nearest occupied cell: in a map built from scans (and in the simulator's,
whose rays stop at the face) that cell lies behind the face, its centre half a cell beyond where
the reading ends. Scored as read (ROS amcl's lookup), end points that sink into the cell cost
nothing and end points that fall short pay, so poses lean half a cell towards where the laser
looks: 1-3.5 cm on the shared logs and the simulated office at 5 cm cells, and about 4 cm ahead
of the truth while a robot drives (docs/sensor-models.md). Each range is therefore looked up
``end_point_offset_m`` farther, by default half the map's cell (0: as ROS amcl).

The compiled kernel runs in parallel over poses;
:meth:`LikelihoodFieldModel.log_likelihood_reference` is the plain NumPy version the tests hold
it to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors._compile import serial_and_parallel
from ceamcl.sensors.scan import LaserScan, PreparedScan, laser_poses, prepare_scan
from ceamcl.sensors.scoring import check_scoring
from ceamcl.sensors.tempering import CombinedBeams, check_temper, resolve_temper

_SQRT_2PI = math.sqrt(2.0 * math.pi)


@dataclass(frozen=True)
class LikelihoodFieldConfig:
    """Parameters of the likelihood field; defaults are ROS amcl's (max_beams as Nav2).

    scoring: how beams combine, ``"product"`` or ``"ros"`` (:mod:`ceamcl.sensors.scoring`);
    temper applies to the product only.
    """

    z_hit: float = 0.95
    z_rand: float = 0.05
    sigma_hit_m: float = 0.2
    max_occ_dist_m: float = 2.0
    max_beams: int = 60
    temper: float | None = None  # None: the scoring's default (tempering.resolve_temper)
    scoring: str = "product"
    #: how much farther than it reads each range is scored (module docstring, "The cell behind
    #: the face"); ``None``: half the map's cell, 0: as ROS amcl
    end_point_offset_m: float | None = None

    def __post_init__(self) -> None:
        check_temper(self.temper)
        off = self.end_point_offset_m
        if off is not None and not (math.isfinite(off) and off >= 0):
            raise ValueError(f"end_point_offset_m: expected a number >= 0 or None, got {off}")
        check_scoring(self.scoring, resolve_temper(self.temper, self.scoring))
        for name in ("z_hit", "z_rand", "sigma_hit_m", "max_occ_dist_m"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: expected a finite number, got {getattr(self, name)}")
        if not (self.z_hit > 0 and self.z_rand >= 0):
            raise ValueError("z_hit must be > 0 and z_rand >= 0")
        if not self.sigma_hit_m > 0:
            raise ValueError(f"sigma_hit_m: expected > 0, got {self.sigma_hit_m}")
        if not self.max_occ_dist_m > 0:
            raise ValueError(f"max_occ_dist_m: expected > 0, got {self.max_occ_dist_m}")
        if self.max_beams < 1:
            raise ValueError(f"max_beams: expected >= 1, got {self.max_beams}")


def _lf_kernel_py(
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    cos_b: NDArray[np.float64],
    sin_b: NDArray[np.float64],
    laser_x: float,
    laser_y: float,
    index: NDArray[np.integer[Any]],
    values: NDArray[np.float64],
    res: float,
    log_p_off_map: float,
    offset: float,
) -> NDArray[np.float64]:
    """Sum over beams of the precomputed value at each beam's end point, each range read
    ``offset`` farther (module docstring, "The cell behind the face"; ``log p`` for the
    product, ``pz^3`` for ROS scoring; ``log_p_off_map`` is the value off the map). A cell's
    value is ``values[index[cell]]``: the map holds a 2-byte index per cell instead of an
    8-byte value, so the random reads of 10^6 test poses stay in the processor's caches.

    The end point's direction ``theta + yaw_laser + bearing`` is rotated with the angle-sum
    identity from per-pose and per-beam cosines, so no transcendental function runs per beam.
    """
    n = poses.shape[0]
    m = ranges.shape[0]
    h, w = index.shape
    out = np.empty(n)
    inv_res = 1.0 / res
    for i in numba.prange(n):
        c = math.cos(poses[i, 2])
        s = math.sin(poses[i, 2])
        lx = poses[i, 0] + c * laser_x - s * laser_y
        ly = poses[i, 1] + s * laser_x + c * laser_y
        acc = 0.0
        for j in range(m):
            ca = c * cos_b[j] - s * sin_b[j]
            sa = s * cos_b[j] + c * sin_b[j]
            r = ranges[j] + offset
            fx = (lx + r * ca) * inv_res
            fy = (ly + r * sa) * inv_res
            if fx >= 0.0 and fy >= 0.0 and fx < w and fy < h:
                acc += values[index[int(fy), int(fx)]]
            else:
                acc += log_p_off_map
        out[i] = acc
    return out


# One source, compiled twice: threads only pay off for large batches (CEAMCL's 10^6 test
# poses); a few hundred particles are faster on one core than after a thread hand-off.
_lf_kernel_serial, _lf_kernel_parallel = serial_and_parallel(_lf_kernel_py)
PARALLEL_MIN_POSES = 4096


class LikelihoodFieldModel(CombinedBeams):
    """Likelihood field over an occupancy grid (implements :class:`SensorModel`)."""

    def __init__(self, grid: OccupancyGrid, config: LikelihoodFieldConfig | None = None) -> None:
        self.grid = grid
        self.config = config or LikelihoodFieldConfig()
        self._tables: dict[float, tuple[NDArray[np.integer[Any]], NDArray[np.float64]]] = {}
        self._caps: dict[float, float] = {}
        off = self.config.end_point_offset_m
        #: what is added to every range before its end point is looked up
        self.end_point_offset_m = 0.5 * grid.resolution if off is None else float(off)

    @cached_property
    def _dist(self) -> NDArray[np.float64]:
        return np.ascontiguousarray(
            np.minimum(self.grid.distance_to_occupied, self.config.max_occ_dist_m)
        )

    def _beam_value(self, d: NDArray[np.float64], range_max: float) -> NDArray[np.float64]:
        """What the kernel sums per beam whose end point lies ``d`` from an obstacle:
        ``log p(z_k | x)`` for the product, ``pz^3`` for ROS scoring."""
        a_hit, k, c_rand = self._terms_for(range_max)
        p = a_hit * np.exp(-d * d * k) + c_rand
        return p * p * p if self.config.scoring == "ros" else np.log(p)

    def _log_p_table(self, range_max: float) -> NDArray[np.float64]:
        """Per-cell :meth:`_beam_value` for an end point in that cell (depends on ``range_max``
        through ``z_rand / range_max``): ``values[index]`` of :meth:`_indexed_table`."""
        index, values = self._indexed_table(range_max)
        return values[index]

    def _indexed_table(
        self, range_max: float
    ) -> tuple[NDArray[np.integer[Any]], NDArray[np.float64]]:
        """``(index, values)``: each cell's :meth:`_beam_value` is ``values[index[cell]]``;
        computed once per map and range limit.

        A cell's distance is ``sqrt(s) * resolution`` for an integer ``s`` (the squared
        distance in cells), capped at ``max_occ_dist_m``, so its value depends on ``s`` alone,
        up to the cap: ``index`` is ``s`` (clipped at the cap) and ``values`` the short list of
        their values (1,601 entries at 5 cm and 2 m), the same numbers as an ``exp`` and a
        ``log`` per cell. The index takes 2 bytes a cell, a quarter of a table of values: on
        a 1,000 m^2 map (1.8 million cells) scoring 10^6 test poses took 2.2 s with the values
        per cell and about half that with the index (2-core VM; docs/performance.md). A cap
        beyond 65,535 squared cells (12.8 m at 5 cm) lists the distances the map has instead."""
        entry = self._tables.get(range_max)
        if entry is None:
            entry = self._tables[range_max] = self._index_and_values(range_max)
        return entry

    def _index_and_values(
        self, range_max: float
    ) -> tuple[NDArray[np.integer[Any]], NDArray[np.float64]]:
        sq = self.grid.squared_cells_to_occupied
        if sq is None:  # no obstacle: every end point is at the cap
            return (
                np.zeros(self.grid.occupied_mask.shape, dtype=np.uint16),
                np.array([self._cap_value(range_max)]),
            )
        res = self.grid.resolution
        cap = self.config.max_occ_dist_m
        # an s at or past the cap (every larger s is clipped to it), or the largest s of the
        # map when no cell reaches the cap
        top = math.ceil((cap / res) ** 2)
        while math.sqrt(float(top)) * res < cap:
            top += 1
        top = min(top, int(sq.max()))
        index: NDArray[np.integer[Any]]
        if top <= np.iinfo(np.uint16).max:
            s_values = np.arange(top + 1, dtype=np.float64)
            index = np.minimum(sq, top).astype(np.uint16)
        else:
            found, inverse = np.unique(np.minimum(sq, top), return_inverse=True)
            s_values = found.astype(np.float64)
            dtype = np.uint16 if found.size <= 1 << 16 else np.int32
            index = inverse.reshape(sq.shape).astype(dtype)
        d = np.minimum(np.sqrt(s_values) * res, cap)
        return np.ascontiguousarray(index), self._beam_value(d, range_max)

    def _cap_value(self, range_max: float) -> float:
        """The value of an end point at the cap or off the map (cached: every likelihood
        call needs it)."""
        value = self._caps.get(range_max)
        if value is None:
            d = np.array([self.config.max_occ_dist_m])
            value = self._caps[range_max] = float(self._beam_value(d, range_max)[0])
        return value

    def prepare(self, scan: LaserScan) -> PreparedScan:
        return prepare_scan(scan, self.config.max_beams, keep_max_range=False)

    def _terms(self, prepared: PreparedScan) -> tuple[float, float, float]:
        return self._terms_for(prepared.range_max)

    def _terms_for(self, range_max: float) -> tuple[float, float, float]:
        cfg = self.config
        # amcl's pz has no Gaussian normaliser (module docstring); the product's density has.
        norm = 1.0 if cfg.scoring == "ros" else 1.0 / (cfg.sigma_hit_m * _SQRT_2PI)
        return cfg.z_hit * norm, 1.0 / (2.0 * cfg.sigma_hit_m**2), cfg.z_rand / range_max

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        a_hit, _, c_rand = self._terms(prepared)
        return math.log(a_hit + c_rand)

    def log_likelihood(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        mp = self.grid.poses_to_map(poses)
        if prepared.n_beams == 0:
            return np.zeros(mp.shape[0])
        lx, ly, _ = prepared.laser_pose
        value_off = self._cap_value(prepared.range_max)  # an end point off the map
        cos_b, sin_b = prepared.directions
        kernel = _lf_kernel_parallel if mp.shape[0] >= PARALLEL_MIN_POSES else _lf_kernel_serial
        out: NDArray[np.float64] = kernel(
            np.ascontiguousarray(mp),
            prepared.ranges,
            cos_b,
            sin_b,
            lx,
            ly,
            *self._indexed_table(prepared.range_max),
            self.grid.resolution,
            value_off,
            self.end_point_offset_m,
        )
        return self._combined(out)

    def log_likelihood_reference(
        self, poses: ArrayLike, prepared: PreparedScan
    ) -> NDArray[np.float64]:
        """NumPy reference of :meth:`log_likelihood` (no compilation, O(N x M) memory)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if prepared.n_beams == 0:
            return np.zeros(p.shape[0])
        return self._combined(np.sum(self.beam_values(p, prepared), axis=1))

    def beam_values(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        """Per pose and prepared beam, what the kernel sums (``log p(z_k | x)`` for the
        product), ``(N, M)``; plain NumPy."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        lp = laser_poses(p, prepared.laser_pose)
        ang = lp[:, 2:3] + prepared.bearings[None, :]
        r = prepared.ranges + self.end_point_offset_m  # read farther, as the kernel does
        ex = lp[:, 0:1] + r[None, :] * np.cos(ang)
        ey = lp[:, 1:2] + r[None, :] * np.sin(ang)
        ix, iy = self.grid.world_to_cell(ex, ey)
        inside = self.grid.in_bounds(ix, iy)
        d = np.full(ex.shape, self.config.max_occ_dist_m)
        d[inside] = self._dist[iy[inside], ix[inside]]
        return self._beam_value(d, prepared.range_max)

    def unexplained_value(self, prepared: PreparedScan) -> float:
        """What one beam scores when nothing in the map explains it (``log(z_rand /
        range_max)`` for the product)."""
        return float(self._beam_value(np.array([np.inf]), prepared.range_max)[0])
