"""Laser scans and the beams a sensor model uses from them.

A :class:`LaserScan` mirrors ``sensor_msgs/LaserScan``: ranges at evenly spaced bearings,
a valid interval ``[range_min, range_max]``, and the laser's pose on the robot.

:func:`prepare_scan` selects the beams a sensor model evaluates (``max_beams``, evenly spaced
over the scan, as ROS amcl's ``laser_max_beams``) and classifies each reading as
``sensor_msgs/LaserScan`` and REP 117 define them:

* ``NaN``: erroneous or missing measurement: dropped;
* ``-inf``: an object too close to measure: dropped (it says nothing about the map);
* ``+inf``: no return within range: a *max-range* reading;
* a finite reading outside ``[range_min, range_max]`` (zero, negative, below ``range_min``,
  beyond ``range_max``): invalid, dropped;
* exactly ``range_max``: a *max-range* reading too, as drivers that predate REP 117 (and the
  simulator) report "no return" as ``range_max``;
* anything else in ``[range_min, range_max)``: a hit.

The likelihood field skips max-range readings; the beam model scores them with its ``z_max``
term. Unlike ROS 1 amcl, which turns readings ``<= range_min`` into max-range readings,
invalid readings are dropped, so a driver's "0 = no echo" convention must be converted to
``+inf`` before the filter sees it. :class:`PreparedScan` counts each class among the
selected beams. A scan whose selected beams are all dropped carries no information: filters
leave their weights unchanged on it (see ``docs/robustness.md``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.errors import LogFormatError


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
        try:
            r = np.asarray(self.ranges, dtype=np.float64)
        except (TypeError, ValueError):
            raise LogFormatError("scan: ranges: expected a sequence of numbers") from None
        if r.ndim > 1:  # flattened, its beams would land at the wrong bearings
            raise LogFormatError(
                f"scan: ranges: expected a 1-D sequence of numbers, got shape {r.shape}"
            )
        r = r.reshape(-1)
        object.__setattr__(self, "ranges", r)
        if not (np.isfinite(self.range_max) and self.range_max > 0):
            raise LogFormatError(
                f"scan: range_max: expected a positive finite number, got {self.range_max}"
            )
        if not (np.isfinite(self.range_min) and 0 <= self.range_min < self.range_max):
            raise LogFormatError(
                f"scan: range_min: expected 0 <= range_min < range_max ({self.range_max}), "
                f"got {self.range_min}"
            )
        for name in ("angle_min", "angle_increment", "stamp"):
            if not np.isfinite(getattr(self, name)):
                raise LogFormatError(
                    f"scan: {name}: expected a finite number, got {getattr(self, name)}"
                )
        if len(self.pose) != 3 or not all(np.isfinite(v) for v in self.pose):
            raise LogFormatError(
                f"scan: pose: expected three finite numbers (x, y, yaw), got {self.pose}"
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

    ``ranges``/``bearings`` hold the selected, usable beams; ``is_max`` flags max-range
    readings. ``n_beams`` is how many beams enter the likelihood of the model at hand
    (the fitness is the geometric mean over those); 0 means the scan says nothing.
    ``n_nan``, ``n_too_close`` (-inf), ``n_invalid`` (finite, outside
    ``[range_min, range_max]``) and ``n_max_range`` count the selected beams of each class
    (``n_max_range`` whether or not the model keeps them).
    """

    ranges: NDArray[np.float64]
    bearings: NDArray[np.float64]
    is_max: NDArray[np.bool_]
    range_max: float
    laser_pose: tuple[float, float, float]
    n_beams: int
    source_indices: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    n_nan: int = 0
    n_too_close: int = 0
    n_invalid: int = 0
    n_max_range: int = 0

    @property
    def informative(self) -> bool:
        """Whether at least one beam enters the likelihood."""
        return self.n_beams > 0

    @functools.cached_property
    def directions(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Cosine and sine of each beam's bearing on the robot (bearing plus the laser's yaw),
        computed once per prepared scan: a filter step weighs one scan several times."""
        angles = self.bearings + self.laser_pose[2]
        return np.ascontiguousarray(np.cos(angles)), np.ascontiguousarray(np.sin(angles))


def select_beam_indices(n_total: int, max_beams: int) -> NDArray[np.intp]:
    """At most ``max_beams`` beam indices evenly spread over ``n_total`` (first and last kept).
    The same few pairs come at every scan, so the answer is cached (read-only)."""
    if max_beams <= 0:
        raise ValueError(f"max_beams: expected a positive count, got {max_beams}")
    return _beam_indices(int(n_total), int(max_beams))


@functools.lru_cache(maxsize=64)
def _beam_indices(n_total: int, max_beams: int) -> NDArray[np.intp]:
    if n_total <= max_beams:
        idx = np.arange(n_total, dtype=np.intp)
    elif max_beams == 1:
        idx = np.array([n_total // 2], dtype=np.intp)
    else:
        idx = np.unique(np.round(np.linspace(0, n_total - 1, max_beams)).astype(np.intp))
    idx.setflags(write=False)
    return idx


def classify_ranges(
    ranges: NDArray[np.float64], range_min: float, range_max: float
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """REP 117 classes of raw readings: ``(usable, is_max)``.

    ``usable``: a hit in ``[range_min, range_max)`` or a max-range reading (``+inf`` or exactly
    ``range_max``); ``is_max``: the max-range readings among them. NaN, ``-inf`` and finite
    readings outside ``[range_min, range_max]`` are neither.
    """
    r = np.asarray(ranges, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        is_max = (r == np.inf) | (r == range_max)
        hit = (r >= range_min) & (r < range_max)
    return hit | is_max, is_max


def prepare_scan(scan: LaserScan, max_beams: int, *, keep_max_range: bool) -> PreparedScan:
    """Select and classify beams (REP 117; see the module docstring).

    ``keep_max_range``: whether max-range readings enter the likelihood (beam model) or are
    dropped (likelihood field). One compiled pass (:func:`_select`) over the selected beams:
    a filter update prepares its scan three or four times (the sensor model's beams, the
    state's wall check, the map's agreement), and the NumPy form
    (:func:`prepare_scan_reference`, which it equals field for field) spent most of its time
    in a dozen small array operations.
    """
    idx = select_beam_indices(scan.n_beams, max_beams)
    kept, r, is_max_kept, n_nan, n_too_close, n_usable, n_max = _select(
        scan.ranges, idx, float(scan.range_min), float(scan.range_max), keep_max_range
    )
    counts = (int(idx.size), int(n_usable), int(n_nan), int(n_too_close), int(n_max))
    return _prepared(scan, kept, r, is_max_kept, counts)


def _prepared(
    scan: LaserScan,
    kept: NDArray[np.intp],
    ranges: NDArray[np.float64],
    is_max: NDArray[np.bool_],
    counts: tuple[int, int, int, int, int],
) -> PreparedScan:
    """The :class:`PreparedScan` of the ``kept`` beams of ``scan``; ``counts``: of the beams
    selected, how many, how many usable, NaN, ``-inf`` and max-range."""
    n_selected, n_usable, n_nan, n_too_close, n_max = counts
    return PreparedScan(
        ranges=ranges,
        # the bearings of LaserScan.angles at those indices, computed for the kept ones only
        bearings=scan.angle_min + scan.angle_increment * kept.astype(np.float64),
        is_max=is_max,
        range_max=scan.range_max,
        laser_pose=scan.pose,
        n_beams=int(kept.size),
        source_indices=kept,
        n_nan=n_nan,
        n_too_close=n_too_close,
        n_invalid=n_selected - n_usable - n_nan - n_too_close,
        n_max_range=n_max,
    )


@numba.njit(cache=True)
def _select(ranges, idx, range_min, range_max, keep_max_range):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The readings at ``idx`` classified as :func:`classify_ranges` does: the kept indices,
    their ranges (max-range readings as ``range_max``) and max-range flags, then the counts of
    NaN, ``-inf``, usable and max-range readings among the selected."""
    m = idx.size
    kept = np.empty(m, dtype=np.intp)
    out = np.empty(m)
    flags = np.empty(m, dtype=np.bool_)
    n_nan = n_too_close = n_usable = n_max = k = 0
    for j in range(m):
        i = idx[j]
        r = ranges[i]
        if np.isnan(r):
            n_nan += 1
            continue
        if r == -np.inf:
            n_too_close += 1
            continue
        is_max = r == np.inf or r == range_max
        if not (is_max or (r >= range_min and r < range_max)):
            continue  # invalid
        n_usable += 1
        if is_max:
            n_max += 1
            if not keep_max_range:
                continue
            out[k] = range_max
        else:
            out[k] = r
        flags[k] = is_max
        kept[k] = i
        k += 1
    return kept[:k].copy(), out[:k].copy(), flags[:k].copy(), n_nan, n_too_close, n_usable, n_max


