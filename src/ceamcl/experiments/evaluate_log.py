"""Real logs: replay one through a filter (``ceamcl run``) and score global localisation from
many start points (``ceamcl evaluate-log``).

Both start the same way (docs/real-data.md):

1. open the log (:func:`ceamcl.io.logs.open_log`);
2. ground truth: where the log's poses are SLAM-corrected, they become the truth and the
   filter reads *synthetic* odometry drawn from them (:data:`DEFAULT_SYNTHETIC_NOISE`, the
   generator of child 0 of ``SeedSequence(seed)``); otherwise the recorded odometry is used
   and there is no truth;
3. the map: a ROS map file, or built from the log itself (:func:`ceamcl.mapping.map_from_log`).

Convergence, as :func:`score_run` computes it. A step is *inside* when the estimate is within
``pos_tol_m`` (0.5 m) and ``head_tol_rad`` (0.3 rad) of the truth. The run *converges* at the
first step ``c`` from which every later step of the window is inside; it *succeeds* when that
inside stretch lasts at least ``hold`` steps (default 10) and so is not a lucky last step.
Time and scans to converge are ``t[c] - t[0]`` and ``c``; the RMSEs are over steps ``c..end``.
"""

from __future__ import annotations

import math
import os
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from ceamcl.errors import ConfigError
from ceamcl.experiments.metrics import HEADING_TOL_RAD, POSITION_TOL_M
from ceamcl.io.logs import DEFAULT_SYNTHETIC_NOISE, RecordedLog, open_log, poses_look_corrected
from ceamcl.io.timestamps import check_times
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryNoise
from ceamcl.runner import RunResult, run_filter, write_run_files

if TYPE_CHECKING:
    from ceamcl.viz.outputs import OutputOptions

TruthMode = Literal["auto", "yes", "no"]

#: Success tolerances (the experiments' own) and the stretch a run must stay inside them.
POS_TOL_M = POSITION_TOL_M
HEAD_TOL_RAD = HEADING_TOL_RAD
HOLD_STEPS = 10
#: Default window of each evaluation run: 50 m of travel along the true path.
DEFAULT_WINDOW_M = 50.0


# ---------------------------------------------------------------------------- preparation
@dataclass(frozen=True, eq=False)
class PreparedLog:
    """A log ready to replay, and what was decided about it (for summaries)."""

    log: RecordedLog
    has_truth: bool
    odometry: str
    noise: OdometryNoise | None
    seed: int
    truth_reason: str = ""


def prepare_log(
    path: str | os.PathLike[str],
    *,
    seed: int = 0,
    truth: TruthMode = "auto",
    noise: OdometryNoise = DEFAULT_SYNTHETIC_NOISE,
    repair_times: bool = False,
    **open_kwargs: Any,
) -> PreparedLog:
    """Open a log and decide ground truth and odometry (module docstring, steps 1-2).

    ``truth="auto"`` takes the poses as ground truth when the log's content shows a corrected
    log (:func:`ceamcl.io.logs.poses_look_corrected`); ``truth_reason`` says what was decided
    and why. Scan times are checked (:func:`ceamcl.io.timestamps.check_times`), and repaired
    with ``repair_times``.
    """
    log = check_times(open_log(path, **open_kwargs), repair=repair_times)
    looks, why = poses_look_corrected(log)
    if truth == "auto":
        use_truth, reason = looks, f"{why} (--truth auto)"
    else:
        use_truth, reason = truth == "yes", f"{truth}: as --truth {truth} says (content: {why})"
    if not use_truth:
        return PreparedLog(log, False, "recorded", None, seed, reason)
    odo_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    return PreparedLog(
        log.with_synthetic_odometry(noise, odo_rng), True, "synthetic", noise, seed, reason
    )


def obtain_map(
    log: RecordedLog, map_path: str | os.PathLike[str] | None, resolution_m: float = 0.05
) -> tuple[OccupancyGrid, str]:
    """The map file, or the log's own map built from its poses; and a sentence saying which."""
    if map_path is not None:
        from ceamcl.maps.ros_io import load_map

        return load_map(map_path), f"map file {map_path}"
    from ceamcl.mapping import MappingConfig, map_from_log

    grid, stats = map_from_log(log, MappingConfig(resolution_m=resolution_m))
    return grid, (
        f"built from the log itself ({stats.scans} scans, {resolution_m} m cells, "
        f"{stats.free_area_m2:.0f} m^2 free)"
    )


