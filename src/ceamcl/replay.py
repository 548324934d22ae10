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

import math
import os
import warnings
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ceamcl.errors import ConfigError, InputWarning
from ceamcl.experiments.metrics import (
    HEADING_TOL_RAD,
    JUMP_M,
    POSITION_TOL_M,
    convergence_verdict,
    estimate_jumps,
    final_error,
    restarts,
    score_errors,
)
from ceamcl.filters.base import LocalisationFilter
from ceamcl.filters.policies import Policy, on_motion
from ceamcl.filters.registry import (
    DEFAULT_SENSOR,
    check_sensor,
    get,
    make_filter,
    sensor_of,
)
from ceamcl.filters.state import summarise_states
from ceamcl.io.logs import DEFAULT_SYNTHETIC_NOISE, open_log, poses_look_corrected
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.results import ensure_output_dir
from ceamcl.io.timestamps import check_times
from ceamcl.io.truth import TruthPairing, pair_truth
from ceamcl.io.truth_check import TruthDoubt, doubtful_truth
from ceamcl.mapping import MappingConfig, map_from_log
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.ros_io import load_map
from ceamcl.motion.odometry import STRIDE_M, STRIDE_RAD, OdometryNoise
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
    truth_log: RecordedLog | None = None
    pairing: TruthPairing | None = None

    @property
    def map_log(self) -> RecordedLog:
        """The log a map is built from: the corrected log that gives the truth, when there is
        one (a raw log's odometry drifts by tens of metres), else the log itself."""
        return self.truth_log if self.truth_log is not None else self.log


def prepare_log(
    path: str | os.PathLike[str],
    *,
    seed: int = 0,
    truth: TruthMode = "auto",
    noise: OdometryNoise = DEFAULT_SYNTHETIC_NOISE,
    repair_times: bool = False,
    truth_from: str | os.PathLike[str] | None = None,
    laser_mount: tuple[float, float, float] | None = None,
    **open_kwargs: Any,
) -> PreparedLog:
    """Open a log and decide ground truth and odometry (module docstring, steps 1-2).

    ``truth="auto"`` takes the poses as ground truth when the log's content shows a corrected
    log (:func:`ceamcl.io.logs.poses_look_corrected`); ``truth_reason`` says what was decided
    and why. Scan times are checked (:func:`ceamcl.io.timestamps.check_times`), and repaired
    with ``repair_times``. ``laser_mount``: the laser's pose on the robot ``(x, y, yaw)`` at
    every scan, in place of the log's (``--laser-mount``; with ``truth_from`` the truth is the
    robot's under that mount, :mod:`ceamcl.io.truth`).
    """
    log = check_times(open_log(path, **open_kwargs), repair=repair_times)
    # whether the poses are corrected is read from the log as written: a mount the user gives
    # (a laser pose apart from the robot's) must not make a corrected log look raw, which
    # would hand its true poses to the filter as odometry
    looks, why = poses_look_corrected(log)
    if laser_mount is not None:
        log = with_laser_mount(log, laser_mount)
    if truth_from is not None:
        return _truth_from(log, truth_from, seed, repair_times, open_kwargs)
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


def with_laser_mount(log: RecordedLog, mount: tuple[float, float, float]) -> RecordedLog:
    """``log`` with the laser at ``mount`` (``x, y, yaw`` on the robot) at every scan."""
    m = np.asarray(mount, dtype=np.float64)
    if m.shape != (3,) or not np.all(np.isfinite(m)):
        raise ConfigError(f"laser mount: expected three finite numbers x, y, yaw, got {mount!r}")
    return replace(log, laser_mount=np.tile(m, (len(log), 1)))


