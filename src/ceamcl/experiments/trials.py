"""One trial: simulate a route from a seed, run one algorithm over it, record what is measured.

:func:`run_trial` is the top-level, picklable function every executor runs. Its generators
come from ``SeedSequence(seed, spawn_key=(route number, repetition))``, the route's number in
the whole course (a route chosen with ``--start-routes`` keeps it): the simulated log depends
on the seed, the route and the repetition, never on the algorithm or on the other routes run,
so every algorithm of an experiment sees the same logs, and no executor can change a number.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ceamcl.experiments.metrics import (
    StepPrecision,
    TrialMetrics,
    likelihood_evaluations,
    nearest_error,
    step_coverage,
    trial_metrics,
    weight_shares,
)
from ceamcl.experiments.routes import Course
from ceamcl.filters import registry
from ceamcl.filters.ceamcl.records import species_of
from ceamcl.pose import position_error
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation.simulator import SimulatedLog


@dataclass(frozen=True, eq=False)
class Trial:
    """One run of one algorithm on one route of a course, from one seed."""

    experiment: str
    algorithm: str
    course: Course
    route_index: int
    repetition: int
    seed: int
    delta_per_m2: float | None = None
    max_time_s: float | None = None
    #: The algorithm's config instead of its default, and sensor settings on top of the
    #: algorithm's own (the tuning sweep, experiments/tuning.py); a picklable frozen dataclass.
    config: Any = None
    sensor_settings: tuple[tuple[str, Any], ...] = ()

    @property
    def route(self) -> str:
        return self.course.routes[self.route_index].name

    @property
    def route_number(self) -> int:
        """The route's number in the whole course: the seed key (``--start-routes`` keeps it)."""
        return self.course.number(self.route_index)

    @property
    def name(self) -> str:
        delta = "" if self.delta_per_m2 is None else f" delta={self.delta_per_m2:g}"
        return (
            f"{self.experiment}: {self.algorithm}{delta} on {self.route}, "
            f"repetition {self.repetition} (seed {self.seed})"
        )


@dataclass(frozen=True, eq=False)
class TrialRecord:
    """What a trial measured, step by step (``T`` steps, ``K`` symmetric images)."""

    experiment: str
    algorithm: str
    route: str
    route_index: int
    repetition: int
    seed: int
    delta_per_m2: float | None
    single_estimate: bool
    times: NDArray[np.float64]  # (T,)
    truth: NDArray[np.float64]  # (T, 3)
    estimates: NDArray[np.float64]  # (T, 3)
    covered: NDArray[np.bool_]  # (T, K): image k covered at step t (identity first)
    gathered: NDArray[np.float64]  # (T,): weight share of hypotheses at some image
    n_particles: NDArray[np.int64]  # (T,)
    step_ms: NDArray[np.float64]  # (T,)
    resources: NDArray[np.float64]  # (T,): CEAMCL's total resources; NaN for the others
    n_hypotheses: NDArray[np.int64]  # (T,)
    tracking_error: NDArray[np.float64]  # (T,): position error of the hypothesis nearest the truth
    precision: StepPrecision  # weight shares, nearest hypothesis, likelihood evaluations
    kidnapped_at: tuple[int, ...]
    metrics: TrialMetrics

    @property
    def position_errors(self) -> NDArray[np.float64]:
        return position_error(self.estimates, self.truth)


def trial_generators(seed: int, route_number: int, repetition: int) -> list[np.random.Generator]:
    """The simulator's and the filter's generators of one trial (algorithm-independent);
    ``route_number``: the route's number in the whole course (:attr:`Trial.route_number`)."""
    ss = np.random.SeedSequence(seed, spawn_key=(route_number, repetition))
    return [np.random.default_rng(s) for s in ss.spawn(2)]


def simulate_trial_log(trial: Trial) -> SimulatedLog:
    """The simulated log of a trial (the same for every algorithm)."""
    sim_rng, _ = trial_generators(trial.seed, trial.route_number, trial.repetition)
    log = trial.course.scenario(trial.route_index).simulate(sim_rng, trial.course.grid())
    if trial.max_time_s is not None:
        n = int(np.searchsorted(log.times, log.times[0] + trial.max_time_s, side="right"))
        n = max(2, min(n, len(log)))
        log = dataclasses.replace(
            log,
            times=log.times[:n],
            true_poses=log.true_poses[:n],
            odometry=log.odometry[:n],
            ranges=log.ranges[:n],
            kidnapped_at=tuple(k for k in log.kidnapped_at if k < n),
        )
    return log