def _filter_rng(seed: int, start: int, algorithm: str) -> np.random.Generator:
    key = (1, start, zlib.crc32(algorithm.encode()))
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


def _build(algorithm: str, grid: OccupancyGrid, rng: np.random.Generator) -> Any:
    from ceamcl.experiments.algorithms import build_filter

    return build_filter(algorithm, grid, rng)


# ---------------------------------------------------------------------------- ceamcl run
@dataclass
class ReplayOutcome:
    result: RunResult
    summary: dict[str, Any]
    out_dir: Path | None
    files: list[Path] = field(default_factory=list)  # visual outputs written (gif, report, mcap)


def replay_log(
    prepared: PreparedLog,
    grid: OccupancyGrid,
    algorithm: str,
    *,
    map_source: str = "",
    out: str | os.PathLike[str] | None = None,
    on_start: Callable[[int], None] | None = None,
    on_step: Callable[[int], None] | None = None,
    outputs: OutputOptions | None = None,
    on_frame: Callable[[int, int], None] | None = None,
) -> ReplayOutcome:
    """Global localisation over the whole log; with ``out``, the files of ``ceamcl run``.

    ``outputs`` (``ceamcl.viz.outputs.OutputOptions``) adds ``run.gif``/``run.mp4``,
    ``report.html`` and an MCAP file (with the log's scans, and its truth where it has one);
    the particles are kept every ``outputs.stride`` steps only when one of them is asked for.
    ``on_frame(i, total)`` reports the animation's progress.
    """
    from ceamcl.io.results import ensure_output_dir

    out_dir = ensure_output_dir(out) if out is not None else None
    log = prepared.log
    if on_start is not None:
        on_start(len(log))
    f = _build(algorithm, grid, _filter_rng(prepared.seed, 0, algorithm))
    snapshot_every = outputs.snapshot_every if outputs is not None else 0
    result = run_filter(f, log, on_step=on_step, snapshot_every=snapshot_every)
    summary = run_summary(result, prepared, grid, map_source)
    files = write_run_files(
        result,
        grid,
        out_dir,
        summary,
        title=f"{algorithm} on {log.name}, seed {prepared.seed}",
        log=log,
        outputs=outputs,
        on_frame=on_frame,
    )
    return ReplayOutcome(result, summary, out_dir, files)


def run_summary(
    result: RunResult, prepared: PreparedLog, grid: OccupancyGrid, map_source: str
) -> dict[str, Any]:
    """The fields of ``summary.json`` of ``ceamcl run``."""
    log = prepared.log
    step_ms = result.step_ms
    summary: dict[str, Any] = {
        "algorithm": result.algorithm,
        "log": log.path,
        "log_format": log.info.get("format"),
        "seed": prepared.seed,
        "scans": len(log),
        "beams_per_scan": sorted({int(b) for b in log.beam_counts}),
        "duration_s": log.duration_s,
        "path_length_m": log.path_length_m,
        "ground_truth": "the log's poses (SLAM-corrected)" if prepared.has_truth else None,
        "ground_truth_decision": prepared.truth_reason,
        "odometry": prepared.odometry,
        "repaired_times": int(log.info.get("repaired_times", 0)),
        "map": map_source,
        "map_size_m": list(grid.size_m),
        "map_free_area_m2": grid.free_area_m2,
        "initialisation_ms": float(result.diagnostics[0].step_ms),
        "mean_step_ms": float(step_ms.mean()),
        "median_step_ms": float(np.median(step_ms)),
        "particles_initial": int(result.diagnostics[0].n_particles),
        "particles_final": int(result.diagnostics[-1].n_particles),
        "mean_particles": float(np.mean([d.n_particles for d in result.diagnostics])),
    }
    if prepared.noise is not None:
        summary["odometry_noise"] = {
            "model": "odometry motion model (Probabilistic Robotics Table 5.6) applied to the "
            "increments between consecutive true poses",
            "alpha1": prepared.noise.alpha1,
            "alpha2": prepared.noise.alpha2,
            "alpha3": prepared.noise.alpha3,
            "alpha4": prepared.noise.alpha4,
            "seed": prepared.seed,
            "stream": "SeedSequence(seed).spawn(1)[0]",
        }
    pos, head = result.position_errors, result.heading_errors
    if pos is not None and head is not None:
        score = score_errors(result.times, pos, head)
        summary.update(
            {
                "final_position_error_m": float(pos[-1]),
                "final_heading_error_rad": float(head[-1]),
                "converged": score.success,
                "scans_to_converge": score.scans_to_converge,
                "time_to_converge_s": score.time_to_converge_s,
                "position_rmse_after_convergence_m": score.position_rmse_m,
                "heading_rmse_after_convergence_rad": score.heading_rmse_rad,
            }
        )
    return summary


