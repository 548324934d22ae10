"""Recorded robot logs (CARMEN or ROS bags) as one replayable object, opened by file type.

:class:`RecordedLog` holds the scans of one laser and the robot's pose at each scan. It is the
log :func:`ceamcl.runner.run_filter` replays (``times``, ``odometry``, ``scan(k)``, ``len``,
and ``true_poses`` once the poses are taken as ground truth).

Ground truth and odometry. A SLAM-corrected log (the Radish "corrected" logs) records the
corrected pose where odometry would be; replaying it as odometry would hand the filter the
answer. :meth:`RecordedLog.with_synthetic_odometry` therefore takes the recorded poses as the
ground truth and builds odometry from them: each increment between consecutive true poses
(rot1, trans, rot2, Probabilistic Robotics eq. 5.34-5.36) is perturbed by the odometry motion
model's noise (Table 5.6, variances ``alpha1 rot^2 + alpha2 trans^2`` and
``alpha3 trans^2 + alpha4 (rot1^2 + rot2^2)``) and integrated, so the odometry drifts like wheel
odometry. One ``numpy.random.Generator`` draws all of it.

:func:`open_log` picks the reader by file type: a ROS 1 bag (``.bag`` or the ``#ROSBAG``
header), a ROS 2 bag (a folder with ``metadata.yaml``, or a ``.db3``/``.mcap`` file inside
one), anything else a CARMEN log (plain or gzip).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import wrap
from ceamcl.errors import ConfigError, LogFormatError
from ceamcl.io import streams
from ceamcl.motion.odometry import OdometryNoise, synthetic_odometry
from ceamcl.sensors.scan import LaserScan, laser_poses

__all__ = [
    "DEFAULT_SYNTHETIC_NOISE",
    "RecordedLog",
    "interpolate_poses",
    "log_format",
    "open_log",
    "poses_look_corrected",
    "synthetic_odometry",
]

#: Odometry noise added to corrected poses: the simulator's (alpha1..4 = 0.02).
DEFAULT_SYNTHETIC_NOISE = OdometryNoise(0.02, 0.02, 0.02, 0.02)

LogFormat = Literal["carmen", "ros1", "ros2"]


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
        p = self.true_poses if self.true_poses is not None else self.poses
        return float(np.hypot(*np.diff(p[:, :2], axis=0).T).sum()) if len(self) > 1 else 0.0

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

    Times before the first or after the last sample take the end pose.
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


def poses_look_corrected(log: RecordedLog) -> tuple[bool, str]:
    """Whether a log's poses are SLAM-corrected ground truth, decided by its content, and why.

    A Radish "corrected" CARMEN log is what a SLAM run wrote: an ``NEFF`` message (the
    effective sample size of the run) for its scans, and every laser message's laser pose equal
    to its robot pose (both are the corrected pose). Raw logs have no ``NEFF``; a raw log's laser
    pose may equal its robot pose too (intel's does), so that alone is not evidence. Bags record
    odometry, never corrected poses. The file's name plays no part.
    """
    if log.info.get("format") != "carmen":
        return False, f"no: a {log.info.get('format', 'bag')} bag records odometry"
    neff = int(log.info.get("skipped_messages", {}).get("NEFF", 0))
    same = bool(len(log)) and not np.any(log.laser_mount)
    if neff and same:
        return True, (
            f"yes: the log holds {neff} NEFF messages of a SLAM run and its laser and robot "
            "poses are identical (a corrected log)"
        )
    if not neff:
        return False, "no: the log has no NEFF messages of a SLAM run (a raw log)"
    return False, "no: the laser pose differs from the robot pose (raw odometry)"


def log_format(path: str | os.PathLike[str]) -> LogFormat:
    """``carmen``, ``ros1`` or ``ros2``, from the name and the first bytes of the file."""
    p = Path(path)
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "ros2"
        raise LogFormatError(
            f"{p}: a folder but not a ROS 2 bag (no metadata.yaml); expected a CARMEN log, "
            "a ROS 1 .bag file or a ROS 2 bag folder"
        )
    if not p.exists():
        raise LogFormatError(f"{p}: log file not found")
    if p.suffix in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        return "ros2"
    try:
        head = streams.sniff(p, 13, "log")  # a pipe keeps these bytes for the reader
    except OSError as exc:
        raise LogFormatError(f"{p}: cannot read the log: {exc.strerror or exc}") from None
    if head.startswith(b"#ROSBAG V2.0") or p.suffix == ".bag":
        return "ros1"
    return "carmen"


def open_log(
    path: str | os.PathLike[str],
    *,
    laser: int = 1,
    max_range_m: float | None = None,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    odom_frame: str = "odom",
    base_frame: str = "base_link",
) -> RecordedLog:
    """Open a CARMEN log or a ROS bag by its type (see :func:`log_format`).

    ``laser`` and ``max_range_m`` apply to CARMEN logs (:func:`ceamcl.io.carmen.read_carmen`);
    the topics and frames to bags (:func:`ceamcl.io.rosbag.read_bag`); ``max_range_m``
    overrides a bag's ``range_max`` too.
    """
    fmt = log_format(path)
    if max_range_m is not None and not max_range_m > 0:
        raise ConfigError(f"max-range: expected a positive number of metres, got {max_range_m}")
    if fmt == "carmen":
        from ceamcl.io.carmen import read_carmen

        return read_carmen(path, laser=laser, max_range_m=max_range_m)
    from ceamcl.io.rosbag import read_bag

    log = read_bag(
        path,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        odom_frame=odom_frame,
        base_frame=base_frame,
    )
    if max_range_m is not None:
        lowest = float(np.max(log.range_min)) if len(log) else 0.0
        if not max_range_m > lowest:
            raise ConfigError(
                f"max-range: {max_range_m:g} m is not above the sensor's minimum range "
                f"{lowest:g} m in {path}; expected a larger maximum"
            )
        log = replace(log, range_max=np.full(len(log), float(max_range_m)))
    return log
