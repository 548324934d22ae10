"""``ceamcl evaluate-log LOG --tracking``: pose tracking over a whole real log, the benchmark
Nav2 and Beluga users know, scored by the absolute pose error (APE) as ``evo_ape`` computes it.

Every algorithm starts from the same perturbed pose: the true pose at the first scan with
truth, moved :data:`START_OFFSET_M` (0.5 m) in a seeded random direction and turned
:data:`START_TURN_RAD` (0.3 rad) to a seeded random side, with the covariance
``diag(0.5^2, 0.5^2, 0.3^2)``. Each algorithm then runs over the rest of the log with the same
particle budget (``particles``: the sample size of MCL and GMCL, ``max_particles`` of KLD-AMCL
and Nav2 AMCL, the tracking species' size and the cap on the total of CEAMCL) and the same
update pace. The APE is the position error of the estimate at the scans with truth (no
alignment: the map frame is the truth's frame): its RMSE, median and maximum; the heading RMSE
beside it; and the RMSE over the scans outside the stretches where the truth is doubtful
(:mod:`ceamcl.io.truth_check`: the truth does not explain its own scans on the map), beside the
RMSE over every scan, never instead of it.

Files: ``tracking.csv`` and ``tracking.md`` (one row per algorithm), ``groundtruth.tum`` and
``tracking-<algorithm>.tum`` at the scans with truth (``evo_ape tum groundtruth.tum
tracking-mcl.tum`` reads them), ``ape.png`` (position error along the log, the doubtful
stretches shaded).
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
from ceamcl.experiments.common import fmt, pct, write_csv, write_text
from ceamcl.experiments.executors import Batch, filter_bytes
from ceamcl.filters.base import LocalisationFilter
from ceamcl.filters.registry import (
    DEFAULT_SENSOR,
    check_sensor,
    describe_sensor,
    get,
    particles_cell,
    with_config,
)
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.results import ensure_output_dir
from ceamcl.io.truth_check import TruthDoubt, doubtful_truth
from ceamcl.io.tum import write_tum
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.pose import heading_error, inside_ellipse, position_error
from ceamcl.replay import PreparedLog, UpdatePace, filter_rng, make_paced_filter, truth_source
from ceamcl.runner import run_filter

START_OFFSET_M = 0.5
START_TURN_RAD = 0.3
#: Default particle budget of tracking: Nav2 amcl's ``max_particles``.
DEFAULT_TRACKING_PARTICLES = 2000


def perturbed_start(truth: NDArray[np.float64], seed: int) -> NDArray[np.float64]:
    """The true pose moved 0.5 m in a random direction and turned 0.3 rad to a random side
    (generator ``SeedSequence(seed, spawn_key=(2,))``, independent of the filters')."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(2,)))
    phi = rng.uniform(-math.pi, math.pi)
    side = 1.0 if rng.random() < 0.5 else -1.0
    x, y, th = (float(v) for v in truth)
    turned = math.remainder(th + side * START_TURN_RAD, 2.0 * math.pi)
    return np.array(
        [x + START_OFFSET_M * math.cos(phi), y + START_OFFSET_M * math.sin(phi), turned]
    )


def start_covariance() -> NDArray[np.float64]:
    return np.diag([START_OFFSET_M**2, START_OFFSET_M**2, START_TURN_RAD**2])


def tracking_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    particles: int,
    sensor: str = DEFAULT_SENSOR,
) -> LocalisationFilter:
    """The filter with the particle budget ``particles``: through the registry's budget where
    the algorithm has one; for CEAMCL as the size of its tracking species and the cap on its
    total sample size (``max_samples``), as ``max_particles`` caps Nav2's, so that no
    recovery's new species take it past the budget; ``sensor`` names the sensor model (the
    Nav2 peer keeps the wheel's beam model)."""
    if get(algorithm).with_particles is not None:
        return make_paced_filter(algorithm, grid, rng, n_particles=particles, sensor=sensor)
    if algorithm == "ceamcl":
        cfg = with_config("ceamcl", tracking_samples=particles, max_samples=particles)
        return make_paced_filter(algorithm, grid, rng, config=cfg, sensor=sensor)
    raise ConfigError(f"tracking: {algorithm} has no particle budget to set")


