"""TUM trajectory files: ``t x y z qx qy qz qw`` per line, as read by the evo tool."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.io.quaternion import quaternion_yaw, yaw_to_quaternion
from ceamcl.io.results import atomic_write


def write_tum(path: str | os.PathLike[str], times: ArrayLike, poses: ArrayLike) -> Path:
    """Write planar poses ``(T, 3)`` as a TUM trajectory (z = 0, yaw as a quaternion)."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if t.size != p.shape[0]:
        raise ValueError(f"write_tum: {t.size} times for {p.shape[0]} poses")
    qz, qw = yaw_to_quaternion(p[:, 2])
    zero = np.zeros_like(t)
    rows = np.column_stack([t, p[:, 0], p[:, 1], zero, zero, zero, qz, qw])
    with atomic_write(path) as tmp:
        np.savetxt(tmp, rows, fmt="%.9f", header="timestamp x y z qx qy qz qw", comments="# ")
    return Path(path)


def read_tum(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a TUM file back as ``(times, poses (T, 3))`` (yaw from the quaternion)."""
    rows = np.atleast_2d(np.loadtxt(path, comments="#"))
    yaw = quaternion_yaw(rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7])
    return rows[:, 0], np.column_stack([rows[:, 1], rows[:, 2], yaw])
