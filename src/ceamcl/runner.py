"""Run a filter over a robot log and collect what experiments, plots and files need.

The runner only runs: it returns a :class:`RunResult` and writes nothing. Files and figures
of a run are written by :mod:`ceamcl.outputs`, one layer above.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from numpy.typing import NDArray

from ceamcl.errors import ConfigError, InputTypeError, type_name, wrong_type
from ceamcl.filters.base import (
    Hypothesis,
    LocalisationFilter,
    ParticleSnapshot,
    StepDiagnostics,
    StepRecord,
)
from ceamcl.filters.policies import Context, Policy
from ceamcl.filters.resampling import effective_sample_size
from ceamcl.filters.state import LocalisationState
from ceamcl.io.recorded import RobotLog
from ceamcl.motion.odometry import OdometryIncrement, apply_increment, increment_between
from ceamcl.pose import heading_error, position_error
from ceamcl.sensors.scan import LaserScan


@dataclass
class RunResult:
    """A whole run. ``hypotheses[k]`` is an array ``(H, 5)``: x, y, theta, weight, fitness."""

    algorithm: str
    times: NDArray[np.float64]
    estimates: NDArray[np.float64]
    truth: NDArray[np.float64] | None
    diagnostics: list[StepDiagnostics]
    hypotheses: list[NDArray[np.float64]]
    final_particles: ParticleSnapshot
    initial_particles: ParticleSnapshot
    snapshots: dict[int, ParticleSnapshot] = field(default_factory=dict)
    #: ``(T, 3, 3)``: the covariance of each step's estimate (carried unchanged between paced
    #: updates); NaN where the filter gave none
    covariances: NDArray[np.float64] | None = None

    @property
    def steps(self) -> int:
        return int(self.times.size)

    @property
    def states(self) -> list[LocalisationState | None]:
        """The filter's state after each step (:mod:`ceamcl.filters.state`)."""
        return [d.state for d in self.diagnostics]

    @property
    def truth_known(self) -> NDArray[np.bool_]:
        """Which steps have a true pose: every one for a simulated or corrected log, the
        matched scans for a raw log with truth from its corrected log (NaN rows elsewhere)."""
        if self.truth is None:
            return np.zeros(self.steps, dtype=bool)
        return np.asarray(np.all(np.isfinite(self.truth), axis=1), dtype=bool)

    @property
    def position_errors(self) -> NDArray[np.float64] | None:
        return None if self.truth is None else position_error(self.estimates, self.truth)

    @property
    def heading_errors(self) -> NDArray[np.float64] | None:
        return None if self.truth is None else heading_error(self.estimates, self.truth)

    @property
    def step_ms(self) -> NDArray[np.float64]:
        """Time of each filter step after the global initialisation (``[0.0]`` when none)."""
        return np.array([d.step_ms for d in self.diagnostics[1:]] or [0.0])

    @property
    def updates(self) -> int:
        """Steps after the initialisation at which the filter was stepped (every step unless an
        update policy held some back)."""
        return sum(d.stepped for d in self.diagnostics[1:])

    @property
    def update_ms(self) -> NDArray[np.float64]:
        """Time of each step that updated the filter (``[0.0]`` when none): with an update
        policy, a held-back scan costs nothing and :attr:`step_ms` counts it as 0."""
        return np.array([d.step_ms for d in self.diagnostics[1:] if d.stepped] or [0.0])

    @property
    def update_state_ms(self) -> NDArray[np.float64]:
        """:attr:`update_ms` with the reading of the filter's state after each update, what
        a user who asks where the robot is and whether to trust it pays per update (the
        runner and the ROS node read it after every update; ``[0.0]`` when none)."""
        return np.array(
            [d.step_ms + d.state_ms for d in self.diagnostics[1:] if d.stepped] or [0.0]
        )


def _hypothesis_array(hyps: Sequence[Hypothesis]) -> NDArray[np.float64]:
    if not hyps:
        return np.zeros((0, 5))
    return np.array([[*h.pose, h.weight, h.fitness] for h in hyps])