@dataclass(frozen=True, eq=False)
class TrackingTrial:
    algorithm: str
    grid: OccupancyGrid
    log: RecordedLog
    start: NDArray[np.float64]
    particles: int
    seed: int
    pace: UpdatePace | None = None
    #: scans of ``log`` where the truth is doubtful (:func:`doubtful_truth`); ``None``: none
    doubtful: NDArray[np.bool_] | None = None
    sensor: str = DEFAULT_SENSOR


@dataclass(frozen=True)
class TrackingResult:
    algorithm: str
    scans: int
    scored_scans: int
    updates: int
    ape_rmse_m: float
    ape_median_m: float
    ape_max_m: float
    #: the APE RMSE over the scored scans outside the doubtful stretches (NaN: none left)
    ape_rmse_outside_doubtful_m: float
    heading_rmse_rad: float
    within_2sigma: float  # share of scored scans with the truth inside the 2-sigma ellipse
    mean_particles: float
    median_update_ms: float
    times: NDArray[np.float64] = field(repr=False)
    estimates: NDArray[np.float64] = field(repr=False)
    truth: NDArray[np.float64] = field(repr=False)

    @property
    def position_errors(self) -> NDArray[np.float64]:
        return position_error(self.estimates, self.truth)


def run_tracking_trial(trial: TrackingTrial) -> TrackingResult:
    """One algorithm over the whole log from the perturbed start (a top-level function, so any
    executor can run it)."""
    rng = filter_rng(trial.seed, 0, trial.algorithm)
    f = tracking_filter(trial.algorithm, trial.grid, rng, trial.particles, trial.sensor)
    result = run_filter(
        f,
        trial.log,
        update_when=None if trial.pace is None else trial.pace.policy(),
        initial_pose=(trial.start, start_covariance()),
    )
    known = result.truth_known
    if result.truth is None or not known.any():
        raise ConfigError(f"tracking {trial.algorithm}: the log has no scan with ground truth")
    est, truth = result.estimates[known], result.truth[known]
    pos, head = position_error(est, truth), heading_error(est, truth)
    sound = ~trial.doubtful[known] if trial.doubtful is not None else np.ones(pos.size, bool)
    return TrackingResult(
        algorithm=trial.algorithm,
        scans=result.steps,
        scored_scans=int(known.sum()),
        updates=result.updates,
        ape_rmse_m=float(np.sqrt(np.mean(pos**2))),
        ape_median_m=float(np.median(pos)),
        ape_max_m=float(np.max(pos)),
        ape_rmse_outside_doubtful_m=(
            float(np.sqrt(np.mean(pos[sound] ** 2))) if sound.any() else math.nan
        ),
        heading_rmse_rad=float(np.sqrt(np.mean(head**2))),
        within_2sigma=_within_2sigma(result.covariances, known, est, truth),
        mean_particles=float(np.mean([d.n_particles for d in result.diagnostics])),
        median_update_ms=float(np.median(result.update_ms)),
        times=result.times[known],
        estimates=est,
        truth=truth,
    )


def _within_2sigma(
    covariances: NDArray[np.float64] | None,
    known: NDArray[np.bool_],
    estimates: NDArray[np.float64],
    truth: NDArray[np.float64],
) -> float:
    """Calibration: the share of scored scans whose true position lies inside the 2-sigma
    ellipse of the estimate's covariance (86.5 % for a calibrated Gaussian)."""
    if covariances is None:
        return math.nan
    return float(np.mean(inside_ellipse(estimates, covariances[known], truth)))