# ---------------------------------------------------------------------------- scoring
@dataclass(frozen=True)
class Score:
    """Convergence of one run (module docstring). NaN/None where it did not converge."""

    success: bool
    scans_to_converge: int | None
    time_to_converge_s: float
    position_rmse_m: float
    heading_rmse_rad: float


def score_errors(
    times: NDArray[np.float64],
    pos_err: NDArray[np.float64],
    head_err: NDArray[np.float64],
    *,
    pos_tol_m: float = POS_TOL_M,
    head_tol_rad: float = HEAD_TOL_RAD,
    hold: int = HOLD_STEPS,
) -> Score:
    """Convergence step, success and RMSE after convergence of an error series."""
    inside = (pos_err <= pos_tol_m) & (head_err <= head_tol_rad)
    n = inside.size
    outside = np.flatnonzero(~inside)
    c = 0 if outside.size == 0 else int(outside[-1]) + 1
    if c >= n or n - c < min(hold, n):
        return Score(False, None, math.nan, math.nan, math.nan)
    return Score(
        True,
        c,
        float(times[c] - times[0]),
        float(np.sqrt(np.mean(pos_err[c:] ** 2))),
        float(np.sqrt(np.mean(head_err[c:] ** 2))),
    )


# ---------------------------------------------------------------------------- evaluate-log
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
    position_rmse_m: float
    heading_rmse_rad: float
    final_position_error_m: float
    final_heading_error_rad: float
    mean_particles: float
    mean_step_ms: float
    initialisation_ms: float
    elapsed_s: NDArray[np.float64] = field(repr=False)
    position_errors: NDArray[np.float64] = field(repr=False)
    heading_errors: NDArray[np.float64] = field(repr=False)


def run_log_trial(trial: LogTrial) -> LogTrialResult:
    """Run one trial (a top-level function, so any executor can run it)."""
    f = _build(
        trial.algorithm, trial.grid, _filter_rng(trial.seed, trial.start_index, trial.algorithm)
    )
    result = run_filter(f, trial.log)
    pos, head = result.position_errors, result.heading_errors
    if pos is None or head is None:
        raise ConfigError(f"trial {trial.name}: the log window has no ground truth")
    score = score_errors(result.times, pos, head, hold=trial.hold)
    log = trial.log
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
        position_rmse_m=score.position_rmse_m,
        heading_rmse_rad=score.heading_rmse_rad,
        final_position_error_m=float(pos[-1]),
        final_heading_error_rad=float(head[-1]),
        mean_particles=float(np.mean([d.n_particles for d in result.diagnostics])),
        mean_step_ms=float(result.step_ms.mean()),
        initialisation_ms=float(result.diagnostics[0].step_ms),
        elapsed_s=result.times - result.times[0],
        position_errors=pos,
        heading_errors=head,
    )


def _progress(
    log: RecordedLog, scans: int | None, window_s: float | None, window_m: float | None
) -> tuple[NDArray[np.float64], float, str]:
    """What a window's length is measured in, the length, and its description."""
    if sum(v is not None for v in (scans, window_s, window_m)) > 1:
        raise ConfigError("window: give one of scans, window_s and window_m, not several")
    if scans is not None:
        if scans < 2:
            raise ConfigError(f"scans: expected at least 2 scans per window, got {scans}")
        return np.arange(len(log), dtype=np.float64), float(scans - 1), f"{scans} scans"
    if window_s is not None:
        if not window_s > 0:
            raise ConfigError(f"window-s: expected a positive duration, got {window_s}")
        # a log's clock may step back a little (intel-corrected does): measure forward time
        elapsed = np.maximum.accumulate(log.times - log.times[0])
        return elapsed, float(window_s), f"{window_s:g} s"
    dist_m = DEFAULT_WINDOW_M if window_m is None else window_m
    if not dist_m > 0:
        raise ConfigError(f"window-m: expected a positive distance, got {dist_m}")
    truth = log.true_poses if log.true_poses is not None else log.poses
    step = np.hypot(*np.diff(truth[:, :2], axis=0).T)
    return np.concatenate([[0.0], np.cumsum(step)]), float(dist_m), f"{dist_m:g} m of travel"