def measure(f: LocalisationFilter, k: int, act: Callable[[], StepRecord]) -> StepDiagnostics:
    """Run one filter call ``act`` (an initialisation or a step) as step ``k``: its wall time,
    then the particle count and the ESS ``1 / sum w_i^2`` of the filter's normalised weights
    afterwards (NaN when the filter cannot show its weights) and its state (it only observes:
    asking it changes nothing of the run)."""
    return _measure(f, k, act, with_hypotheses=False)[0]


def _measure(
    f: LocalisationFilter, k: int, act: Callable[[], StepRecord], *, with_hypotheses: bool
) -> tuple[StepDiagnostics, list[Hypothesis]]:
    """:func:`measure`, and with ``with_hypotheses`` the filter's hypotheses after the call,
    asked once and handed to ``state`` (a particle filter clusters its particles for them)."""
    start = time.perf_counter()
    record = act()
    step_ms = (time.perf_counter() - start) * 1e3
    start = time.perf_counter()
    hyps = f.hypotheses() if with_hypotheses else []
    state = f.state(hyps) if with_hypotheses else f.state()
    state_ms = (time.perf_counter() - start) * 1e3
    w = f.particle_weights()
    ess = effective_sample_size(w) if np.all(np.isfinite(w)) else float("nan")
    diag = StepDiagnostics(k, int(w.size), ess, step_ms, record, state=state, state_ms=state_ms)
    return diag, hyps


def timed_step(
    f: LocalisationFilter, k: int, increment: OdometryIncrement, scan: LaserScan | None
) -> StepDiagnostics:
    """``f.step(increment, scan)`` as step ``k``, measured (:func:`measure`)."""
    return measure(f, k, lambda: f.step(increment, scan))


