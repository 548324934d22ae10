"""Recorded robot logs (CARMEN or ROS bags), opened by file type.

:func:`open_log` picks the reader by file type: a ROS 1 bag (``.bag`` or the ``#ROSBAG``
header), a ROS 2 bag (a folder with ``metadata.yaml``, or a ``.db3``/``.mcap`` file inside
one or on its own), anything else a CARMEN log (plain, gzip, bzip2 or xz). Every reader returns a
:class:`~ceamcl.io.recorded.RecordedLog` (the log type, its ground truth and synthetic
odometry are described in :mod:`ceamcl.io.recorded`).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Literal

import numpy as np

from ceamcl.errors import ConfigError, LogFormatError
from ceamcl.io import streams
from ceamcl.io.carmen import read_carmen
from ceamcl.io.recorded import RecordedLog, interpolate_poses
from ceamcl.io.rosbag import read_bag
from ceamcl.motion.odometry import OdometryNoise, synthetic_odometry

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

#: The first bytes of a ROS 2 bag's storage files, by suffix: MCAP and SQLite 3.
ROS2_STORAGE_MAGIC = {".mcap": b"\x89MCAP0\r\n", ".db3": b"SQLite format 3\x00"}


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
        head = streams.sniff(p, 16, "log")  # a pipe keeps these bytes for the reader
    except OSError as exc:
        raise LogFormatError(f"{p}: cannot read the log: {exc.strerror or exc}") from None
    if head.startswith(b"#ROSBAG V2.0") or p.suffix == ".bag":
        return "ros1"
    magic = ROS2_STORAGE_MAGIC.get(p.suffix)
    if magic is not None and head.startswith(magic):
        return "ros2"  # a ROS 2 bag's storage file out of its folder (rosbag.read_bag)
    return "carmen"


def open_log(
    path: str | os.PathLike[str],
    *,
    laser: int = 1,
    max_range_m: float | None = None,
    odometry_sign: str = "auto",
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    odom_frame: str = "odom",
    base_frame: str = "base_link",
) -> RecordedLog:
    """Open a CARMEN log or a ROS bag by its type (see :func:`log_format`).

    ``laser``, ``max_range_m`` and ``odometry_sign`` apply to CARMEN logs
    (:func:`ceamcl.io.carmen.read_carmen`);
    the topics and frames to bags (:func:`ceamcl.io.rosbag.read_bag`); ``max_range_m``
    overrides a bag's ``range_max`` too.
    """
    fmt = log_format(path)
    if max_range_m is not None and not max_range_m > 0:
        raise ConfigError(f"max-range: expected a positive number of metres, got {max_range_m}")
    if fmt == "carmen":
        return read_carmen(path, laser=laser, max_range_m=max_range_m, odometry_sign=odometry_sign)
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
    bad = np.flatnonzero(~np.isfinite(log.range_max))
    if bad.size:  # the bag's own (rosbag.read_bag lets inf through for --max-range to set)
        k = int(bad[0])
        raise LogFormatError(
            f"{path}: {log.info.get('scan_topic', 'scan')}: scan {k} (t={log.times[k]:.3f} s): "
            f"range_max {log.range_max[k]}: expected a finite number of metres "
            "(--max-range sets the maximum instead)"
        )
    return log
