"""The odometry motion model of Probabilistic Robotics (Thrun, Burgard, Fox 2005, sec. 5.4).

The motion between two odometry poses is decomposed into a first rotation ``rot1``, a
translation ``trans`` and a second rotation ``rot2`` (eq. 5.34-5.36). ``sample`` implements
``sample_motion_model_odometry`` (Table 5.6) for a whole array of poses at once: each
component is perturbed by zero-mean Gaussian noise whose *variance* is

    rot1:  alpha1 * rot1^2 + alpha2 * trans^2
    trans: alpha3 * trans^2 + alpha4 * (rot1^2 + rot2^2)
    rot2:  alpha1 * rot2^2 + alpha2 * trans^2

As in ROS amcl's differential model, the rotation noise uses the smaller of ``rot1`` and
``rot1 - pi`` (a robot driving backwards has not really turned by pi). For translations under
1 cm, where the direction of travel is meaningless, amcl takes ``rot1`` as 0; here it is 0
(forwards) or pi (backwards) by the sign of the displacement along the old heading: a
reversing robot whose odometry is read at every scan moves in steps that small, and a ``rot1``
of 0 would carry it forwards by as much as it backed up.

:func:`synthetic_odometry` (the simulator's odometry, and a corrected log's) draws the noise of
each step of a pose track from :meth:`OdometryIncrement.wheel_variances`: a step that travels
sideways, as a SLAM track jitters while the robot stands, is no turn.

**Noise per stride of travel (the default since 2026-11-30).** amcl's alphas suit its own
pace: an update at the first scan past :data:`STRIDE_M` of travel or :data:`STRIDE_RAD` of
turning (``update_min_d``, ``update_min_a``), so an update Nav2 makes spans up to about two of
those strides. An update that spans more ground (a corrected log's key scans, one every
0.1-3 m) gets the noise of that many independent strides of :data:`DEFAULT_STRIDE_M` (twice
``update_min_d``): Table 5.6's variances divided by :meth:`OdometryIncrement.strides`, so that
they grow with the distance, not with its square (over 1.5 m with alpha 0.2 the heading
spreads by 0.52 rad instead of 0.9). An update within one such stride keeps Table 5.6 exactly:
every step of the simulator and every update at Nav2's pace on the shared raw logs. A stride
of 0.25 m divided Nav2's own updates too (0.3 m by 1.2) and tracked fr079's doubtful room
worse. Turns are not counted by default (``stride_rad=None``): a turn's slip on real wheels is
one systematic error, not a sum of independent ones, and counting it cut the rotation noise
that lets a species follow raw odometry through a turn (measured: docs/real-data.md, "Noise
per stride of travel"). ``stride_m=None`` is amcl's rule, Table 5.6 over the whole update.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import diff, wrap
from ceamcl.errors import ConfigError, check_rng

MIN_TRANSLATION_FOR_ROT1_M = 0.01
#: the travel and the turn of one stride of Nav2's pace, its ``update_min_d`` and
#: ``update_min_a`` (module docstring, "noise per stride")
STRIDE_M = 0.25
STRIDE_RAD = 0.2
#: the motion model's default stride of travel: the longest update Nav2 itself makes, about two
#: of its strides (module docstring)
DEFAULT_STRIDE_M = 2 * STRIDE_M


@dataclass(frozen=True)
class OdometryNoise:
    """Noise parameters alpha1..alpha4 of the odometry model (ROS amcl's odom_alpha1..4).

    alpha1: rotation noise from rotation; alpha2: rotation noise from translation (rad^2/m^2);
    alpha3: translation noise from translation; alpha4: translation noise from rotation
    (m^2/rad^2). Defaults are ROS amcl's (0.2 each).
    """

    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2

    def __post_init__(self) -> None:
        for name in ("alpha1", "alpha2", "alpha3", "alpha4"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name}: expected a non-negative number, got {v}")


@dataclass(frozen=True)
class OdometryIncrement:
    """Motion between two odometry poses: rotate ``rot1``, drive ``trans``, rotate ``rot2``."""

    rot1: float
    trans: float
    rot2: float

    @property
    def is_zero(self) -> bool:
        return self.rot1 == 0.0 and self.trans == 0.0 and self.rot2 == 0.0

    @property
    def turns(self) -> tuple[float, float]:
        """How far the robot turned before and after its travel, in radians: a travel
        backwards (``rot1`` nearer pi than 0) is no turn, so ``rot1`` counts from pi and
        ``rot2`` from -pi then; the two add up to the change of heading. (Not the noise's
        fold of :meth:`variances`, which also reads a ``rot2`` near pi as small.)"""
        shift = self._travel_shift()
        return abs(float(diff(self.rot1, shift))), abs(float(diff(self.rot2, -shift)))

    def _travel_shift(self) -> float:
        """pi when the robot travels backwards (``rot1`` nearer pi than 0), else 0: what
        ``rot1`` counts from as a turn."""
        back = abs(float(diff(self.rot1, np.pi))) < abs(float(diff(self.rot1, 0.0)))
        return np.pi if back else 0.0

    def variances(self, noise: OdometryNoise) -> tuple[float, float, float]:
        """Variances of the three components under ``noise`` (Table 5.6; each rotation folded
        as Nav2's differential model folds it: the smaller of it and its difference to pi)."""
        r1 = min(abs(float(diff(self.rot1, 0.0))), abs(float(diff(self.rot1, np.pi))))
        r2 = min(abs(float(diff(self.rot2, 0.0))), abs(float(diff(self.rot2, np.pi))))
        return _table_5_6(noise, r1, self.trans, r2)

    def strides(self, stride_m: float | None, stride_rad: float | None) -> float:
        """How many strides of ``stride_m`` travel or ``stride_rad`` turning (:attr:`turns`,
        both together) the increment spans, at least 1 (module docstring, "noise per
        stride"); ``None`` leaves that part out."""
        n = 1.0
        if stride_m is not None:
            n = max(n, self.trans / stride_m)
        if stride_rad is not None:
            n = max(n, sum(self.turns) / stride_rad)
        return n

    def wheel_variances(self, noise: OdometryNoise) -> tuple[float, float, float]:
        """:meth:`variances` for a step that wheels could have made, read from a pose track.

        A wheeled robot travels in a direction between its heading before and after the step
        (forwards or backwards). A track that moves sideways, as a SLAM estimate jitters while
        the robot stands or turns on the spot, decomposes into a turn out of about pi/2 and a
        turn back, and ``alpha1 * rot1^2`` makes that a random turn of about
        ``sqrt(alpha1) * pi/2`` (0.22 rad with alpha 0.02) that the wheels never made. Here the
        rotation noise of such a step is that of the turn the robot made: ``rot1`` clipped into
        the sweep of headings, ``rot2`` the rest of the change of heading. Inside the sweep the
        step keeps :meth:`variances` exactly."""
        along = float(diff(self.rot1, self._travel_shift()))
        turn = float(diff(self.rot1 + self.rot2, 0.0))
        r1 = min(max(along, min(0.0, turn)), max(0.0, turn))
        if r1 == along:
            return self.variances(noise)
        return _table_5_6(noise, r1, self.trans, turn - r1)


def _table_5_6(noise: OdometryNoise, r1: float, t: float, r2: float) -> tuple[float, float, float]:
    """The variances of ``rot1``, ``trans`` and ``rot2`` for turns ``r1``, ``r2`` and travel
    ``t`` (Table 5.6)."""
    return (
        noise.alpha1 * r1**2 + noise.alpha2 * t**2,
        noise.alpha3 * t**2 + noise.alpha4 * (r1**2 + r2**2),
        noise.alpha1 * r2**2 + noise.alpha2 * t**2,
    )


def _odometry_pose(pose: ArrayLike, name: str) -> NDArray[np.float64]:
    """``pose`` as three numbers ``(x, y, theta)``; a one-line error naming ``name`` else."""
    try:
        p = np.asarray(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(
            f"{name}: expected an odometry pose (x, y, theta), got {type(pose).__name__}"
        ) from None
    if p.size != 3:
        raise ConfigError(
            f"{name}: expected an odometry pose (x, y, theta), got {p.size} value(s) "
            f"(shape {p.shape})"
        )
    return p.reshape(3)


def increment_between(previous: ArrayLike, current: ArrayLike) -> OdometryIncrement:
    """Decompose the motion between two odometry poses ``(x, y, theta)`` (eq. 5.34-5.36)."""
    p = _odometry_pose(previous, "previous")
    c = _odometry_pose(current, "current")
    dx, dy = c[0] - p[0], c[1] - p[1]
    trans = float(np.hypot(dx, dy))
    if trans >= MIN_TRANSLATION_FOR_ROT1_M:
        rot1 = float(diff(np.arctan2(dy, dx), p[2]))
    else:  # only forwards or backwards (module docstring)
        rot1 = np.pi if dx * np.cos(p[2]) + dy * np.sin(p[2]) < 0.0 else 0.0
    rot2 = float(diff(c[2] - p[2], rot1))
    return OdometryIncrement(rot1, trans, rot2)


def apply_increment(
    poses: ArrayLike,
    rot1: ArrayLike,
    trans: ArrayLike,
    rot2: ArrayLike,
) -> NDArray[np.float64]:
    """Move poses ``(N, 3)`` by (possibly per-pose) increments; headings wrapped."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    heading = p[:, 2] + np.asarray(rot1, dtype=np.float64)
    t = np.asarray(trans, dtype=np.float64)
    return np.column_stack(
        [
            p[:, 0] + t * np.cos(heading),
            p[:, 1] + t * np.sin(heading),
            wrap(heading + np.asarray(rot2, dtype=np.float64)),
        ]
    )


@dataclass(frozen=True)
class OdometryMotionModel:
    """Samples ``p(x_t | x_{t-1}, u)`` for arrays of poses (sample_motion_model_odometry).

    ``stride_m``, ``stride_rad``: an update's noise is that of the strides of travel (and, with
    ``stride_rad``, of turning) it spans (module docstring, "noise per stride of travel"); the
    default counts strides of :data:`DEFAULT_STRIDE_M` travel only; ``None`` for both: Table
    5.6 over the whole update, as amcl."""

    noise: OdometryNoise = OdometryNoise()
    stride_m: float | None = DEFAULT_STRIDE_M
    stride_rad: float | None = None

    def __post_init__(self) -> None:
        for name in ("stride_m", "stride_rad"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: expected a positive number or None, got {v}")

    def sample(
        self,
        poses: ArrayLike,
        increment: OdometryIncrement,
        rng: np.random.Generator,
        *,
        wheels: bool = False,
    ) -> NDArray[np.float64]:
        """New poses ``(N, 3)``: each input pose moved by a noisy copy of ``increment``.

        ``wheels``: the noise of :meth:`OdometryIncrement.wheel_variances` (odometry made
        from a pose track), not of :meth:`OdometryIncrement.variances` (the filter's model,
        Nav2's). Either is divided by the increment's :meth:`~OdometryIncrement.strides`."""
        check_rng(rng)
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        n = p.shape[0]
        variances = increment.wheel_variances if wheels else increment.variances
        v_rot1, v_trans, v_rot2 = variances(self.noise)
        strides = increment.strides(self.stride_m, self.stride_rad)
        if strides > 1.0:
            v_rot1, v_trans, v_rot2 = v_rot1 / strides, v_trans / strides, v_rot2 / strides
        noise = rng.standard_normal((n, 3))
        rot1 = increment.rot1 - noise[:, 0] * np.sqrt(v_rot1)
        trans = increment.trans - noise[:, 1] * np.sqrt(v_trans)
        rot2 = increment.rot2 - noise[:, 2] * np.sqrt(v_rot2)
        return apply_increment(p, rot1, trans, rot2)


def synthetic_odometry(
    true_poses: ArrayLike,
    noise: OdometryNoise,
    rng: np.random.Generator,
    *,
    kidnapped_at: Sequence[int] = (),
) -> NDArray[np.float64]:
    """Odometry poses ``(T, 3)``: the true increments, each perturbed by the odometry model
    with the rotation noise of the turn a wheeled robot made (``wheels=True`` of
    :meth:`OdometryMotionModel.sample`: a track's sideways jitter is no turn).

    Serves the simulator and corrected real logs (which hold no raw odometry). At the steps in
    ``kidnapped_at`` the robot is lifted and carried: the wheels do not turn, so the odometry
    stays where it was while the truth jumps. Each step's noise is Table 5.6's over the whole
    step, however long (no strides): the data the shared logs' measurements were made on.
    """
    check_rng(rng)
    truth = np.asarray(true_poses, dtype=np.float64).reshape(-1, 3)
    model = OdometryMotionModel(noise, stride_m=None)
    odom = np.empty_like(truth)
    if truth.shape[0] == 0:
        return odom
    odom[0] = truth[0]
    lifted = set(kidnapped_at)
    for k in range(1, truth.shape[0]):
        if k in lifted:
            odom[k] = odom[k - 1]
            continue
        inc = increment_between(truth[k - 1], truth[k])
        odom[k] = model.sample(odom[k - 1 : k], inc, rng, wheels=True)[0]
    return odom