def localise_trial(
    trial: Trial,
    *,
    snapshot_every: int = 0,
    on_start: Callable[[int], None] | None = None,
    on_step: Callable[[int], None] | None = None,
) -> tuple[SimulatedLog, RunResult]:
    """Simulate the trial's log and run its filter over it: the run :func:`run_trial` records.

    ``snapshot_every > 0`` also keeps the particles every that many steps (for the visual
    outputs); it does not change the run. ``on_start(steps)``/``on_step(k)``: progress.
    """
    log = simulate_trial_log(trial)
    if on_start is not None:
        on_start(len(log))
    _, filter_rng = trial_generators(trial.seed, trial.route_number, trial.repetition)
    grid = trial.course.grid()
    config = trial.config
    if trial.delta_per_m2 is not None:
        config = registry.with_config(trial.algorithm, delta_per_m2=trial.delta_per_m2)
    f = registry.make_filter(
        trial.algorithm,
        grid,
        filter_rng,
        config=config,
        sensor_settings=dict(trial.sensor_settings),
    )
    return log, run_filter(f, log, on_step=on_step, snapshot_every=snapshot_every)


def run_trial(trial: Trial) -> TrialRecord:
    """Simulate, localise globally, and record coverage, errors, sample size and cost."""
    log, result = localise_trial(trial)
    return record_trial(trial, log, result)


def record_trial(trial: Trial, log: SimulatedLog, result: RunResult) -> TrialRecord:
    """What :func:`run_trial` records of the run ``result`` of ``trial`` over ``log``."""
    # an algorithm that reports one pose is measured by its estimate (docs/experiments.md)
    single = registry.get(trial.algorithm).reports == "estimate"
    n = result.steps
    k_images = trial.course.n_images
    covered = np.zeros((n, k_images), dtype=bool)
    gathered = np.zeros(n)
    tracking = np.zeros(n)
    shares = np.zeros((n, 4))  # true image set, spurious, heaviest, at the truth
    nearest_heading = np.zeros(n)
    truth = np.asarray(log.true_poses, dtype=np.float64)
    for k in range(n):
        images = trial.course.images(truth[k])
        if single:
            hyps = np.array([[*result.estimates[k], 1.0]])
        else:
            hyps = result.hypotheses[k]
        covered[k], gathered[k] = step_coverage(hyps, images)
        near = hyps if hyps.shape[0] else result.estimates[k : k + 1]
        tracking[k], nearest_heading[k] = nearest_error(near, truth[k])
        w = weight_shares(hyps, images)
        shares[k] = w.true_images, w.spurious, w.heaviest, w.truth
    diags = result.diagnostics
    n_particles = np.array([d.n_particles for d in diags], dtype=np.int64)
    step_ms = np.array([d.step_ms for d in diags], dtype=np.float64)
    resources = np.array(
        [sum(s.resources for s in species_of(d)) if species_of(d) else np.nan for d in diags]
    )
    n_hyp = np.array([h.shape[0] for h in result.hypotheses], dtype=np.int64)
    precision = StepPrecision(
        true_image_weight=shares[:, 0],
        spurious_weight=shares[:, 1],
        heaviest_weight=shares[:, 2],
        truth_weight=shares[:, 3],
        nearest_position_error=tracking,
        nearest_heading_error=nearest_heading,
        likelihood_evaluations=likelihood_evaluations(diags),
    )
    metrics = trial_metrics(
        result.times,
        truth,
        result.estimates,
        covered,
        gathered,
        n_particles,
        step_ms,
        precision,
        single_estimate=single,
    )
    return TrialRecord(
        experiment=trial.experiment,
        algorithm=trial.algorithm,
        route=trial.route,
        route_index=trial.route_index,
        repetition=trial.repetition,
        seed=trial.seed,
        delta_per_m2=trial.delta_per_m2,
        single_estimate=single,
        times=result.times,
        truth=truth,
        estimates=result.estimates,
        covered=covered,
        gathered=gathered,
        n_particles=n_particles,
        step_ms=step_ms,
        resources=resources,
        n_hypotheses=n_hyp,
        tracking_error=tracking,
        precision=precision,
        kidnapped_at=tuple(log.kidnapped_at),
        metrics=metrics,
    )