@dataclass
class Tracking:
    results: list[TrackingResult]
    start: NDArray[np.float64]
    first_scan: int
    particles: int
    update_policy: str
    map_source: str
    skipped: dict[str, str]
    out_dir: Path | None
    #: ``(first scan, last scan, lowest share)`` where the truth is doubtful (log's indices)
    doubtful: tuple[tuple[int, int, float], ...] = ()
    sensor: str = DEFAULT_SENSOR


def track_log(
    prepared: PreparedLog,
    grid: OccupancyGrid,
    algorithms: Sequence[str],
    *,
    particles: int = DEFAULT_TRACKING_PARTICLES,
    pace: UpdatePace | None = None,
    map_source: str = "",
    batch: Batch | None = None,
    out: str | os.PathLike[str] | None = None,
    skipped: dict[str, str] | None = None,
    truth_doubt: TruthDoubt | None = None,
    sensor: str = DEFAULT_SENSOR,
) -> Tracking:
    """Pose tracking over the whole log with each algorithm (module docstring); the trials run
    as ``batch`` says (default: local processes, no progress). ``truth_doubt``: the truth
    check for ``tracking.md`` when the caller has it (else it is made here). ``sensor``: the
    sensor model of every core algorithm (the Nav2 peer keeps the wheel's beam model)."""
    check_sensor(sensor)
    log = prepared.log
    known = log.has_truth_at
    if not prepared.has_truth or not known.any():
        raise ConfigError(
            f"{log.path}: no ground truth to start from and score against; tracking needs a "
            "corrected log or --truth-from CORRECTED"
        )
    if particles < 1:
        raise ConfigError(f"particles: expected a positive count, got {particles}")
    first = int(np.flatnonzero(known)[0])
    window = log.window(first, len(log))
    assert window.true_poses is not None
    start = perturbed_start(window.true_poses[0], prepared.seed)
    out_dir = ensure_output_dir(out) if out is not None else None
    doubt = truth_doubt or doubtful_truth(prepared.log, grid)
    doubtful = doubt.mask(len(log))[first:]
    trials = [
        TrackingTrial(a, grid, window, start, particles, prepared.seed, pace, doubtful, sensor)
        for a in algorithms
    ]
    results = (batch or Batch()).run(
        run_tracking_trial, trials, f"track {log.name}", filter_bytes(grid)
    )
    tracking = Tracking(
        results,
        start,
        first,
        particles,
        "every scan" if pace is None else pace.describe(),
        map_source,
        dict(skipped or {}),
        out_dir,
        doubt.stretches,
        sensor,
    )
    if out_dir is not None:
        write_tracking(tracking, prepared, out_dir, doubt.summary())
    return tracking


_ROW_FIELDS = (
    "algorithm",
    "scans",
    "scored_scans",
    "updates",
    "ape_rmse_m",
    "ape_median_m",
    "ape_max_m",
    "ape_rmse_outside_doubtful_m",
    "heading_rmse_rad",
    "within_2sigma",
    "mean_particles",
    "median_update_ms",
)


def tracking_rows(tracking: Tracking) -> list[dict[str, Any]]:
    return [{k: getattr(r, k) for k in _ROW_FIELDS} for r in tracking.results]


