"""``ceamcl evaluate-log``: global localisation from many start points of a real log, scored
per algorithm (success rate, time to converge, RMSE, particles, step time).

The log is prepared as ``ceamcl run`` prepares it (:mod:`ceamcl.replay`: truth, synthetic
odometry, map); :mod:`~ceamcl.experiments.log_windows` chooses the windows, each run is scored
by :func:`~ceamcl.experiments.metrics.score_errors`, and
:mod:`~ceamcl.experiments.log_report` writes the tables and figures.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ceamcl.errors import ConfigError
from ceamcl.experiments.executors import Batch, ProgressCallback, filter_bytes
from ceamcl.experiments.log_report import write_evaluation
from ceamcl.experiments.log_windows import start_windows
from ceamcl.experiments.metrics import (
    GATHERED_SHARE,
    HOLD_STEPS,
    final_error,
    likelihood_evaluations,
    score_errors,
    within,
)
from ceamcl.filters.registry import DEFAULT_SENSOR, check_sensor, localises_globally
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.results import ensure_output_dir
from ceamcl.io.truth_check import TruthDoubt, doubtful_truth
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.replay import PreparedLog, UpdatePace, filter_rng, make_paced_filter
from ceamcl.runner import RunResult, run_filter


@dataclass(frozen=True, eq=False)
class LogTrial:
    """One evaluation run: global localisation with ``algorithm`` on a window of the log."""

    name: str
    algorithm: str
    start_index: int
    grid: OccupancyGrid
    log: RecordedLog
    seed: int
    hold: int = HOLD_STEPS
    pace: UpdatePace | None = None
    hold_m: float | None = None
    #: the sensor model of the core algorithms (the Nav2 peer keeps the wheel's beam model)
    sensor: str = DEFAULT_SENSOR


@dataclass(frozen=True)
class LogTrialResult:
    name: str
    algorithm: str
    start_index: int
    start_time_s: float
    scans: int
    window_s: float
    window_m: float
    success: bool
    scans_to_converge: int | None
    time_to_converge_s: float
    distance_to_converge_m: float
    position_rmse_m: float
    position_rmse_from_first_m: float
    confidently_wrong: bool
    heading_rmse_rad: float
    final_position_error_m: float
    final_heading_error_rad: float
    mean_particles: float
    mean_step_ms: float
    initialisation_ms: float
    updates: int
    #: poses scored against a scan over the run, the global initialisation included (NaN for
    #: a filter that does not count them: the Nav2 peer)
    likelihood_evaluations: float
    elapsed_s: NDArray[np.float64] = field(repr=False)
    position_errors: NDArray[np.float64] = field(repr=False)
    heading_errors: NDArray[np.float64] = field(repr=False)
    #: every scan's step time after the initialisation (a held-back scan costs 0)
    step_ms: NDArray[np.float64] = field(repr=False)
    #: the time of each scan that updated the filter (the runner's ``update_ms``: ``[0.0]``
    #: when none did)
    update_ms: NDArray[np.float64] = field(repr=False)

    @property
    def median_step_ms(self) -> float:
        """The median over the run's scans (the initialisation, its own column, excluded)."""
        return float(np.median(self.step_ms)) if self.step_ms.size else math.nan

    @property
    def mean_update_ms(self) -> float:
        """The mean over the scans that updated the filter."""
        return float(self.update_ms.mean()) if self.update_ms.size else math.nan

    @property
    def median_update_ms(self) -> float:
        """The median over the scans that updated the filter: at Nav2's pace most scans only
        carry their odometry, so the median step is about 0 and this is what an update costs."""
        return float(np.median(self.update_ms)) if self.update_ms.size else math.nan


def run_log_trial(trial: LogTrial) -> LogTrialResult:
    """Run one trial (a top-level function, so any executor can run it)."""
    rng = filter_rng(trial.seed, trial.start_index, trial.algorithm)
    f = make_paced_filter(trial.algorithm, trial.grid, rng, sensor=trial.sensor)
    result = run_filter(
        f, trial.log, update_when=None if trial.pace is None else trial.pace.policy()
    )
    pos, head = result.position_errors, result.heading_errors
    if pos is None or head is None:
        raise ConfigError(f"trial {trial.name}: the log window has no ground truth")
    log = trial.log
    score = score_errors(
        result.times, pos, head, hold=trial.hold, hold_m=trial.hold_m, travelled=log.travelled_m
    )
    known = result.truth_known
    return LogTrialResult(
        name=trial.name,
        algorithm=trial.algorithm,
        start_index=trial.start_index,
        start_time_s=float(log.times[0]),
        scans=len(log),
        window_s=log.duration_s,
        window_m=log.path_length_m,
        success=score.success,
        scans_to_converge=score.scans_to_converge,
        time_to_converge_s=score.time_to_converge_s,
        distance_to_converge_m=score.distance_to_converge_m,
        position_rmse_m=score.position_rmse_m,
        position_rmse_from_first_m=score.position_rmse_from_first_m,
        confidently_wrong=confidently_wrong(result),
        heading_rmse_rad=score.heading_rmse_rad,
        final_position_error_m=final_error(pos),
        final_heading_error_rad=final_error(head),
        # after the initialisation (step 0, its test poses' population), as the step time
        mean_particles=float(
            np.mean([d.n_particles for d in result.diagnostics[1:] or result.diagnostics])
        ),
        mean_step_ms=float(result.step_ms.mean()),
        initialisation_ms=float(result.diagnostics[0].step_ms),
        updates=result.updates,
        likelihood_evaluations=_evaluations(result),
        # the scans with truth only (all of a corrected log's; a raw log's matched scans)
        elapsed_s=(result.times - result.times[0])[known],
        position_errors=pos[known],
        heading_errors=head[known],
        step_ms=result.step_ms,
        update_ms=result.update_ms,
    )


