"""Laser scans and the beams a sensor model uses from them.

A :class:`LaserScan` mirrors ``sensor_msgs/LaserScan``: ranges at evenly spaced bearings,
a valid interval ``[range_min, range_max]``, and the laser's pose on the robot.

:func:`prepare_scan` selects the beams a sensor model evaluates (``max_beams``, evenly spaced
over the scan, as ROS amcl's ``laser_max_beams``) and classifies each reading as ROS amcl does:

* NaN: skipped (amcl's likelihood-field model drops it);
* ``r <= range_min`` (zero, negative, -inf): amcl replaces it by ``range_max``, i.e. a
  *max-range* reading;
* ``r >= range_max`` or +inf: a *max-range* reading (no return). The likelihood field skips
  these; the beam model scores them with its ``z_max`` term.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True, eq=False)
class LaserScan:
    """One scan. ``ranges`` in metres at bearings ``angle_min + i * angle_increment`` (laser frame).

    ``pose`` is the laser's pose ``(x, y, yaw)`` in the robot's base frame.
    """

    ranges: NDArray[np.float64]
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    stamp: float = 0.0

    def __post_init__(self) -> None:
        r = np.asarray(self.ranges, dtype=np.float64).reshape(-1)
        object.__setattr__(self, "ranges", r)
        if not (np.isfinite(self.range_max) and self.range_max > 0):
            raise ValueError(f"range_max: expected a positive number, got {self.range_max}")
        if not (np.isfinite(self.range_min) and 0 <= self.range_min < self.range_max):
            raise ValueError(
                f"range_min: expected 0 <= range_min < range_max, got {self.range_min}"
            )

    @property
    def n_beams(self) -> int:
        return int(self.ranges.size)

    @property
    def angles(self) -> NDArray[np.float64]:
        return self.angle_min + self.angle_increment * np.arange(self.n_beams, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class LaserGeometry:
    """What is constant across a laser's scans: beam bearings, range limits, mounting pose."""

    n_beams: int = 181
    angle_min: float = -np.pi / 2.0
    angle_increment: float = np.pi / 180.0
    range_min: float = 0.02
    range_max: float = 8.0
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def covering(
        cls,
        fov_rad: float,
        n_beams: int,
        range_max: float,
        range_min: float = 0.02,
        pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> LaserGeometry:
        """Beams spread evenly over ``fov_rad``, centred on the laser's x axis."""
        inc = fov_rad / (n_beams - 1) if n_beams > 1 else 0.0
        return cls(n_beams, -fov_rad / 2.0, inc, range_min, range_max, pose)

    @property
    def angles(self) -> NDArray[np.float64]:
        return self.angle_min + self.angle_increment * np.arange(self.n_beams, dtype=np.float64)

    def scan(self, ranges: ArrayLike, stamp: float = 0.0) -> LaserScan:
        return LaserScan(
            np.asarray(ranges, dtype=np.float64),
            self.angle_min,
            self.angle_increment,
            self.range_min,
            self.range_max,
            self.pose,
            stamp,
        )


@dataclass(frozen=True, eq=False)
class PreparedScan:
    """The beams of one scan that a sensor model evaluates.

    ``ranges``/``bearings`` hold the selected, non-NaN beams; ``is_max`` flags max-range
    readings. ``n_beams`` is how many beams enter the likelihood of the model at hand
    (the fitness is the geometric mean over those).
    """

    ranges: NDArray[np.float64]
    bearings: NDArray[np.float64]
    is_max: NDArray[np.bool_]
    range_max: float
    laser_pose: tuple[float, float, float]
    n_beams: int
    source_indices: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))


def select_beam_indices(n_total: int, max_beams: int) -> NDArray[np.intp]:
    """At most ``max_beams`` beam indices evenly spread over ``n_total`` (first and last kept)."""
    if max_beams <= 0:
        raise ValueError(f"max_beams: expected a positive count, got {max_beams}")
    if n_total <= max_beams:
        return np.arange(n_total, dtype=np.intp)
    if max_beams == 1:
        return np.array([n_total // 2], dtype=np.intp)
    return np.unique(np.round(np.linspace(0, n_total - 1, max_beams)).astype(np.intp))


def prepare_scan(scan: LaserScan, max_beams: int, *, keep_max_range: bool) -> PreparedScan:
    """Select and classify beams as ROS amcl does (see the module docstring).

    ``keep_max_range``: whether max-range readings enter the likelihood (beam model) or are
    dropped (likelihood field).
    """
    idx = select_beam_indices(scan.n_beams, max_beams)
    r = scan.ranges[idx]
    bearings = scan.angles[idx]
    keep = ~np.isnan(r)
    is_max = keep & ((r <= scan.range_min) | (r >= scan.range_max))
    if not keep_max_range:
        keep &= ~is_max
    r = np.where(is_max, scan.range_max, r)[keep]
    return PreparedScan(
        ranges=np.ascontiguousarray(r),
        bearings=np.ascontiguousarray(bearings[keep]),
        is_max=np.ascontiguousarray(is_max[keep]),
        range_max=scan.range_max,
        laser_pose=scan.pose,
        n_beams=int(keep.sum()),
        source_indices=idx[keep],
    )


def laser_poses(poses: ArrayLike, laser_pose: tuple[float, float, float]) -> NDArray[np.float64]:
    """World poses ``(N, 3)`` of the laser given robot poses and the laser's mounting pose."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    lx, ly, lyaw = laser_pose
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    return np.column_stack([p[:, 0] + c * lx - s * ly, p[:, 1] + s * lx + c * ly, p[:, 2] + lyaw])