def _truth_from(
    log: RecordedLog,
    truth_path: str | os.PathLike[str],
    seed: int,
    repair_times: bool,
    open_kwargs: dict[str, Any],
) -> PreparedLog:
    """``log`` with its own odometry and every scan, its truth the poses of the corrected log
    ``truth_path`` at the scans the two share (:func:`ceamcl.io.truth.pair_truth`)."""
    truth_log = check_times(open_log(truth_path, **open_kwargs), repair=repair_times)
    looks, why = poses_look_corrected(truth_log)
    pairing = pair_truth(log, truth_log)
    reason = f"from {truth_path} (--truth-from): {pairing.summary()}"
    if not looks:
        # The user named this log as the truth: a corrected log written by another SLAM tool
        # may carry no NEFF messages, or a laser pose apart from the robot pose. Say so, and
        # take its poses as asked (a raw log passed by mistake still pairs, and the warning
        # names it).
        doubt = (
            f"truth-from: {truth_path} does not look SLAM-corrected ({why}); its poses are "
            "taken as the truth, as --truth-from asks"
        )
        warnings.warn(InputWarning(doubt), stacklevel=2)
        reason = f"{reason} (warning: {doubt})"
    paired = replace(log, true_poses=pairing.truth_at_raw_scans())
    return PreparedLog(paired, True, "recorded", None, seed, reason, truth_log, pairing)


def obtain_map(
    log: RecordedLog,
    map_path: str | os.PathLike[str] | None,
    resolution_m: float = 0.05,
    *,
    own: bool = True,
) -> tuple[OccupancyGrid, str]:
    """The map file, or the map built from ``log``'s poses; and a sentence saying which
    (``own=False``: ``log`` is not the replayed log but the corrected log giving its truth)."""
    if map_path is not None:
        return load_map(map_path), f"map file {map_path}"
    grid, stats = map_from_log(log, MappingConfig(resolution_m=resolution_m))
    whose = "the log itself" if own else f"the corrected log {log.path}"
    return grid, (
        f"built from {whose} ({stats.scans} scans, {resolution_m} m cells, "
        f"{stats.free_area_m2:.0f} m^2 free)"
    )


#: The verdict of a run on a log without ground truth.
NOT_SCORED = "not scored: the log has no ground truth (see restarts and jumps)"

#: Nav2 amcl's defaults: update once the robot has moved 0.25 m or turned 0.2 rad (one stride
#: of the pace its motion noise was set for, :data:`ceamcl.motion.odometry.STRIDE_M`).
DEFAULT_UPDATE_MIN_D = STRIDE_M
DEFAULT_UPDATE_MIN_A = STRIDE_RAD
#: The config fields of an algorithm that holds its own update thresholds (amcl's, KLD-AMCL
#: and its presets): under a shared pace they are set to 0 so that the runner alone decides,
#: for every algorithm alike.
_OWN_THRESHOLDS = ("update_min_d", "update_min_a")


def _holds_thresholds(algorithm: str) -> bool:
    """Whether ``algorithm``'s config has update thresholds of its own (by its fields, so a
    preset of such a filter, ``kld-amcl-tuned``, counts too)."""
    config_type = get(algorithm).config_type
    names = {f.name for f in fields(config_type)} if is_dataclass(config_type) else set()
    return all(name in names for name in _OWN_THRESHOLDS)