def _evaluations(result: RunResult) -> float:
    counts = likelihood_evaluations(result.diagnostics)
    return math.nan if counts is None else float(counts.sum())


def confidently_wrong(result: RunResult, share: float = GATHERED_SHARE) -> bool:
    """At the last scan with truth, the filter puts at least ``share`` (90 %) of its weight on
    one hypothesis, and that hypothesis is not within the tolerances of the truth. (A filter
    that shows one hypothesis, as Nav2 AMCL, is confidently wrong when its estimate is.)"""
    known = np.flatnonzero(result.truth_known)
    if known.size == 0 or result.truth is None:
        return False
    k = int(known[-1])
    hyps = result.hypotheses[k]
    total = float(hyps[:, 3].sum()) if hyps.shape[0] else 0.0
    if total <= 0:
        return False
    top = int(np.argmax(hyps[:, 3]))
    return bool(hyps[top, 3] / total >= share and not within(hyps[top, :3], result.truth[k]))


@dataclass
class Evaluation:
    results: list[LogTrialResult]
    table: list[dict[str, Any]]
    skipped: dict[str, str]
    map_source: str
    windows: list[tuple[int, int]]
    window: str
    out_dir: Path | None
    update_policy: str = "every scan"
    sensor: str = DEFAULT_SENSOR
    #: :func:`paired_evaluations`: the evaluations of the first algorithm beside each other's
    #: over the windows both localised
    paired: list[dict[str, Any]] = field(default_factory=list)


def _pooled_median(times: Sequence[NDArray[np.float64]]) -> float:
    """The median over the values of every run together (NaN when there are none)."""
    pooled = np.concatenate(times) if times else np.empty(0)
    return float(np.median(pooled)) if pooled.size else math.nan


def aggregate(results: Sequence[LogTrialResult], algorithms: Sequence[str]) -> list[dict[str, Any]]:
    """Per algorithm: success rate, time/scans to converge, RMSEs, particles, step time."""
    rows = []
    for algo in algorithms:
        rs = [r for r in results if r.algorithm == algo]
        if not rs:
            continue
        ok = [r for r in rs if r.success]

        def mean(vals: list[float]) -> float:
            return float(np.mean(vals)) if vals else math.nan

        rows.append(
            {
                "algorithm": algo,
                "runs": len(rs),
                "success_rate": len(ok) / len(rs),
                "time_to_converge_s": mean([r.time_to_converge_s for r in ok]),
                "distance_to_converge_m": mean([r.distance_to_converge_m for r in ok]),
                "scans_to_converge": mean([float(r.scans_to_converge or 0) for r in ok]),
                "position_rmse_m": mean([r.position_rmse_m for r in ok]),
                "position_rmse_from_first_m": mean(
                    [
                        r.position_rmse_from_first_m
                        for r in rs
                        if math.isfinite(r.position_rmse_from_first_m)
                    ]
                ),
                "confidently_wrong": sum(r.confidently_wrong for r in rs),
                "heading_rmse_rad": mean([r.heading_rmse_rad for r in ok]),
                "mean_particles": mean([r.mean_particles for r in rs]),
                "mean_step_ms": mean([r.mean_step_ms for r in rs]),
                # over every scan of every run: a recovery's long update moves the mean, not
                # the median a robot meets at most scans
                "median_step_ms": _pooled_median([r.step_ms for r in rs]),
                "mean_update_ms": mean([r.mean_update_ms for r in rs]),
                "median_update_ms": _pooled_median([r.update_ms for r in rs]),
                "updates_per_run": mean([float(r.updates) for r in rs]),
                "initialisation_ms": mean([r.initialisation_ms for r in rs]),
                "likelihood_evaluations": mean([r.likelihood_evaluations for r in rs]),
            }
        )
    return rows


