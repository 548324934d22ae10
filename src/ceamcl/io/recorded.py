"""The log types every reader produces and the runner replays.

:class:`RobotLog` is what a replayable log offers (``times``, ``odometry``, ``scan(k)``,
``len``; ``true_poses`` where the truth is known): :func:`ceamcl.runner.run_filter` replays
one and :mod:`ceamcl.mapping` maps one. :class:`RecordedLog` is the one the readers
(:mod:`ceamcl.io.carmen`, :mod:`ceamcl.io.rosbag`) build; the simulator's
:class:`~ceamcl.simulation.simulator.SimulatedLog` is another.

Ground truth and odometry. A SLAM-corrected log (the Radish "corrected" logs) records the
corrected pose where odometry would be; replaying it as odometry would hand the filter the
answer. :meth:`RecordedLog.with_synthetic_odometry` therefore takes the recorded poses as the
ground truth and builds odometry from them: each increment between consecutive true poses
(rot1, trans, rot2, Probabilistic Robotics eq. 5.34-5.36) is perturbed by the odometry motion
model's noise (Table 5.6, variances ``alpha1 rot^2 + alpha2 trans^2`` and
``alpha3 trans^2 + alpha4 (rot1^2 + rot2^2)``) and integrated, so the odometry drifts like wheel
odometry. One ``numpy.random.Generator`` draws all of it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import wrap
from ceamcl.motion.odometry import OdometryNoise, synthetic_odometry
from ceamcl.pose import HEADING_LIMIT_RAD, POSE_LIMIT_M
from ceamcl.sensors.scan import LaserScan, laser_poses

__all__ = [
    "HEADING_LIMIT_RAD",
    "POSE_LIMIT_M",
    "RecordedLog",
    "RobotLog",
    "interpolate_poses",
    "poses_at_scans",
]


class RobotLog(Protocol):
    """What a replayable log offers: times, odometry poses, scans, and truth where known."""

    @property
    def times(self) -> NDArray[np.float64]: ...

    @property
    def odometry(self) -> NDArray[np.float64]: ...

    def __len__(self) -> int: ...

    def scan(self, k: int) -> LaserScan: ...


@dataclass(frozen=True, eq=False)
class RecordedLog:
    """Scans of one laser with the robot's pose at each scan.

    Scan ``k``'s ranges are ``ranges_flat[offsets[k]:offsets[k+1]]`` at bearings
    ``angle_min[k] + i * angle_increment[k]`` in the laser frame; readings outside
    ``[range_min[k], range_max[k])`` are no-return. ``laser_mount[k]`` is the laser's pose in
    the robot's frame, ``poses`` the robot's recorded world pose. ``odometry`` is what a
    filter reads (the recorded poses unless replaced), ``true_poses`` the ground truth where
    known.
    """

    path: str
    times: NDArray[np.float64]
    poses: NDArray[np.float64]
    ranges_flat: NDArray[np.float64]
    offsets: NDArray[np.intp]
    angle_min: NDArray[np.float64]
    angle_increment: NDArray[np.float64]
    range_min: NDArray[np.float64]
    range_max: NDArray[np.float64]
    laser_mount: NDArray[np.float64]
    info: dict[str, Any] = field(default_factory=dict)
    odometry: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    true_poses: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        n = int(np.asarray(self.times).size)
        if self.odometry.shape[0] == 0 and n:
            object.__setattr__(self, "odometry", np.asarray(self.poses, dtype=np.float64))
        checks = {
            "poses": np.shape(self.poses) == (n, 3),
            "odometry": np.shape(self.odometry) == (n, 3),
            "offsets": np.shape(self.offsets) == (n + 1,),
            "angle_min": np.shape(self.angle_min) == (n,),
            "angle_increment": np.shape(self.angle_increment) == (n,),
            "range_min": np.shape(self.range_min) == (n,),
            "range_max": np.shape(self.range_max) == (n,),
            "laser_mount": np.shape(self.laser_mount) == (n, 3),
            "true_poses": self.true_poses is None or np.shape(self.true_poses) == (n, 3),
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"RecordedLog: fields {', '.join(bad)} do not match {n} scans")

    # ---------------------------------------------------------------- the RobotLog protocol
    def __len__(self) -> int:
        return int(self.times.size)

    def ranges(self, k: int) -> NDArray[np.float64]:
        return self.ranges_flat[self.offsets[k] : self.offsets[k + 1]]

    def scan(self, k: int) -> LaserScan:
        m = self.laser_mount[k]
        return LaserScan(
            self.ranges(k),
            float(self.angle_min[k]),
            float(self.angle_increment[k]),
            float(self.range_min[k]),
            float(self.range_max[k]),
            (float(m[0]), float(m[1]), float(m[2])),
            float(self.times[k]),
        )

    # ---------------------------------------------------------------- views
    @property
    def name(self) -> str:
        """The file name without compression and log suffixes (``intel-corrected``)."""
        base = Path(self.path).name
        for suffix in (".gz", ".log", ".clf", ".txt", ".bag", ".db3", ".mcap"):
            base = base.removesuffix(suffix)
        return base

    @property
    def beam_counts(self) -> NDArray[np.intp]:
        return np.diff(self.offsets)

    @property
    def duration_s(self) -> float:
        return float(self.times[-1] - self.times[0]) if len(self) else 0.0

    @property
    def path_length_m(self) -> float:
        return float(self.travelled_m[-1]) if len(self) else 0.0

    @property
    def travelled_m(self) -> NDArray[np.float64]:
        """Distance travelled along the true path (the recorded poses where there is no truth)
        up to each scan. Scans without truth (NaN rows, a raw log paired with a corrected one)
        are skipped: the path runs from one scan with truth to the next."""
        p = self.true_poses if self.true_poses is not None else self.poses
        known = np.flatnonzero(np.all(np.isfinite(p), axis=1))
        out = np.zeros(len(self))
        if known.size > 1:
            step = np.hypot(*np.diff(p[known, :2], axis=0).T)
            out[known[1:]] = np.cumsum(step)
            out = np.maximum.accumulate(out)
        return out

    @property
    def has_truth_at(self) -> NDArray[np.bool_]:
        """Which scans have a ground-truth pose (none when the log has no truth)."""
        if self.true_poses is None:
            return np.zeros(len(self), dtype=bool)
        return np.asarray(np.all(np.isfinite(self.true_poses), axis=1), dtype=bool)

    def window(self, start: int, stop: int) -> RecordedLog:
        """Scans ``start .. stop-1`` as a log of their own."""
        n = len(self)
        if not 0 <= start < stop <= n:
            raise ValueError(f"window: expected 0 <= start < stop <= {n}, got {start}, {stop}")
        lo, hi = int(self.offsets[start]), int(self.offsets[stop])
        return replace(
            self,
            times=self.times[start:stop],
            poses=self.poses[start:stop],
            ranges_flat=self.ranges_flat[lo:hi],
            offsets=self.offsets[start : stop + 1] - lo,
            angle_min=self.angle_min[start:stop],
            angle_increment=self.angle_increment[start:stop],
            range_min=self.range_min[start:stop],
            range_max=self.range_max[start:stop],
            laser_mount=self.laser_mount[start:stop],
            odometry=self.odometry[start:stop],
            true_poses=None if self.true_poses is None else self.true_poses[start:stop],
        )

    def with_synthetic_odometry(
        self, noise: OdometryNoise, rng: np.random.Generator
    ) -> RecordedLog:
        """The recorded poses become the ground truth; odometry is drawn from them (module doc)."""
        return replace(
            self,
            true_poses=self.poses,
            odometry=synthetic_odometry(self.poses, noise, rng),
            info={**self.info, "odometry": "synthetic", "odometry_noise": _noise_dict(noise)},
        )

    def laser_world_poses(self) -> NDArray[np.float64]:
        """World pose of the laser at each scan (true poses where known, else recorded)."""
        base = self.true_poses if self.true_poses is not None else self.poses
        world = laser_poses(base, self.laser_mount)
        world[:, 2] = wrap(world[:, 2])
        return world


def _noise_dict(noise: OdometryNoise) -> dict[str, float]:
    return {k: float(getattr(noise, k)) for k in ("alpha1", "alpha2", "alpha3", "alpha4")}


def interpolate_poses(times: ArrayLike, poses: ArrayLike, at: ArrayLike) -> NDArray[np.float64]:
    """Poses ``(T, 3)`` at times ``at``: linear in x and y, along the shorter arc in heading.

    Times before the first or after the last sample take the end pose. A time that is not a
    number gives a NaN pose: the readers call :func:`poses_at_scans`, which refuses that.
    """
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(at, dtype=np.float64).reshape(-1)
    order = np.argsort(t, kind="stable")
    t, p = t[order], p[order]
    heading = np.unwrap(p[:, 2])
    return np.column_stack(
        [np.interp(q, t, p[:, 0]), np.interp(q, t, p[:, 1]), wrap(np.interp(q, t, heading))]
    )


def poses_at_scans(
    sample_times: ArrayLike,
    sample_poses: ArrayLike,
    scan_times: ArrayLike,
    *,
    scans: str,
    odometry: str,
    error: Callable[[str], Exception],
) -> NDArray[np.float64]:
    """The odometry's poses interpolated at the scans' times (:func:`interpolate_poses`),
    refusing with ``error`` what would give poses that mean nothing:

    * a sample or scan time that is not finite (the pose would be NaN);
    * scan times that do not overlap the odometry's time span at all: every scan would take
      the first or the last odometry pose, a robot that never moves (scans stamped by another
      clock, such as simulated time against wall time). Scans a little before the first or
      after the last sample, as real logs have, still take the end pose;
    * and, as a last guard, any interpolated pose that is not finite.

    ``scans`` and ``odometry`` name the two sources in the message (``"the scans on /scan"``).
    """
    t = np.asarray(sample_times, dtype=np.float64).reshape(-1)
    q = np.asarray(scan_times, dtype=np.float64).reshape(-1)
    for name, values in ((odometry, t), (scans, q)):
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            k = int(bad[0])
            raise error(f"{name}: time {values[k]} of entry {k}: expected finite times")
    if t.size and q.size and max(t.min(), q.min()) > min(t.max(), q.max()):
        raise error(
            f"{scans} span {_span(q)} and {odometry} {_span(t)}: the times do not overlap, so "
            "every scan would take the odometry's first or last pose (a robot that never "
            "moves); expected scans stamped within the odometry's time span, by the same clock"
        )
    poses = interpolate_poses(t, sample_poses, q)
    bad = np.flatnonzero(~np.all(np.isfinite(poses), axis=1))
    if bad.size:
        k = int(bad[0])
        raise error(
            f"{scans}: scan {k} (t={q[k]:.3f} s): the pose interpolated from {odometry} is "
            f"not finite ({poses[k, 0]}, {poses[k, 1]}, {poses[k, 2]}); expected finite poses"
        )
    return poses


def _span(t: NDArray[np.float64]) -> str:
    return f"{t.min():.3f} .. {t.max():.3f} s"


#: Poses beyond ``POSE_LIMIT_M`` and ``HEADING_LIMIT_RAD`` (:mod:`ceamcl.pose`, where a map's
#: origin is bounded by them too) are refused.


def check_pose_values(v: NDArray[np.float64], what: str, error: Callable[[str], Exception]) -> None:
    """Refuse a pose ``(x, y, theta)`` that is not finite or lies beyond the limits above."""
    x, y, theta = (float(a) for a in v[:3])
    if not all(math.isfinite(a) for a in (x, y, theta)):
        raise error(f"{what}: expected three finite numbers, got {x} {y} {theta}")
    if max(abs(x), abs(y)) > POSE_LIMIT_M or abs(theta) > HEADING_LIMIT_RAD:
        raise error(
            f"{what}: expected |x|, |y| <= {POSE_LIMIT_M:g} m and |theta| <= "
            f"{HEADING_LIMIT_RAD:g} rad, got {x:g} {y:g} {theta:g}"
        )