def prepare_scan_reference(
    scan: LaserScan, max_beams: int, *, keep_max_range: bool
) -> PreparedScan:
    """:func:`prepare_scan` in NumPy (the reference it equals field for field)."""
    idx = select_beam_indices(scan.n_beams, max_beams)
    r = scan.ranges[idx]
    usable, is_max = classify_ranges(r, scan.range_min, scan.range_max)
    n_nan = int(np.count_nonzero(np.isnan(r)))
    n_too_close = int(np.count_nonzero(r == -np.inf))
    keep = usable if keep_max_range else usable & ~is_max
    kept = idx[keep]
    n_max = int(np.count_nonzero(is_max))
    r = r[keep]
    is_max_kept = is_max[keep]
    if n_max:
        r[is_max_kept] = scan.range_max
    counts = (int(idx.size), int(np.count_nonzero(usable)), n_nan, n_too_close, n_max)
    return _prepared(scan, kept, r, is_max_kept, counts)


def laser_poses(poses: ArrayLike, laser_pose: ArrayLike) -> NDArray[np.float64]:
    """World poses ``(N, 3)`` of the laser given robot poses and the laser's mounting pose
    ``(x, y, yaw)`` on the robot: one for all poses, or one per pose ``(N, 3)``. Headings are
    not wrapped (the sensor models only take their sine and cosine)."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    m = np.asarray(laser_pose, dtype=np.float64).reshape(-1, 3)
    lx, ly, lyaw = m[:, 0], m[:, 1], m[:, 2]
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    x, y, yaw = p[:, 0] + c * lx - s * ly, p[:, 1] + s * lx + c * ly, p[:, 2] + lyaw
    out = np.empty((x.size, 3))
    out[:, 0], out[:, 1], out[:, 2] = x, y, yaw
    return out