@dataclass(frozen=True)
class UpdatePace:
    """Update at a real robot's pace (Nav2's ``update_min_d`` / ``update_min_a``): the filter
    is stepped once the odometry has moved ``min_d`` metres along x or y or turned ``min_a``
    radians since the last update, with the whole increment (:func:`ceamcl.runner.run_filter`).
    Every algorithm of a run or comparison gets the same pace; KLD-AMCL's own thresholds are set
    to 0 under it (:func:`make_paced_filter`), so it updates exactly when the others do."""

    min_d: float = DEFAULT_UPDATE_MIN_D
    min_a: float = DEFAULT_UPDATE_MIN_A

    def __post_init__(self) -> None:
        for name, v in (("update-min-d", self.min_d), ("update-min-a", self.min_a)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ConfigError(f"{name}: expected a non-negative number, got {v}")

    def policy(self) -> Policy:
        return on_motion(self.min_d, self.min_a)

    def describe(self) -> str:
        return f"update when moved {self.min_d:g} m or turned {self.min_a:g} rad"


def check_pace(min_d: float | None, min_a: float | None, *, every_scan: bool) -> None:
    """Refuse thresholds together with ``every_scan`` (which updates at every scan); callable
    before a log is read (``ceamcl run`` and ``evaluate-log`` check their options with it)."""
    if every_scan and (min_d is not None or min_a is not None):
        raise ConfigError("update-min-d/-a: not with --every-scan, which updates at every scan")


def choose_pace(
    prepared: PreparedLog,
    min_d: float | None = None,
    min_a: float | None = None,
    *,
    every_scan: bool = False,
) -> UpdatePace | None:
    """The update pace of a replay: none with ``every_scan``; else Nav2's thresholds (or those
    given) on a log with the robot's own odometry (raw logs, bags), and on any log where a
    threshold is given. A corrected log with synthetic odometry is a sparse subset of key scans
    already (one every 0.1-1 m): it steps at every scan unless a threshold is given."""
    check_pace(min_d, min_a, every_scan=every_scan)
    if every_scan:
        return None
    if min_d is None and min_a is None and prepared.odometry != "recorded":
        return None
    return UpdatePace(
        DEFAULT_UPDATE_MIN_D if min_d is None else min_d,
        DEFAULT_UPDATE_MIN_A if min_a is None else min_a,
    )


def make_paced_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    **kwargs: Any,
) -> LocalisationFilter:
    """:func:`ceamcl.filters.registry.make_filter` for a replay, where the runner decides when
    every algorithm updates (under a pace, or at every scan): an algorithm with update
    thresholds of its own (KLD-AMCL and its presets) gets them at 0, in its default config or
    in the one given. Until 2026-11-29 only under a pace and without a config given, so at
    "every scan" (``--every-scan``, a corrected log's key scans) the KLD-AMCL variants still
    skipped the scans their own 0.25 m / 0.2 rad did not reach."""
    if _holds_thresholds(algorithm):
        config = kwargs.get("config") or get(algorithm).default()
        kwargs["config"] = replace(config, **dict.fromkeys(_OWN_THRESHOLDS, 0.0))
    return make_filter(algorithm, grid, rng, **kwargs)


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
    pace: UpdatePace | None = None,
    truth_doubt: TruthDoubt | None = None,
    sensor: str = DEFAULT_SENSOR,
) -> ReplayOutcome:
    """Global localisation over the whole log; with ``out``, the files of ``ceamcl run``.

    ``outputs`` (:class:`ceamcl.outputs.OutputOptions`) adds ``run.gif``/``run.mp4``,
    ``report.html`` and an MCAP file (with the log's scans, and its truth where it has one);
    the particles are kept every ``outputs.stride`` steps only when one of them is asked for.
    ``on_frame(i, total)`` reports the animation's progress. ``sensor`` names the sensor
    model (:data:`ceamcl.filters.registry.SENSOR_MODELS`; the Nav2 peer keeps the wheel's).
    """
    check_sensor(sensor)
    out_dir = ensure_output_dir(out) if out is not None else None
    log = prepared.log
    if on_start is not None:
        on_start(len(log))
    f = make_paced_filter(algorithm, grid, filter_rng(prepared.seed, 0, algorithm), sensor=sensor)
    snapshot_every = outputs.snapshot_every if outputs is not None else 0
    result = run_filter(
        f,
        log,
        on_step=on_step,
        snapshot_every=snapshot_every,
        update_when=None if pace is None else pace.policy(),
    )
    summary = run_summary(result, prepared, grid, map_source, pace, truth_doubt, sensor)
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


def truth_source(prepared: PreparedLog) -> str | None:
    """Where the run's ground truth comes from, in words (``None``: no truth)."""
    if prepared.pairing is not None:
        p = prepared.pairing
        x, y, yaw = (float(v) for v in prepared.log.laser_mount[0])
        return (
            f"the SLAM-corrected poses of {p.truth_path} at the {p.n_matched} of "
            f"{p.n_raw} scans that match, for a robot whose laser sits at ({x:.3f}, {y:.3f}) m, "
            f"{yaw:.3f} rad{p.mount_suggestion()}"
        )
    return "the log's poses (SLAM-corrected)" if prepared.has_truth else None


ODOMETRY_SOURCES = {
    "synthetic": "synthetic, from the corrected poses",
    "recorded": "recorded in the log",
}


