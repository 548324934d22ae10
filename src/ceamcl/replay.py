"""``ceamcl run``: replay a real log (CARMEN or ROS bag) through a filter from global
localisation.

Three steps (docs/real-data.md), each a function; in Python::

    prepared = prepare_log("intel-corrected.log.gz", seed=0)     # 1. open, decide the truth
    grid, source = obtain_map(prepared.log, None)                 # 2. a map file or the log's
    outcome = replay_log(prepared, grid, "ceamcl", map_source=source, out="run-out")  # 3.

1. open the log (:func:`ceamcl.io.logs.open_log`);
2. ground truth: where the log's poses are SLAM-corrected, they become the truth and the
   filter reads *synthetic* odometry drawn from them (:data:`DEFAULT_SYNTHETIC_NOISE`, the
   generator of child 0 of ``SeedSequence(seed)``); otherwise the recorded odometry is used
   and there is no truth;
3. the map: a ROS map file, or built from the log itself (:func:`ceamcl.mapping.map_from_log`);
   then the filter (from the registry, :func:`ceamcl.filters.registry.make_filter`) runs over
   the whole log (:func:`ceamcl.runner.run_filter`), and with ``out`` the run's files are
   written (:func:`ceamcl.outputs.write_run_files`).

Convergence in the summary is :func:`ceamcl.experiments.metrics.score_errors`, the measure
``ceamcl evaluate-log`` uses too, told in one sentence by
:func:`~ceamcl.experiments.metrics.convergence_verdict` (``verdict``); beside it the estimate's
jumps (:func:`~ceamcl.experiments.metrics.estimate_jumps`) and the filter's restarts
(:func:`~ceamcl.experiments.metrics.restarts`).
"""

from __future__ import annotations

import os
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ceamcl.experiments.metrics import (
    HEADING_TOL_RAD,
    JUMP_M,
    POSITION_TOL_M,
    convergence_verdict,
    estimate_jumps,
    restarts,
    score_errors,
)
from ceamcl.filters.registry import make_filter
from ceamcl.io.logs import DEFAULT_SYNTHETIC_NOISE, open_log, poses_look_corrected
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.results import ensure_output_dir
from ceamcl.io.timestamps import check_times
from ceamcl.mapping import MappingConfig, map_from_log
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.ros_io import load_map
from ceamcl.motion.odometry import OdometryNoise
from ceamcl.outputs import OutputOptions, write_run_files
from ceamcl.runner import RunResult, run_filter

TruthMode = Literal["auto", "yes", "no"]


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
        return load_map(map_path), f"map file {map_path}"
    grid, stats = map_from_log(log, MappingConfig(resolution_m=resolution_m))
    return grid, (
        f"built from the log itself ({stats.scans} scans, {resolution_m} m cells, "
        f"{stats.free_area_m2:.0f} m^2 free)"
    )


def filter_rng(seed: int, start: int, algorithm: str) -> np.random.Generator:
    """The filter's generator of run ``start`` with ``algorithm``: independent of the
    odometry's stream (child 0) and of every other run and algorithm."""
    key = (1, start, zlib.crc32(algorithm.encode()))
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


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

    ``outputs`` (:class:`ceamcl.outputs.OutputOptions`) adds ``run.gif``/``run.mp4``,
    ``report.html`` and an MCAP file (with the log's scans, and its truth where it has one);
    the particles are kept every ``outputs.stride`` steps only when one of them is asked for.
    ``on_frame(i, total)`` reports the animation's progress.
    """
    out_dir = ensure_output_dir(out) if out is not None else None
    log = prepared.log
    if on_start is not None:
        on_start(len(log))
    f = make_filter(algorithm, grid, filter_rng(prepared.seed, 0, algorithm))
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


ODOMETRY_SOURCES = {
    "synthetic": "synthetic, from the corrected poses",
    "recorded": "recorded in the log",
}


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
        "odometry_source": ODOMETRY_SOURCES[prepared.odometry],
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
        **restarts(result.diagnostics),
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
    jumps_from = 0
    if pos is not None and head is not None:
        score = score_errors(result.times, pos, head)
        inside = (pos <= POSITION_TOL_M) & (head <= HEADING_TOL_RAD)
        verdict = convergence_verdict(result.times, inside, float(pos[-1]))
        jumps_from = verdict.first_localised_scan or 0
        summary.update(
            {
                "verdict": verdict.text,
                "convergence": verdict.status,
                "first_localised_scan": verdict.first_localised_scan,
                "first_localised_s": verdict.first_localised_s,
                "scans_inside_tolerance": verdict.scans_inside,
                "final_stretch_scans": verdict.final_stretch,
                "final_position_error_m": float(pos[-1]),
                "final_heading_error_rad": float(head[-1]),
                "converged": score.success,
                "scans_to_converge": score.scans_to_converge,
                "time_to_converge_s": score.time_to_converge_s,
                "position_rmse_after_convergence_m": score.position_rmse_m,
                "heading_rmse_after_convergence_rad": score.heading_rmse_rad,
            }
        )
    jumps = estimate_jumps(result.estimates, log.odometry, jumps_from)
    summary.update(
        {
            "jumps_from_scan": jumps.from_scan,
            "largest_jump_m": jumps.largest_m,
            "largest_jump_scan": jumps.largest_at_scan,
            "jump_threshold_m": JUMP_M,
            "jumps_over_threshold": jumps.over_threshold,
        }
    )
    return summary
