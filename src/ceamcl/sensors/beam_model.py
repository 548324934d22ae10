"""The beam sensor model (Probabilistic Robotics, sec. 6.3, Table 6.1).

For each beam the expected range ``r*`` is ray-cast in the map from the particle's laser pose;
the measured range ``r`` is scored by the mixture

    p(r | x) = z_hit   * N(r; r*, sigma_hit^2)
             + z_short * lambda_short * exp(-lambda_short * r)   if r < r*
             + z_max                                             if r is a max-range reading
             + z_rand / range_max                                if r < range_max

The short-noise normaliser ``1 / (1 - exp(-lambda r*))`` and the Gaussian's truncation are
dropped, as ROS amcl drops them; with ``scoring="product"`` (the default) the Gaussian keeps
its ``1 / (sqrt(2 pi) sigma)`` so that ``z_hit`` and ``z_rand`` weigh densities of the same
units, and beams combine as a product (a sum of logs). With ``scoring="ros"`` the model is
amcl's: no Gaussian normaliser (amcl's ``pz += z_hit * exp(-z^2 / (2 sigma^2))``) and
``log(1 + sum_k pz_k^3)`` (:mod:`ceamcl.sensors.scoring`). Ray casting and scoring are fused in
one compiled kernel, parallel over particles, with no (N x M) temporaries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors._compile import serial_and_parallel
from ceamcl.sensors.likelihood_field import PARALLEL_MIN_POSES
from ceamcl.sensors.raycast import RangeTable, _march, _mounted_pose, _table_range, cast_fan
from ceamcl.sensors.scan import LaserScan, PreparedScan, laser_poses, prepare_scan
from ceamcl.sensors.scoring import check_scoring
from ceamcl.sensors.tempering import CombinedBeams, check_temper, resolve_temper

_SQRT_2PI = math.sqrt(2.0 * math.pi)

#: How the expected ranges are found: "table" (a ray-cast lookup table, see
#: :class:`~ceamcl.sensors.raycast.RangeTable`) or "exact" (a ray cast per beam and pose).
RAY_CASTING: tuple[str, ...] = ("table", "exact")


@dataclass(frozen=True)
class BeamModelConfig:
    """Parameters of the beam model; defaults are ROS amcl's (max_beams as Nav2).

    scoring: how beams combine, ``"product"`` or ``"ros"`` (:mod:`ceamcl.sensors.scoring`);
    temper applies to the product only.
    """

    z_hit: float = 0.95
    z_short: float = 0.1
    z_max: float = 0.05
    z_rand: float = 0.05
    sigma_hit_m: float = 0.2
    lambda_short: float = 0.1
    max_beams: int = 60
    ray_casting: str = "table"
    table_angles: int = 360
    table_max_mb: float = 256.0
    temper: float | None = None  # None: the scoring's default (tempering.resolve_temper)
    scoring: str = "product"

    def __post_init__(self) -> None:
        check_temper(self.temper)
        check_scoring(self.scoring, resolve_temper(self.temper, self.scoring))
        for name in ("z_hit", "z_short", "z_max", "z_rand", "sigma_hit_m", "lambda_short"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: expected a finite number, got {getattr(self, name)}")
        if not self.z_hit > 0 or min(self.z_short, self.z_max, self.z_rand) < 0:
            raise ValueError("z_hit must be > 0 and z_short, z_max, z_rand >= 0")
        if not self.sigma_hit_m > 0:
            raise ValueError(f"sigma_hit_m: expected > 0, got {self.sigma_hit_m}")
        if not self.lambda_short > 0:
            raise ValueError(f"lambda_short: expected > 0, got {self.lambda_short}")
        if self.max_beams < 1:
            raise ValueError(f"max_beams: expected >= 1, got {self.max_beams}")
        if self.ray_casting not in RAY_CASTING:
            raise ValueError(
                f"ray_casting: expected one of {', '.join(RAY_CASTING)}, got {self.ray_casting!r}"
            )
        if self.table_angles < 4:
            raise ValueError(f"table_angles: expected >= 4, got {self.table_angles}")
        if not self.table_max_mb >= 0:
            raise ValueError(f"table_max_mb: expected >= 0, got {self.table_max_mb}")


@numba.njit(cache=True, inline="always")
def _beam_value(
    r: float,
    expected: float,
    a_hit: float,
    inv_two_sigma2: float,
    short: float,
    extra: float,
    cube: bool,
) -> float:
    """What one beam adds to the sum: ``log p(r | r*)``, or ``p^3`` when ``cube`` (ROS
    scoring). ``short`` is the short term ``z_short lambda exp(-lambda r)`` (added where
    ``r < r*``), ``extra`` is ``z_max`` or ``z_rand / range_max``."""
    z = r - expected
    p = a_hit * math.exp(-z * z * inv_two_sigma2)
    if z < 0.0:
        p += short
    p += extra
    return p * p * p if cube else math.log(p)


def _beam_kernel_py(
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    bearings: NDArray[np.float64],
    extra: NDArray[np.float64],
    short: NDArray[np.float64],
    laser_x: float,
    laser_y: float,
    laser_yaw: float,
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    range_max: float,
    a_hit: float,
    inv_two_sigma2: float,
    cube: bool,
) -> NDArray[np.float64]:
    """The beam model with an exact ray cast per beam: per pose, the sum over beams of
    :func:`_beam_value` (``extra``, ``short`` per beam as there)."""
    n = poses.shape[0]
    m = ranges.shape[0]
    out = np.empty(n)
    for i in numba.prange(n):
        lx, ly, lth = _mounted_pose(
            poses[i, 0], poses[i, 1], poses[i, 2], laser_x, laser_y, laser_yaw
        )
        acc = 0.0
        for j in range(m):
            expected = _march(lx, ly, lth + bearings[j], blocking, dist, res, range_max)
            acc += _beam_value(ranges[j], expected, a_hit, inv_two_sigma2, short[j], extra[j], cube)
        out[i] = acc
    return out


_beam_kernel_serial, _beam_kernel_parallel = serial_and_parallel(_beam_kernel_py)


def _beam_table_kernel_py(
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    bearings: NDArray[np.float64],
    extra: NDArray[np.float64],
    short: NDArray[np.float64],
    laser_x: float,
    laser_y: float,
    laser_yaw: float,
    slot: NDArray[np.int32],
    rows: NDArray[np.float32],
    cos_k: NDArray[np.float64],
    sin_k: NDArray[np.float64],
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    range_max: float,
    a_hit: float,
    inv_two_sigma2: float,
    cube: bool,
) -> NDArray[np.float64]:
    """The beam model over a :class:`RangeTable` (:func:`_table_range`); otherwise as
    :func:`_beam_kernel_py`."""
    n = poses.shape[0]
    m = ranges.shape[0]
    out = np.empty(n)
    for i in numba.prange(n):
        lx, ly, lth = _mounted_pose(
            poses[i, 0], poses[i, 1], poses[i, 2], laser_x, laser_y, laser_yaw
        )
        acc = 0.0
        for j in range(m):
            expected = _table_range(
                lx,
                ly,
                lth + bearings[j],
                slot,
                rows,
                cos_k,
                sin_k,
                blocking,
                dist,
                res,
                range_max,
            )
            acc += _beam_value(ranges[j], expected, a_hit, inv_two_sigma2, short[j], extra[j], cube)
        out[i] = acc
    return out


_beam_table_serial, _beam_table_parallel = serial_and_parallel(_beam_table_kernel_py)


class BeamModel(CombinedBeams):
    """Beam model over an occupancy grid (implements :class:`SensorModel`).

    With ``config.ray_casting == "table"`` (the default) expected ranges come from a lazily
    filled :class:`RangeTable` per ``range_max`` (docs/performance.md: speed and accuracy);
    with ``"exact"`` every beam of every pose is ray-cast.
    """

    def __init__(self, grid: OccupancyGrid, config: BeamModelConfig | None = None) -> None:
        self.grid = grid
        self.config = config or BeamModelConfig()
        self._tables: dict[float, RangeTable] = {}

    @property
    def ray_casting(self) -> str:
        """ "table" or "exact": what :meth:`log_likelihood` uses."""
        if self.config.ray_casting == "exact" or self.config.table_max_mb <= 0:
            return "exact"
        return "table"

    def range_table(self, range_max: float) -> RangeTable:
        """The lookup table for this range limit (created empty on first use)."""
        table = self._tables.get(range_max)
        if table is None:
            table = RangeTable(
                self.grid,
                range_max,
                self.config.table_angles,
                int(self.config.table_max_mb * 1e6),
            )
            self._tables[range_max] = table
        return table

    def prepare(self, scan: LaserScan) -> PreparedScan:
        return prepare_scan(scan, self.config.max_beams, keep_max_range=True)

    def _a_hit(self) -> float:
        cfg = self.config
        if cfg.scoring == "ros":  # amcl's pz: no Gaussian normaliser (module docstring)
            return cfg.z_hit
        return cfg.z_hit / (cfg.sigma_hit_m * _SQRT_2PI)

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        cfg = self.config
        a_hit = self._a_hit()
        hit_case = a_hit + cfg.z_short * cfg.lambda_short + cfg.z_rand / prepared.range_max
        return math.log(max(hit_case, a_hit + cfg.z_max))

    def log_likelihood(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        mp = np.ascontiguousarray(self.grid.poses_to_map(poses))
        if prepared.n_beams == 0:
            return np.zeros(mp.shape[0])
        cfg = self.config
        lx, ly, lyaw = prepared.laser_pose
        parallel = mp.shape[0] >= PARALLEL_MIN_POSES
        beams = (
            mp,
            prepared.ranges,
            prepared.bearings,
            np.ascontiguousarray(
                np.where(prepared.is_max, cfg.z_max, cfg.z_rand / prepared.range_max)
            ),
            np.ascontiguousarray(
                cfg.z_short * cfg.lambda_short * np.exp(-cfg.lambda_short * prepared.ranges)
            ),
            lx,
            ly,
            lyaw,
        )
        grid = (self.grid.blocking_mask, self.grid.distance_to_blocking, self.grid.resolution)
        cube = cfg.scoring == "ros"
        mixture = (prepared.range_max, self._a_hit(), 1.0 / (2.0 * cfg.sigma_hit_m**2), cube)
        if self.ray_casting == "table":
            table = self.range_table(prepared.range_max)
            table.reserve(mp, (lx, ly))
            tkernel = _beam_table_parallel if parallel else _beam_table_serial
            out: NDArray[np.float64] = tkernel(
                *beams, table.slot, table.rows, table.cos_k, table.sin_k, *grid, *mixture
            )
        else:
            kernel = _beam_kernel_parallel if parallel else _beam_kernel_serial
            out = kernel(*beams, *grid, *mixture)
        return self._combined(out)

    def expected_ranges(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        """Expected ranges ``(N, M)`` of the prepared beams, as :meth:`log_likelihood` uses
        them (from the table or exact)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        lp = laser_poses(p, prepared.laser_pose)
        if self.ray_casting == "table":
            table = self.range_table(prepared.range_max)
            return table.cast_fan(self.grid.poses_to_map(lp), prepared.bearings)
        return cast_fan(self.grid, lp, prepared.bearings, prepared.range_max)

    def log_likelihood_reference(
        self, poses: ArrayLike, prepared: PreparedScan
    ) -> NDArray[np.float64]:
        """NumPy version of :meth:`log_likelihood` over :meth:`expected_ranges` (the compiled
        table lookup or ray caster; those are tested against brute force on their own)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if prepared.n_beams == 0:
            return np.zeros(p.shape[0])
        cfg = self.config
        expected = self.expected_ranges(p, prepared)
        r = prepared.ranges[None, :]
        z = r - expected
        prob = self._a_hit() * np.exp(-z * z / (2.0 * cfg.sigma_hit_m**2))
        prob = prob + np.where(
            z < 0, cfg.z_short * cfg.lambda_short * np.exp(-cfg.lambda_short * r), 0.0
        )
        prob = prob + np.where(prepared.is_max[None, :], cfg.z_max, cfg.z_rand / prepared.range_max)
        per_beam = prob**3 if cfg.scoring == "ros" else np.log(prob)
        return self._combined(np.sum(per_beam, axis=1))