def start_windows(
    log: RecordedLog,
    starts: int,
    *,
    scans: int | None = None,
    window_s: float | None = None,
    window_m: float | None = None,
) -> tuple[list[tuple[int, int]], str]:
    """``starts`` windows ``(start, stop)`` with evenly spread starts, each a whole window
    (``scans`` scans, ``window_s`` seconds or ``window_m`` metres of travel; default
    :data:`DEFAULT_WINDOW_M`), and the window's description.

    A window ends at the first scan where the length is reached. The latest start is the last
    one whose whole window lies in the log.
    """
    progress, length, what = _progress(log, scans, window_s, window_m)
    fits = np.flatnonzero(progress[-1] - progress >= length - 1e-9)
    if fits.size == 0:
        raise ConfigError(
            f"{log.path}: the log ({len(log)} scans, {log.duration_s:.0f} s, "
            f"{log.path_length_m:.0f} m) is shorter than one evaluation window of {what}; "
            "choose a shorter --scans/--window-s/--window-m"
        )
    last = int(fits[-1])
    picks = np.unique(np.round(np.linspace(0, last, starts)).astype(int))
    windows = []
    for s in picks:
        stop = int(np.searchsorted(progress, progress[s] + length - 1e-9, side="left")) + 1
        windows.append((int(s), max(stop, int(s) + 2)))
    return windows, what


@dataclass
class Evaluation:
    results: list[LogTrialResult]
    table: list[dict[str, Any]]
    skipped: dict[str, str]
    map_source: str
    windows: list[tuple[int, int]]
    window: str
    out_dir: Path | None


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
                "scans_to_converge": mean([float(r.scans_to_converge or 0) for r in ok]),
                "position_rmse_m": mean([r.position_rmse_m for r in ok]),
                "heading_rmse_rad": mean([r.heading_rmse_rad for r in ok]),
                "mean_particles": mean([r.mean_particles for r in rs]),
                "mean_step_ms": mean([r.mean_step_ms for r in rs]),
                "initialisation_ms": mean([r.initialisation_ms for r in rs]),
            }
        )
    return rows


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
    map_source: str = "",
    executor: str = "local",
    workers: int | None = None,
    out: str | os.PathLike[str] | None = None,
    console: Any = None,
    quiet: bool = False,
    skipped: dict[str, str] | None = None,
) -> Evaluation:
    """Global localisation from ``starts`` points of the log with each algorithm.

    Writes ``evaluate.csv``, ``evaluate.md``, ``errors.png`` and ``success.png`` to ``out``.
    """
    from ceamcl.experiments.executors import map_trials, open_executor
    from ceamcl.io.results import ensure_output_dir

    log = prepared.log
    if not prepared.has_truth:
        raise ConfigError(
            f"{log.path}: the log has no ground truth to score against; evaluate-log needs a "
            "SLAM-corrected log (pass --truth yes if its poses are corrected)"
        )
    if starts < 1:
        raise ConfigError(f"starts: expected a positive count, got {starts}")
    out_dir = ensure_output_dir(out) if out is not None else None
    windows, window_what = start_windows(
        log, starts, scans=scans, window_s=window_s, window_m=window_m
    )
    trials = [
        LogTrial(
            name=f"{algo}@{s}",
            algorithm=algo,
            start_index=s,
            grid=grid,
            log=log.window(s, e),
            seed=prepared.seed,
            hold=hold,
        )
        for s, e in windows
        for algo in algorithms
    ]
    with open_executor(executor, workers) as ex:
        results = map_trials(
            ex, run_log_trial, trials, label=f"evaluate {log.name}", console=console, quiet=quiet
        )
    table = aggregate(results, algorithms)
    evaluation = Evaluation(
        results, table, dict(skipped or {}), map_source, windows, window_what, out_dir
    )
    if out_dir is not None:
        write_evaluation(evaluation, prepared, out_dir, hold=hold)
    return evaluation


# ---------------------------------------------------------------------------- outputs
_CSV_FIELDS = (
    "algorithm",
    "start_index",
    "start_time_s",
    "scans",
    "window_s",
    "window_m",
    "success",
    "scans_to_converge",
    "time_to_converge_s",
    "position_rmse_m",
    "heading_rmse_rad",
    "final_position_error_m",
    "final_heading_error_rad",
    "mean_particles",
    "mean_step_ms",
    "initialisation_ms",
)