def run_summary(
    result: RunResult,
    prepared: PreparedLog,
    grid: OccupancyGrid,
    map_source: str,
    pace: UpdatePace | None = None,
    truth_doubt: TruthDoubt | None = None,
    sensor: str = DEFAULT_SENSOR,
) -> dict[str, Any]:
    """The fields of ``summary.json`` of ``ceamcl run``; ``truth_doubt``: the truth check of
    the log on ``grid`` when the caller has it (else it is made here); ``sensor``: the sensor
    model the filter was given (``summary.json`` names the one it weighed with,
    :func:`~ceamcl.filters.registry.sensor_of`)."""
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
        "ground_truth": truth_source(prepared),
        "ground_truth_decision": prepared.truth_reason,
        "odometry": prepared.odometry,
        "odometry_source": ODOMETRY_SOURCES[prepared.odometry],
        "repaired_times": int(log.info.get("repaired_times", 0)),
        "odometry_sign": log.info.get("odometry_sign", "as recorded"),
        # set when the laser's no-return value was read from its readings (ACES: 50 m)
        "max_range_from": log.info.get("max_range_from", "the log or --max-range"),
        "map": map_source,
        "map_size_m": list(grid.size_m),
        "map_free_area_m2": grid.free_area_m2,
        "initialisation_ms": float(result.diagnostics[0].step_ms),
        "mean_step_ms": float(step_ms.mean()),
        "median_step_ms": float(np.median(step_ms)),
        "updates": result.updates,
        "update_policy": "every scan" if pace is None else pace.describe(),
        "sensor": sensor_of(result.algorithm, sensor),
        "median_update_ms": float(np.median(result.update_ms)),
        "particles_initial": int(result.diagnostics[0].n_particles),
        "particles_final": int(result.diagnostics[-1].n_particles),
        "mean_particles": float(np.mean([d.n_particles for d in result.diagnostics])),
        **restarts(result.diagnostics),
        **summarise_states(result.states, result.times),
    }
    if prepared.has_truth:
        doubt = truth_doubt or doubtful_truth(prepared.log, grid)
        summary["truth_fit"] = {
            "median_share": None if math.isnan(doubt.median) else doubt.median,
            "doubtful_scans": [list(s) for s in doubt.stretches],
            "note": doubt.summary(),
        }
    if prepared.pairing is not None:
        p = prepared.pairing
        summary["truth_pairing"] = {
            "truth_log": p.truth_path,
            "matched_scans": p.n_matched,
            "truth_scans": p.n_truth,
            "raw_scans": p.n_raw,
            "clock_offset_s": p.clock_offset_s,
            "max_time_residual_s": p.max_time_residual_s,
            # False: the timestamps could not check the pairs (ranges and order alone)
            "times_used": p.times_used,
            # the truth is the raw robot's pose: moved where the two logs' laser mounts differ
            "mount_moved_pairs": p.mount_moved,
            "mount_shift_m": p.mount_shift_m,
            # the laser's (x, y) on the robot the corrected poses and the odometry agree on
            "laser_mount_used": [float(v) for v in prepared.log.laser_mount[0]],
            "laser_mount_suggested": None if p.suggested_mount is None else [*p.suggested_mount],
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
        # Scored at the scans with a truth (all of them, or a raw log's matched scans).
        known = np.flatnonzero(np.isfinite(pos) & np.isfinite(head))
        inside = (pos[known] <= POSITION_TOL_M) & (head[known] <= HEADING_TOL_RAD)
        partial = known.size < pos.size
        verdict = convergence_verdict(
            result.times, inside, final_error(pos), scan_ids=known if partial else None
        )
        jumps_from = verdict.first_localised_scan or 0
        summary.update(
            {
                "verdict": verdict.text,
                "convergence": verdict.status,
                "first_localised_scan": verdict.first_localised_scan,
                "first_localised_s": verdict.first_localised_s,
                "scans_inside_tolerance": verdict.scans_inside,
                "final_stretch_scans": verdict.final_stretch,
                "final_position_error_m": final_error(pos),
                "final_heading_error_rad": final_error(head),
                "converged": score.success,
                "scans_to_converge": score.scans_to_converge,
                "time_to_converge_s": score.time_to_converge_s,
                "position_rmse_after_convergence_m": score.position_rmse_m,
                "heading_rmse_after_convergence_rad": score.heading_rmse_rad,
            }
        )
    else:  # the console's verdict, in the file too (docs/real-data.md lists it)
        summary.update({"verdict": NOT_SCORED, "convergence": "not scored"})
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
