"""The beam sensor model (Probabilistic Robotics, sec. 6.3, Table 6.1).

For each beam the expected range ``r*`` is ray-cast in the map from the particle's laser pose;
the measured range ``r`` is scored by the mixture

    p(r | x) = z_hit   * N(r; r*, sigma_hit^2)
             + z_short * lambda_short * exp(-lambda_short * r)   if r < r*
             + z_max                                             if r is a max-range reading
             + z_rand / range_max                                if r < range_max

The short-noise normaliser ``1 / (1 - exp(-lambda r*))`` and the Gaussian's truncation are
dropped, as ROS amcl drops them; the Gaussian keeps its ``1 / (sqrt(2 pi) sigma)`` so that
``z_hit`` and ``z_rand`` weigh densities of the same units. Ray casting and scoring are fused in
one compiled kernel, parallel over particles, with no (N x M) temporaries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.likelihood_field import PARALLEL_MIN_POSES
from ceamcl.sensors.raycast import _march, cast_fan
from ceamcl.sensors.scan import LaserScan, PreparedScan, laser_poses, prepare_scan

_SQRT_2PI = math.sqrt(2.0 * math.pi)


@dataclass(frozen=True)
class BeamModelConfig:
    """Parameters of the beam model; defaults are ROS amcl's (max_beams as Nav2)."""

    z_hit: float = 0.95
    z_short: float = 0.1
    z_max: float = 0.05
    z_rand: float = 0.05
    sigma_hit_m: float = 0.2
    lambda_short: float = 0.1
    max_beams: int = 60

    def __post_init__(self) -> None:
        if not self.z_hit > 0 or min(self.z_short, self.z_max, self.z_rand) < 0:
            raise ValueError("z_hit must be > 0 and z_short, z_max, z_rand >= 0")
        if not self.sigma_hit_m > 0:
            raise ValueError(f"sigma_hit_m: expected > 0, got {self.sigma_hit_m}")
        if not self.lambda_short > 0:
            raise ValueError(f"lambda_short: expected > 0, got {self.lambda_short}")
        if self.max_beams < 1:
            raise ValueError(f"max_beams: expected >= 1, got {self.max_beams}")


@numba.njit(cache=True, inline="always")
def _beam_log_p(
    r: float,
    expected: float,
    is_max: bool,
    range_max: float,
    a_hit: float,
    inv_two_sigma2: float,
    z_short: float,
    lambda_short: float,
    z_max: float,
    c_rand: float,
) -> float:
    z = r - expected
    p = a_hit * math.exp(-z * z * inv_two_sigma2)
    if z < 0.0:
        p += z_short * lambda_short * math.exp(-lambda_short * r)
    if is_max:
        p += z_max
    else:
        p += c_rand
    return math.log(p)


def _beam_kernel_py(
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    bearings: NDArray[np.float64],
    is_max: NDArray[np.bool_],
    laser_x: float,
    laser_y: float,
    laser_yaw: float,
    blocking: NDArray[np.bool_],
    dist: NDArray[np.float64],
    res: float,
    range_max: float,
    a_hit: float,
    inv_two_sigma2: float,
    z_short: float,
    lambda_short: float,
    z_max: float,
    c_rand: float,
) -> NDArray[np.float64]:
    n = poses.shape[0]
    m = ranges.shape[0]
    out = np.empty(n)
    for i in numba.prange(n):
        c = math.cos(poses[i, 2])
        s = math.sin(poses[i, 2])
        lx = poses[i, 0] + c * laser_x - s * laser_y
        ly = poses[i, 1] + s * laser_x + c * laser_y
        lth = poses[i, 2] + laser_yaw
        acc = 0.0
        for j in range(m):
            expected = _march(lx, ly, lth + bearings[j], blocking, dist, res, range_max)
            acc += _beam_log_p(
                ranges[j],
                expected,
                is_max[j],
                range_max,
                a_hit,
                inv_two_sigma2,
                z_short,
                lambda_short,
                z_max,
                c_rand,
            )
        out[i] = acc
    return out


_beam_kernel_parallel = numba.njit(cache=True, parallel=True, fastmath=True)(_beam_kernel_py)
_beam_kernel_serial = numba.njit(cache=True, fastmath=True)(_beam_kernel_py)


class BeamModel:
    """Beam model over an occupancy grid (implements :class:`SensorModel`)."""

    def __init__(self, grid: OccupancyGrid, config: BeamModelConfig | None = None) -> None:
        self.grid = grid
        self.config = config or BeamModelConfig()

    def prepare(self, scan: LaserScan) -> PreparedScan:
        return prepare_scan(scan, self.config.max_beams, keep_max_range=True)

    def _a_hit(self) -> float:
        return self.config.z_hit / (self.config.sigma_hit_m * _SQRT_2PI)

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        cfg = self.config
        a_hit = self._a_hit()
        hit_case = a_hit + cfg.z_short * cfg.lambda_short + cfg.z_rand / prepared.range_max
        return math.log(max(hit_case, a_hit + cfg.z_max))

    def log_likelihood(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        mp = self.grid.poses_to_map(poses)
        if prepared.n_beams == 0:
            return np.zeros(mp.shape[0])
        cfg = self.config
        lx, ly, lyaw = prepared.laser_pose
        kernel = _beam_kernel_parallel if mp.shape[0] >= PARALLEL_MIN_POSES else _beam_kernel_serial
        return kernel(  # type: ignore[no-any-return,unused-ignore]
            np.ascontiguousarray(mp),
            prepared.ranges,
            prepared.bearings,
            prepared.is_max,
            lx,
            ly,
            lyaw,
            self.grid.blocking_mask,
            self.grid.distance_to_blocking,
            self.grid.resolution,
            prepared.range_max,
            self._a_hit(),
            1.0 / (2.0 * cfg.sigma_hit_m**2),
            cfg.z_short,
            cfg.lambda_short,
            cfg.z_max,
            cfg.z_rand / prepared.range_max,
        )

    def log_likelihood_reference(
        self, poses: ArrayLike, prepared: PreparedScan
    ) -> NDArray[np.float64]:
        """NumPy version of :meth:`log_likelihood` over the compiled ray caster's fan."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if prepared.n_beams == 0:
            return np.zeros(p.shape[0])
        cfg = self.config
        expected = cast_fan(
            self.grid, laser_poses(p, prepared.laser_pose), prepared.bearings, prepared.range_max
        )
        r = prepared.ranges[None, :]
        z = r - expected
        prob = self._a_hit() * np.exp(-z * z / (2.0 * cfg.sigma_hit_m**2))
        prob = prob + np.where(
            z < 0, cfg.z_short * cfg.lambda_short * np.exp(-cfg.lambda_short * r), 0.0
        )
        prob = prob + np.where(prepared.is_max[None, :], cfg.z_max, cfg.z_rand / prepared.range_max)
        return np.sum(np.log(prob), axis=1)
