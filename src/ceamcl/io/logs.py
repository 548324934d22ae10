"""Recorded robot logs (CARMEN or ROS bags), opened by file type.

:func:`open_log` picks the reader by file type: a ROS 1 bag (``.bag`` or the ``#ROSBAG``
header), a ROS 2 bag (a folder with ``metadata.yaml``, or a ``.db3``/``.mcap`` file inside
one), anything else a CARMEN log (plain or gzip). Every reader returns a
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


def poses_look_corrected(path: str | os.PathLike[str]) -> bool:
    """Whether a log's poses are taken as ground truth by default: its name says "corrected"."""
    return "corrected" in Path(path).name.lower()


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
        with p.open("rb") as fh:
            head = fh.read(13)
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
        return read_carmen(path, laser=laser, max_range_m=max_range_m)
    log = read_bag(
        path,
        scan_topic=scan_topic,
        odom_topic=odom_topic,
        odom_frame=odom_frame,
        base_frame=base_frame,
    )
    if max_range_m is not None:
        log = replace(log, range_max=np.full(len(log), float(max_range_m)))
    return log
