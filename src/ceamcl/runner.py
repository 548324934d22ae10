"""Run a filter over a robot log and collect what experiments, plots and files need."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.base import LocalisationFilter, ParticleSnapshot, StepDiagnostics
from ceamcl.motion.odometry import increment_between
from ceamcl.sensors.scan import LaserScan


class RobotLog(Protocol):
    """What a replayable log offers: times, odometry poses, scans, and truth where known."""

    @property
    def times(self) -> NDArray[np.float64]: ...

    @property
    def odometry(self) -> NDArray[np.float64]: ...

    def __len__(self) -> int: ...

    def scan(self, k: int) -> LaserScan: ...


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
        if self.truth is None:
            return None
        return np.hypot(*(self.estimates[:, :2] - self.truth[:, :2]).T)

    @property
    def heading_errors(self) -> NDArray[np.float64] | None:
        if self.truth is None:
            return None
        d = self.estimates[:, 2] - self.truth[:, 2]
        return np.abs(np.angle(np.exp(1j * d)))


def _hypothesis_array(f: LocalisationFilter) -> NDArray[np.float64]:
    hyps = f.hypotheses()
    if not hyps:
        return np.zeros((0, 5))
    return np.array([[*h.pose, h.weight, h.fitness] for h in hyps])


def run_filter(
    f: LocalisationFilter,
    log: RobotLog,
    *,
    on_step: Callable[[int], None] | None = None,
    snapshot_every: int = 0,
) -> RunResult:
    """Global localisation from the first scan, then one filter step per log entry.

    ``on_step(k)`` is called after each step (progress bars hook in here);
    ``snapshot_every > 0`` keeps the particles every that many steps (for animations).
    """
    n = len(log)
    if n == 0:
        raise ValueError("run_filter: the log has no entries")
    estimates = np.zeros((n, 3))
    diagnostics = [f.initialise_global(log.scan(0))]
    initial = f.particles()
    estimates[0] = f.estimate().pose
    hypotheses = [_hypothesis_array(f)]
    snapshots: dict[int, ParticleSnapshot] = {0: initial} if snapshot_every > 0 else {}
    if on_step is not None:
        on_step(0)
    for k in range(1, n):
        inc = increment_between(log.odometry[k - 1], log.odometry[k])
        diagnostics.append(f.step(inc, log.scan(k)))
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