def paired_evaluations(
    results: Sequence[LogTrialResult], algorithms: Sequence[str]
) -> list[dict[str, Any]]:
    """Likelihood evaluations at equal success: the first algorithm of ``algorithms`` that
    localises globally beside each other one that does, over the windows where both localised
    (issue 17's "at equal success"; the per-algorithm means of :func:`aggregate` also count
    the windows one of them failed). A row per other algorithm: ``windows`` both localised,
    each one's mean evaluations there and ``ratio`` (the first's over the other's; NaN where
    a filter does not count its evaluations or no window qualifies)."""
    scored = [a for a in dict.fromkeys(algorithms) if localises_globally(a)]
    if len(scored) < 2:
        return []
    first, others = scored[0], scored[1:]
    ok = {(r.algorithm, r.start_index): r for r in results if r.success}
    rows = []
    for other in others:
        both = sorted(s for (a, s) in ok if a == first and (other, s) in ok)
        mine = [ok[(first, s)].likelihood_evaluations for s in both]
        theirs = [ok[(other, s)].likelihood_evaluations for s in both]
        a = float(np.mean(mine)) if both else math.nan
        b = float(np.mean(theirs)) if both else math.nan
        rows.append(
            {
                "algorithm": first,
                "against": other,
                "windows": len(both),
                "evaluations": a,
                "against_evaluations": b,
                "ratio": a / b if b > 0 else math.nan,
            }
        )
    return rows


def log_trials(
    prepared: PreparedLog,
    grid: OccupancyGrid,
    algorithms: Sequence[str],
    windows: Sequence[tuple[int, int]],
    *,
    hold: int = HOLD_STEPS,
    hold_m: float | None = None,
    pace: UpdatePace | None = None,
    sensor: str = DEFAULT_SENSOR,
) -> list[LogTrial]:
    """The runs :func:`evaluate_log` makes: each algorithm on each window ``(start, stop)``
    of the prepared log, seeded with the log's seed."""
    log = prepared.log
    return [
        LogTrial(
            name=f"{algo}@{s}",
            algorithm=algo,
            start_index=s,
            grid=grid,
            log=log.window(s, e),
            seed=prepared.seed,
            hold=hold,
            pace=pace,
            hold_m=hold_m,
            sensor=sensor,
        )
        for s, e in windows
        for algo in algorithms
    ]


def evaluate_log(
    prepared: PreparedLog,
    grid: OccupancyGrid,
    algorithms: Sequence[str],
    *,
    starts: int = 20,
    scans: int | None = None,
    window_s: float | None = None,
    window_m: float | None = None,
    hold: int = HOLD_STEPS,
    hold_m: float | None = None,
    map_source: str = "",
    executor: str = "local",
    workers: int | None = None,
    out: str | os.PathLike[str] | None = None,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
    skipped: dict[str, str] | None = None,
    pace: UpdatePace | None = None,
    truth_doubt: TruthDoubt | None = None,
    sensor: str = DEFAULT_SENSOR,
) -> Evaluation:
    """Global localisation from ``starts`` points of the log with each algorithm.

    Writes ``evaluate.csv``, ``evaluate.md``, ``errors.png`` and ``success.png`` to ``out``;
    ``evaluate.md`` says how well the truth explains its scans (``truth_doubt``, made here when
    the caller has none). ``sensor`` names the sensor model of every core algorithm
    (:data:`ceamcl.filters.registry.SENSOR_MODELS`; the Nav2 peer keeps the wheel's own).
    """
    check_sensor(sensor)
    log = prepared.log
    if not prepared.has_truth:
        raise ConfigError(
            f"{log.path}: the log has no ground truth to score against; evaluate-log needs a "
            "SLAM-corrected log (--truth yes if its poses are corrected), or a raw log with "
            "--truth-from CORRECTED, the corrected log of the same run"
        )
    if starts < 1:
        raise ConfigError(f"starts: expected a positive count, got {starts}")
    out_dir = ensure_output_dir(out) if out is not None else None
    windows, window_what = start_windows(
        log, starts, scans=scans, window_s=window_s, window_m=window_m
    )
    trials = log_trials(
        prepared, grid, algorithms, windows, hold=hold, hold_m=hold_m, pace=pace, sensor=sensor
    )
    batch = Batch(executor, workers, progress, quiet)
    results = batch.run(run_log_trial, trials, f"evaluate {log.name}", filter_bytes(grid))
    table = aggregate(results, algorithms)
    evaluation = Evaluation(
        results,
        table,
        dict(skipped or {}),
        map_source,
        windows,
        window_what,
        out_dir,
        "every scan" if pace is None else pace.describe(),
        sensor,
        paired_evaluations(results, algorithms),
    )
    if out_dir is not None:
        doubt = truth_doubt or doubtful_truth(log, grid)
        write_evaluation(
            evaluation, prepared, out_dir, hold=hold, hold_m=hold_m, truth_note=doubt.summary()
        )
    return evaluation
