"""Simulator: drives a robot along waypoints and records truth, noisy odometry and noisy scans.

The robot turns on the spot towards the next waypoint at ``turn_rate_rps``, then drives
straight to it at ``speed_mps``; poses are recorded at ``rate_hz``. Odometry integrates the
true relative motion corrupted by the odometry motion model's own noise (``odometry_noise``),
so it drifts like wheel odometry does. Scans are ray-cast from the true laser pose, then get
Gaussian range noise and a share of uniformly random readings; beams that hit nothing within
``range_max`` read ``range_max`` (no return), as a SICK LMS on a Pioneer reports.

Every noise parameter lives in :class:`SimulationConfig`; one ``numpy.random.Generator``
drives the whole run, so one seed reproduces the log bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import diff, wrap
from ceamcl.errors import check_rng
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryNoise, synthetic_odometry
from ceamcl.sensors.raycast import cast_rays
from ceamcl.sensors.scan import LaserGeometry, LaserScan, laser_poses


def default_laser() -> LaserGeometry:
    """A SICK LMS on a Pioneer: 180 degrees, 181 beams, 8 m, mounted 0.1 m ahead of the axle."""
    return LaserGeometry.covering(np.pi, 181, 8.0, range_min=0.02, pose=(0.1, 0.0, 0.0))


@dataclass(frozen=True)
class SimulationConfig:
    """Everything the simulator draws at random, and the robot's pace."""

    rate_hz: float = 10.0
    speed_mps: float = 0.3
    turn_rate_rps: float = 0.6
    odometry_noise: OdometryNoise = field(
        default_factory=lambda: OdometryNoise(0.02, 0.02, 0.02, 0.02)
    )
    laser: LaserGeometry = field(default_factory=default_laser)
    range_sigma_m: float = 0.02
    random_reading_prob: float = 0.01

    def __post_init__(self) -> None:
        # finite too: an infinite rate divided by zero, an infinite speed ended every route at
        # its start, a NaN sigma made most readings NaN
        for name in ("rate_hz", "speed_mps", "turn_rate_rps"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: expected a finite number > 0, got {v}")
        if not (math.isfinite(self.range_sigma_m) and self.range_sigma_m >= 0):
            raise ValueError(
                f"range_sigma_m: expected a finite number >= 0, got {self.range_sigma_m}"
            )
        if not 0 <= self.random_reading_prob <= 1:
            raise ValueError(
                f"random_reading_prob: expected in [0, 1], got {self.random_reading_prob}"
            )


@dataclass(frozen=True, eq=False)
class SimulatedLog:
    """A recorded run: ``T`` time steps of truth, odometry and scans."""

    times: NDArray[np.float64]
    true_poses: NDArray[np.float64]
    odometry: NDArray[np.float64]
    ranges: NDArray[np.float64]
    laser: LaserGeometry
    world: str = ""
    #: Steps at which the robot was carried to another pose (kidnapped): the truth jumps,
    #: the odometry does not move.
    kidnapped_at: tuple[int, ...] = ()

    def __len__(self) -> int:
        return int(self.times.size)

    def scan(self, k: int) -> LaserScan:
        return self.laser.scan(self.ranges[k], stamp=float(self.times[k]))


def drive_waypoints(
    start: ArrayLike,
    waypoints: Sequence[ArrayLike],
    config: SimulationConfig,
) -> NDArray[np.float64]:
    """True poses ``(T, 3)`` at ``rate_hz``: turn on the spot to each waypoint, then drive to it.

    ``start`` is ``(x, y, theta)``; waypoints are ``(x, y)`` points or ``(x, y, theta)`` poses
    (a heading makes the robot turn to it on arrival).
    """
    dt = 1.0 / config.rate_hz
    step_turn = config.turn_rate_rps * dt
    step_move = config.speed_mps * dt
    pose = np.asarray(start, dtype=np.float64).copy()
    out = [pose.copy()]

    def turn_to(heading: float) -> None:
        while True:
            err = float(diff(heading, pose[2]))
            if abs(err) <= 1e-9:
                return
            pose[2] = float(wrap(pose[2] + np.clip(err, -step_turn, step_turn)))
            out.append(pose.copy())

    for wp in waypoints:
        w = np.asarray(wp, dtype=np.float64)
        delta = w[:2] - pose[:2]
        dist = float(np.hypot(*delta))
        if dist > 1e-9:
            turn_to(float(np.arctan2(delta[1], delta[0])))
            n = int(np.ceil(dist / step_move))
            origin = pose[:2].copy()
            for k in range(1, n + 1):
                pose[:2] = origin + delta * (k / n)
                out.append(pose.copy())
        if w.size == 3:
            turn_to(float(w[2]))
    return np.asarray(out)


class Simulator:
    """Turns a path of true poses into odometry and scans on a map."""

    def __init__(self, grid: OccupancyGrid, config: SimulationConfig | None = None) -> None:
        self.grid = grid
        self.config = config or SimulationConfig()

    def noisy_odometry(
        self,
        true_poses: ArrayLike,
        rng: np.random.Generator,
        *,
        kidnapped_at: Sequence[int] = (),
    ) -> NDArray[np.float64]:
        """Odometry poses: the true increments, each perturbed by the odometry noise model.

        At the steps in ``kidnapped_at`` the robot is lifted and carried: the wheels do not
        turn, so the odometry stays where it was while the truth jumps.
        """
        check_rng(rng)
        return synthetic_odometry(
            true_poses, self.config.odometry_noise, rng, kidnapped_at=kidnapped_at
        )

    def scans(self, true_poses: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
        """Noisy ranges ``(T, n_beams)`` seen from the true poses."""
        check_rng(rng)
        cfg = self.config
        laser = cfg.laser
        lp = laser_poses(true_poses, laser.pose)
        t, m = lp.shape[0], laser.n_beams
        angles = (lp[:, 2:3] + laser.angles[None, :]).reshape(-1)
        origins = np.repeat(lp[:, :2], m, axis=0)
        exact = cast_rays(self.grid, origins, angles, laser.range_max).reshape(t, m)
        hit = exact < laser.range_max
        noisy = exact + rng.standard_normal((t, m)) * cfg.range_sigma_m
        ranges = np.where(hit, np.clip(noisy, laser.range_min, laser.range_max), laser.range_max)
        random = rng.random((t, m)) < cfg.random_reading_prob
        ranges = np.where(random, rng.uniform(laser.range_min, laser.range_max, (t, m)), ranges)
        return ranges

    def run(
        self,
        true_poses: ArrayLike,
        rng: np.random.Generator,
        *,
        kidnapped_at: Sequence[int] = (),
    ) -> SimulatedLog:
        """Simulate a path; ``kidnapped_at`` lists steps where the truth jumps unseen by the
        odometry (see :meth:`noisy_odometry`)."""
        check_rng(rng)
        truth = np.asarray(true_poses, dtype=np.float64).reshape(-1, 3)
        kidnapped = tuple(sorted(int(k) for k in kidnapped_at))
        if any(not 0 < k < truth.shape[0] for k in kidnapped):
            raise ValueError(
                f"kidnapped_at: steps must lie in 1..{truth.shape[0] - 1}, got {kidnapped}"
            )
        odom = self.noisy_odometry(truth, rng, kidnapped_at=kidnapped)
        ranges = self.scans(truth, rng)
        times = np.arange(truth.shape[0]) / self.config.rate_hz
        return SimulatedLog(
            times, truth, odom, ranges, self.config.laser, self.grid.name, kidnapped
        )