def write_evaluation(
    ev: Evaluation, prepared: PreparedLog, out_dir: Path, *, hold: int = HOLD_STEPS
) -> None:
    """``evaluate.csv`` (per run), ``evaluate.md`` (per algorithm) and two figures."""
    from ceamcl.experiments.common import write_csv, write_text

    rows = [{k: getattr(r, k) for k in _CSV_FIELDS} for r in ev.results]
    write_csv(out_dir / "evaluate.csv", rows)
    write_text(out_dir / "evaluate.md", evaluation_markdown(ev, prepared, hold=hold))
    plot_evaluation(ev, out_dir)


def evaluation_markdown(ev: Evaluation, prepared: PreparedLog, *, hold: int = HOLD_STEPS) -> str:
    from ceamcl.experiments.common import fmt

    log = prepared.log
    lengths = [e - s for s, e in ev.windows]
    lines = [
        f"# Global localisation on {log.name}",
        "",
        f"- log: `{log.path}` ({len(log)} scans, {log.duration_s:.0f} s, "
        f"{log.path_length_m:.0f} m of travel)",
        f"- map: {ev.map_source}",
        f"- odometry: {prepared.odometry}"
        + (
            f" (alpha1..4 = {prepared.noise.alpha1:g}, {prepared.noise.alpha2:g}, "
            f"{prepared.noise.alpha3:g}, {prepared.noise.alpha4:g}; seed {prepared.seed})"
            if prepared.noise is not None
            else ""
        ),
        f"- {len(ev.windows)} start points, windows of {ev.window} "
        f"({min(lengths)}-{max(lengths)} scans)",
        f"- success: within {POS_TOL_M} m and {HEAD_TOL_RAD} rad from a step on to the end of "
        f"the window, for at least {hold} steps; times and RMSEs over successful runs",
        "",
        "| algorithm | runs | success | time to converge [s] | scans to converge | "
        "position RMSE [m] | heading RMSE [rad] | mean particles | mean step [ms] | "
        "initialisation [ms] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    digits = {
        "time_to_converge_s": 1,
        "scans_to_converge": 1,
        "position_rmse_m": 3,
        "heading_rmse_rad": 3,
        "mean_particles": 0,
        "mean_step_ms": 1,
        "initialisation_ms": 0,
    }
    for row in ev.table:
        cells = [fmt(row[key], d, "-") for key, d in digits.items()]
        lines.append(
            f"| {row['algorithm']} | {row['runs']} | {100 * row['success_rate']:.0f}% | "
            + " | ".join(cells)
            + " |"
        )
    for algo, why in ev.skipped.items():
        lines.append(f"\n{algo} skipped: {why}")
    return "\n".join(lines) + "\n"


def plot_evaluation(ev: Evaluation, out_dir: Path) -> None:
    """``errors.png``: median and quartiles of the position error over time per algorithm;
    ``success.png``: success rate per algorithm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    algos = [row["algorithm"] for row in ev.table]
    fig, ax = plt.subplots(figsize=(8, 5))
    cmap = plt.get_cmap("tab10")
    for i, algo in enumerate(algos):
        rs = [r for r in ev.results if r.algorithm == algo]
        n = min(r.position_errors.size for r in rs)
        err = np.vstack([r.position_errors[:n] for r in rs])
        t = np.median(np.vstack([r.elapsed_s[:n] for r in rs]), axis=0)
        q1, med, q3 = np.percentile(err, [25, 50, 75], axis=0)
        ax.plot(t, med, color=cmap(i), label=algo)
        ax.fill_between(t, q1, q3, color=cmap(i), alpha=0.2)
    ax.axhline(POS_TOL_M, color="k", ls=":", lw=1, label=f"{POS_TOL_M} m")
    ax.set_yscale("log")
    ax.set_xlabel("time since start [s] (median over starts)")
    ax.set_ylabel("position error [m] (median, quartiles)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "errors.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4))
    rates = [100 * row["success_rate"] for row in ev.table]
    ax.bar(algos, rates, color=[cmap(i) for i in range(len(algos))])
    ax.set_ylim(0, 100)
    ax.set_ylabel("success [%]")
    ax.set_title(f"global localisation from {len(ev.windows)} starts")
    fig.tight_layout()
    fig.savefig(out_dir / "success.png", dpi=110)
    plt.close(fig)