def tracking_markdown(
    tracking: Tracking, prepared: PreparedLog, truth_note: str | None = None
) -> str:
    log = prepared.log
    x, y, th = tracking.start
    lines = [
        f"# Pose tracking on {log.name}",
        "",
        f"- log: `{log.path}` ({len(log)} scans, {log.duration_s:.0f} s, "
        f"{log.path_length_m:.0f} m of travel)",
        f"- map: {tracking.map_source}",
        f"- ground truth: {truth_source(prepared)}",
        *([f"- {truth_note}"] if truth_note else []),
        f"- odometry: {prepared.odometry}",
        f"- start: scan {tracking.first_scan}, the true pose moved {START_OFFSET_M} m and turned "
        f"{START_TURN_RAD} rad: ({x:.3f}, {y:.3f}, {th:.3f}), seed {prepared.seed}",
        f"- particle budget: {tracking.particles} for every algorithm",
        f"- filter updates (every algorithm): {tracking.update_policy}",
        f"- sensor model: {describe_sensor(tracking.sensor)}",
        "- APE: position error of the estimate at the scans with truth, no alignment; "
        '"outside doubtful truth": the RMSE without the stretches where the truth does not '
        "explain its own scans on the map (the stretches the ground-truth line names; with "
        "none, the same as over every scan)",
        "- within 2 sigma: share of scored scans whose true position lies inside the 2-sigma "
        "ellipse of the estimate's covariance (86.5 % if the covariance is calibrated; much "
        "lower: overconfident)",
        "",
        "| algorithm | scans | scored | updates | APE RMSE [m] | APE median [m] | APE max [m] | "
        "APE RMSE outside doubtful truth [m] | heading RMSE [rad] | within 2 sigma | "
        "mean particles | median update [ms] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in tracking.results:
        lines.append(
            f"| {r.algorithm} | {r.scans} | {r.scored_scans} | {r.updates} | "
            f"{fmt(r.ape_rmse_m, 3)} | {fmt(r.ape_median_m, 3)} | {fmt(r.ape_max_m, 3)} | "
            f"{fmt(r.ape_rmse_outside_doubtful_m, 3)} | {fmt(r.heading_rmse_rad, 3)} | "
            f"{pct(r.within_2sigma)} | "
            f"{particles_cell(r.algorithm, fmt(r.mean_particles, 0))} | "
            f"{fmt(r.median_update_ms, 1)} |"
        )
    for algo, why in tracking.skipped.items():
        lines.append(f"\n{algo} skipped: {why}")
    return "\n".join(lines) + "\n"


def write_tracking(
    tracking: Tracking, prepared: PreparedLog, out_dir: Path, truth_note: str | None = None
) -> None:
    """``tracking.csv``, ``tracking.md`` (with ``truth_note``, how well the truth explains its
    scans on the map), the TUM files and ``ape.png``; an earlier run's ``tracking-*.tum`` of
    algorithms this run does not have are removed."""
    import matplotlib.pyplot as plt  # lazy: the CLI imports this module to build its parser

    write_csv(out_dir / "tracking.csv", tracking_rows(tracking))
    write_text(out_dir / "tracking.md", tracking_markdown(tracking, prepared, truth_note))
    if tracking.results:
        first = tracking.results[0]
        write_tum(out_dir / "groundtruth.tum", first.times, first.truth)
    fig, ax = plt.subplots(figsize=(9, 4.5))
    if tracking.results and tracking.doubtful:
        t = prepared.log.times
        t0 = tracking.results[0].times[0]
        for i, (a, b, _) in enumerate(tracking.doubtful):
            label = "truth doubtful (truth check)" if i == 0 else None
            ax.axvspan(t[a] - t0, t[b] - t0, color="0.85", zorder=0, label=label)
    tums = {f"tracking-{r.algorithm}.tum" for r in tracking.results}
    for r in tracking.results:
        write_tum(out_dir / f"tracking-{r.algorithm}.tum", r.times, r.estimates)
        ax.plot(r.times - r.times[0], r.position_errors, lw=1, label=r.algorithm)
    # an earlier run's trajectories of other algorithms (another seed, log or pace) would pass
    # for this run's beside its groundtruth.tum (evo_ape compares them without a word)
    for old in out_dir.glob("tracking-*.tum"):
        if old.name not in tums and (old.is_file() or old.is_symlink()):
            old.unlink()
    ax.set_yscale("log")
    ax.set_xlabel("time since the start [s]")
    ax.set_ylabel("position error (APE) [m]")
    ax.set_title(f"pose tracking on {prepared.log.name}, {tracking.particles} particles")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "ape.png", dpi=110)
    plt.close(fig)


__all__ = [
    "DEFAULT_TRACKING_PARTICLES",
    "Tracking",
    "TrackingResult",
    "TrackingTrial",
    "perturbed_start",
    "run_tracking_trial",
    "track_log",
    "tracking_filter",
]
