"""Motion models: how particles move between scans given odometry."""

from ceamcl.motion.odometry import (
    OdometryIncrement,
    OdometryMotionModel,
    OdometryNoise,
    apply_increment,
    increment_between,
    synthetic_odometry,
)

__all__ = [
    "OdometryIncrement",
    "OdometryMotionModel",
    "OdometryNoise",
    "apply_increment",
    "increment_between",
    "synthetic_odometry",
]
