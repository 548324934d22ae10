"""TUM trajectory files: ``t x y z qx qy qz qw`` per line, as read by the evo tool."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray


def write_tum(path: str | os.PathLike[str], times: ArrayLike, poses: ArrayLike) -> Path:
    """Write planar poses ``(T, 3)`` as a TUM trajectory (z = 0, yaw as a quaternion)."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if t.size != p.shape[0]:
        raise ValueError(f"write_tum: {t.size} times for {p.shape[0]} poses")
    half = p[:, 2] / 2.0
    rows = np.column_stack(
        [
            t,
            p[:, 0],
            p[:, 1],
            np.zeros_like(t),
            np.zeros_like(t),
            np.zeros_like(t),
            np.sin(half),
            np.cos(half),
        ]
    )
    out = Path(path)
    tmp = out.with_name(out.name + ".tmp")
    np.savetxt(tmp, rows, fmt="%.9f", header="timestamp x y z qx qy qz qw", comments="# ")
    os.replace(tmp, out)
    return out


def read_tum(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a TUM file back as ``(times, poses (T, 3))`` (yaw from the quaternion)."""
    rows = np.atleast_2d(np.loadtxt(path, comments="#"))
    qz, qw = rows[:, 6], rows[:, 7]
    yaw = 2.0 * np.arctan2(qz, qw)
    return rows[:, 0], np.column_stack([rows[:, 1], rows[:, 2], np.angle(np.exp(1j * yaw))])
