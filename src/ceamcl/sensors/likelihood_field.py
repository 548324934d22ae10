"""The likelihood-field sensor model (Probabilistic Robotics, sec. 6.4, Table 6.3).

Each beam end point is projected into the map; its likelihood is a mixture of a Gaussian in
the distance ``d`` to the nearest obstacle and a uniform term:

    p(z_k | x) = z_hit * N(d; 0, sigma_hit^2) + z_rand / range_max

``d`` is read from the map's distance field (computed once per map), capped at
``max_occ_dist_m`` (ROS amcl's ``laser_likelihood_max_dist``); end points off the map get the
cap, and max-range readings are skipped (as in ROS amcl). Unlike ROS amcl, which adds cubes of
per-beam values, beams are combined as a product (a sum of logs), as the textbook does.

The compiled kernel runs in parallel over poses;
:meth:`LikelihoodFieldModel.log_likelihood_reference` is the plain NumPy version the tests hold
it to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.scan import LaserScan, PreparedScan, laser_poses, prepare_scan

_SQRT_2PI = math.sqrt(2.0 * math.pi)


@dataclass(frozen=True)
class LikelihoodFieldConfig:
    """Parameters of the likelihood field; defaults are ROS amcl's (max_beams as Nav2)."""

    z_hit: float = 0.95
    z_rand: float = 0.05
    sigma_hit_m: float = 0.2
    max_occ_dist_m: float = 2.0
    max_beams: int = 60

    def __post_init__(self) -> None:
        if not (self.z_hit > 0 and self.z_rand >= 0):
            raise ValueError("z_hit must be > 0 and z_rand >= 0")
        if not self.sigma_hit_m > 0:
            raise ValueError(f"sigma_hit_m: expected > 0, got {self.sigma_hit_m}")
        if not self.max_occ_dist_m > 0:
            raise ValueError(f"max_occ_dist_m: expected > 0, got {self.max_occ_dist_m}")
        if self.max_beams < 1:
            raise ValueError(f"max_beams: expected >= 1, got {self.max_beams}")


@numba.njit(cache=True, parallel=True, fastmath=True)
def _lf_kernel(
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    bearings: NDArray[np.float64],
    laser_x: float,
    laser_y: float,
    laser_yaw: float,
    dist: NDArray[np.float64],
    res: float,
    a_hit: float,
    inv_two_sigma2: float,
    c_rand: float,
    max_occ: float,
) -> NDArray[np.float64]:
    n = poses.shape[0]
    m = ranges.shape[0]
    h, w = dist.shape
    out = np.empty(n)
    for i in numba.prange(n):
        c = math.cos(poses[i, 2])
        s = math.sin(poses[i, 2])
        lx = poses[i, 0] + c * laser_x - s * laser_y
        ly = poses[i, 1] + s * laser_x + c * laser_y
        lth = poses[i, 2] + laser_yaw
        acc = 0.0
        for j in range(m):
            a = lth + bearings[j]
            ex = lx + ranges[j] * math.cos(a)
            ey = ly + ranges[j] * math.sin(a)
            fx = ex / res
            fy = ey / res
            d = max_occ
            if fx >= 0.0 and fy >= 0.0:
                ix = int(fx)
                iy = int(fy)
                if ix < w and iy < h:
                    d = min(dist[iy, ix], max_occ)
            acc += math.log(a_hit * math.exp(-d * d * inv_two_sigma2) + c_rand)
        out[i] = acc
    return out


class LikelihoodFieldModel:
    """Likelihood field over an occupancy grid (implements :class:`SensorModel`)."""

    def __init__(self, grid: OccupancyGrid, config: LikelihoodFieldConfig | None = None) -> None:
        self.grid = grid
        self.config = config or LikelihoodFieldConfig()

    @cached_property
    def _dist(self) -> NDArray[np.float64]:
        return np.ascontiguousarray(
            np.minimum(self.grid.distance_to_occupied, self.config.max_occ_dist_m)
        )

    def prepare(self, scan: LaserScan) -> PreparedScan:
        return prepare_scan(scan, self.config.max_beams, keep_max_range=False)

    def _terms(self, prepared: PreparedScan) -> tuple[float, float, float]:
        cfg = self.config
        a_hit = cfg.z_hit / (cfg.sigma_hit_m * _SQRT_2PI)
        return a_hit, 1.0 / (2.0 * cfg.sigma_hit_m**2), cfg.z_rand / prepared.range_max

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        a_hit, _, c_rand = self._terms(prepared)
        return math.log(a_hit + c_rand)

    def log_likelihood(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        mp = self.grid.poses_to_map(poses)
        if prepared.n_beams == 0:
            return np.zeros(mp.shape[0])
        a_hit, k, c_rand = self._terms(prepared)
        lx, ly, lyaw = prepared.laser_pose
        return _lf_kernel(
            np.ascontiguousarray(mp),
            prepared.ranges,
            prepared.bearings,
            lx,
            ly,
            lyaw,
            self._dist,
            self.grid.resolution,
            a_hit,
            k,
            c_rand,
            self.config.max_occ_dist_m,
        )

    def log_likelihood_reference(
        self, poses: ArrayLike, prepared: PreparedScan
    ) -> NDArray[np.float64]:
        """NumPy reference of :meth:`log_likelihood` (no compilation, O(N x M) memory)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if prepared.n_beams == 0:
            return np.zeros(p.shape[0])
        a_hit, k, c_rand = self._terms(prepared)
        lp = laser_poses(p, prepared.laser_pose)
        ang = lp[:, 2:3] + prepared.bearings[None, :]
        ex = lp[:, 0:1] + prepared.ranges[None, :] * np.cos(ang)
        ey = lp[:, 1:2] + prepared.ranges[None, :] * np.sin(ang)
        ix, iy = self.grid.world_to_cell(ex, ey)
        inside = self.grid.in_bounds(ix, iy)
        d = np.full(ex.shape, self.config.max_occ_dist_m)
        d[inside] = self._dist[iy[inside], ix[inside]]
        return np.sum(np.log(a_hit * np.exp(-d * d * k) + c_rand), axis=1)