def _carried(
    hypotheses: NDArray[np.float64], odom_from: NDArray[np.float64], odom_to: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Hypothesis rows (x, y, theta, ...) moved, noise-free, by the odometry between two poses
    (as amcl's map -> odom transform carries the robot between updates)."""
    inc = increment_between(odom_from, odom_to)
    if inc.is_zero or hypotheses.shape[0] == 0:
        return hypotheses
    out = hypotheses.copy()
    out[:, :3] = apply_increment(hypotheses[:, :3], inc.rot1, inc.trans, inc.rot2)
    return out


def _estimate(f: LocalisationFilter) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    e = f.estimate()
    return np.asarray(e.pose, dtype=np.float64), np.asarray(e.covariance, dtype=np.float64)


def _start_tracking(
    f: LocalisationFilter,
    initial: tuple[NDArray[np.float64], NDArray[np.float64]],
    scan: LaserScan,
) -> StepRecord:
    f.initialise_pose(*initial)
    return f.step(OdometryIncrement(0.0, 0.0, 0.0), scan)


#: What :func:`run_filter` calls on a filter (and ``initialise_global``, or ``initialise_pose``
#: with an initial pose) and on a log.
_FILTER_METHODS = ("step", "estimate", "hypotheses", "state", "particles", "particle_weights")
_LOG_ATTRIBUTES = ("times", "odometry", "scan", "__len__")


def _check_run_arguments(
    f: object,
    log: object,
    on_step: object,
    snapshot_every: object,
    update_when: object,
    initial_pose: object,
) -> None:
    """:func:`run_filter`'s arguments, each refused in one line naming it."""
    start = "initialise_global" if initial_pose is None else "initialise_pose"
    if not all(callable(getattr(f, m, None)) for m in (start, *_FILTER_METHODS)):
        raise InputTypeError(
            f"f: expected a localisation filter (ceamcl.filters.make_filter(name, grid, rng)), "
            f"got {type_name(f)}"
        )
    if not all(hasattr(log, a) for a in _LOG_ATTRIBUTES):
        raise InputTypeError(
            "log: expected a robot log with times, odometry and scan(k) "
            "(ceamcl.io.logs.open_log(path), Scenario.simulate(rng)), "
            f"got {type_name(log)}"
        )
    for name, value in (("on_step", on_step), ("update_when", update_when)):
        if value is not None and not callable(value):
            raise InputTypeError(f"{name}: expected a function or None, got {type_name(value)}")
    if not isinstance(snapshot_every, int | np.integer) or isinstance(snapshot_every, bool):
        raise wrong_type(snapshot_every, int, "snapshot_every")
    if snapshot_every < 0:
        raise ConfigError(f"snapshot_every: expected a count >= 0, got {snapshot_every}")
    if initial_pose is not None and (
        not isinstance(initial_pose, tuple | list) or len(initial_pose) != 2
    ):
        raise InputTypeError(
            "initial_pose: expected (pose, covariance) or None, got "
            f"{type_name(initial_pose)}"
            + (f" of {len(initial_pose)}" if isinstance(initial_pose, tuple | list) else "")
        )


def run_filter(
    f: LocalisationFilter,
    log: RobotLog,
    *,
    on_step: Callable[[int], None] | None = None,
    snapshot_every: int = 0,
    update_when: Policy | None = None,
    initial_pose: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> RunResult:
    """Global localisation from the first scan, then one filter step per log entry; each
    step's record holds its time, particle count and ESS (measured here) and what the filter
    says about it.

    ``update_when`` (e.g. :func:`ceamcl.filters.policies.on_motion` ``(0.25, 0.2)``, Nav2's
    ``update_min_d``/``update_min_a``) updates at a real robot's pace: the filter is stepped
    only at the scans where the policy, shown the odometry motion since the last update, says
    so, with the *whole* increment since then (no scan's odometry is dropped). At the other
    scans the estimate and hypotheses are the last update's, carried along by the odometry
    since (:func:`_carried`), and the step's record says ``stepped=False``. Without it (the
    default) every entry is a step.

    ``initial_pose=(pose, covariance)`` tracks instead: step 0 is ``f.initialise_pose`` and a
    step with the first scan and no motion, in place of the global initialisation.

    ``on_step(k)`` is called after each step (progress bars hook in here);
    ``snapshot_every > 0`` keeps the particles every that many steps (for animations).
    """
    _check_run_arguments(f, log, on_step, snapshot_every, update_when, initial_pose)
    n = len(log)
    if n == 0:
        raise ValueError("run_filter: the log has no entries")
    estimates = np.zeros((n, 3))
    covariances = np.full((n, 3, 3), np.nan)
    first = log.scan(0)
    if initial_pose is None:
        diag, hyps = _measure(f, 0, partial(f.initialise_global, first), with_hypotheses=True)
    else:
        start = partial(_start_tracking, f, initial_pose, first)
        diag, hyps = _measure(f, 0, start, with_hypotheses=True)
    diagnostics = [diag]
    initial = f.particles()
    estimates[0], covariances[0] = _estimate(f)
    hypotheses = [_hypothesis_array(hyps)]
    snapshots: dict[int, ParticleSnapshot] = {0: initial} if snapshot_every > 0 else {}
    if on_step is not None:
        on_step(0)
    odom_at_update = np.asarray(log.odometry[0], dtype=np.float64)
    for k in range(1, n):
        odom = np.asarray(log.odometry[k], dtype=np.float64)
        if update_when is None:
            inc = increment_between(log.odometry[k - 1], odom)
        elif update_when(Context(motion=odom - odom_at_update)):
            inc = increment_between(odom_at_update, odom)
        else:
            last = diagnostics[-1]
            diagnostics.append(
                StepDiagnostics(k, last.n_particles, last.ess, 0.0, StepRecord(), False, last.state)
            )
            estimates[k] = _carried(estimates[k - 1][None, :], log.odometry[k - 1], odom)[0]
            covariances[k] = covariances[k - 1]
            hypotheses.append(_carried(hypotheses[-1], log.odometry[k - 1], odom))
            if on_step is not None:
                on_step(k)
            continue
        odom_at_update = odom
        diag, hyps = _measure(f, k, partial(f.step, inc, log.scan(k)), with_hypotheses=True)
        diagnostics.append(diag)
        estimates[k], covariances[k] = _estimate(f)
        hypotheses.append(_hypothesis_array(hyps))
        if snapshot_every > 0 and k % snapshot_every == 0:
            snapshots[k] = f.particles()
        if on_step is not None:
            on_step(k)
    truth = getattr(log, "true_poses", None)
    return RunResult(
        algorithm=f.name,
        times=np.asarray(log.times, dtype=np.float64),
        estimates=estimates,
        truth=None if truth is None else np.asarray(truth, dtype=np.float64),
        diagnostics=diagnostics,
        hypotheses=hypotheses,
        final_particles=f.particles(),
        initial_particles=initial,
        snapshots=snapshots,
        covariances=covariances,
    )
