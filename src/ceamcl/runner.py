"""Run a filter over a robot log and collect what experiments, plots and files need.

The runner only runs: it returns a :class:`RunResult` and writes nothing. Files and figures
of a run are written by :mod:`ceamcl.outputs`, one layer above.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.base import LocalisationFilter, ParticleSnapshot, StepDiagnostics, StepRecord
from ceamcl.filters.resampling import effective_sample_size
from ceamcl.io.recorded import RobotLog
from ceamcl.motion.odometry import OdometryIncrement, increment_between
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

    @property
    def steps(self) -> int:
        return int(self.times.size)

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


def _hypothesis_array(f: LocalisationFilter) -> NDArray[np.float64]:
    hyps = f.hypotheses()
    if not hyps:
        return np.zeros((0, 5))
    return np.array([[*h.pose, h.weight, h.fitness] for h in hyps])


def measure(f: LocalisationFilter, k: int, act: Callable[[], StepRecord]) -> StepDiagnostics:
    """Run one filter call ``act`` (an initialisation or a step) as step ``k``: its wall time,
    then the particle count and the ESS ``1 / sum w_i^2`` of the filter's normalised weights
    afterwards (NaN when the filter cannot show its weights)."""
    start = time.perf_counter()
    record = act()
    step_ms = (time.perf_counter() - start) * 1e3
    w = f.particle_weights()
    ess = effective_sample_size(w) if np.all(np.isfinite(w)) else float("nan")
    return StepDiagnostics(k, int(w.size), ess, step_ms, record)


def timed_step(
    f: LocalisationFilter, k: int, increment: OdometryIncrement, scan: LaserScan | None
) -> StepDiagnostics:
    """``f.step(increment, scan)`` as step ``k``, measured (:func:`measure`)."""
    return measure(f, k, lambda: f.step(increment, scan))


def run_filter(
    f: LocalisationFilter,
    log: RobotLog,
    *,
    on_step: Callable[[int], None] | None = None,
    snapshot_every: int = 0,
) -> RunResult:
    """Global localisation from the first scan, then one filter step per log entry; each
    step's record holds its time, particle count and ESS (measured here) and what the filter
    says about it.

    ``on_step(k)`` is called after each step (progress bars hook in here);
    ``snapshot_every > 0`` keeps the particles every that many steps (for animations).
    """
    n = len(log)
    if n == 0:
        raise ValueError("run_filter: the log has no entries")
    estimates = np.zeros((n, 3))
    first = log.scan(0)
    diagnostics = [measure(f, 0, lambda: f.initialise_global(first))]
    initial = f.particles()
    estimates[0] = f.estimate().pose
    hypotheses = [_hypothesis_array(f)]
    snapshots: dict[int, ParticleSnapshot] = {0: initial} if snapshot_every > 0 else {}
    if on_step is not None:
        on_step(0)
    for k in range(1, n):
        inc = increment_between(log.odometry[k - 1], log.odometry[k])
        diagnostics.append(timed_step(f, k, inc, log.scan(k)))
        estimates[k] = f.estimate().pose
        hypotheses.append(_hypothesis_array(f))
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
    )
