"""Planar headings as quaternions ``(x, y, z, w)`` and back, for ROS bags, MCAP and TUM files."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def yaw_to_quaternion(yaw: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(qz, qw)`` of the rotation by ``yaw`` about z (``qx = qy = 0``)."""
    half = np.asarray(yaw, dtype=np.float64) / 2.0
    return np.sin(half), np.cos(half)


def quaternion_yaw(x: ArrayLike, y: ArrayLike, z: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
    """Heading in ``[-pi, pi]`` (rotation about z, ZYX convention) of quaternions of any norm
    and either sign."""
    qx, qy, qz, qw = (np.asarray(v, dtype=np.float64) for v in (x, y, z, w))
    return np.arctan2(2.0 * (qw * qz + qx * qy), qw * qw + qx * qx - qy * qy - qz * qz)
