"""The files of ``ceamcl evaluate-log``: ``evaluate.csv`` (per run), ``evaluate.md`` (per
algorithm), ``errors.png`` and ``success.png``."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ceamcl.experiments.common import fmt, write_csv, write_text
from ceamcl.experiments.metrics import HEADING_TOL_RAD, HOLD_STEPS, POSITION_TOL_M
from ceamcl.filters.registry import (
    describe_sensor,
    global_cell,
    global_cells,
    global_notes,
    localises_globally,
    particles_cell,
)
from ceamcl.replay import truth_source

if TYPE_CHECKING:
    from ceamcl.experiments.evaluate_log import Evaluation
    from ceamcl.replay import PreparedLog

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
    "distance_to_converge_m",
    "position_rmse_m",
    "position_rmse_from_first_m",
    "confidently_wrong",
    "heading_rmse_rad",
    "final_position_error_m",
    "final_heading_error_rad",
    "mean_particles",
    "mean_step_ms",
    "median_step_ms",
    "initialisation_ms",
    "updates",
    "mean_update_ms",
    "median_update_ms",
    "likelihood_evaluations",
)
#: The columns of ``evaluate.md`` that measure global localisation (the rest: its cost).
_GLOBAL = frozenset(
    {
        "time_to_converge_s",
        "scans_to_converge",
        "distance_to_converge_m",
        "position_rmse_m",
        "position_rmse_from_first_m",
        "heading_rmse_rad",
    }
)


def write_evaluation(
    ev: Evaluation,
    prepared: PreparedLog,
    out_dir: Path,
    *,
    hold: int = HOLD_STEPS,
    hold_m: float | None = None,
    truth_note: str | None = None,
) -> None:
    """``evaluate.csv`` (per run), ``evaluate.md`` (per algorithm, with ``truth_note``, how
    well the truth explains its scans on the map) and two figures."""
    # matplotlib (~0.4 s) only when figures are drawn, as in the other experiments' writers:
    # `ceamcl --help` imports this module.
    from ceamcl.experiments.figures import plot_evaluation

    rows = [
        {
            **{k: getattr(r, k) for k in _CSV_FIELDS},
            # False: the success columns measure a start that is not a global localisation
            "localises_globally": localises_globally(r.algorithm),
            "seed": prepared.seed,  # the run's generators: filter_rng(seed, start, algorithm)
        }
        for r in ev.results
    ]
    write_csv(out_dir / "evaluate.csv", rows)
    write_text(
        out_dir / "evaluate.md",
        evaluation_markdown(ev, prepared, hold=hold, hold_m=hold_m, truth_note=truth_note),
    )
    plot_evaluation(ev, out_dir)


def evaluation_markdown(
    ev: Evaluation,
    prepared: PreparedLog,
    *,
    hold: int = HOLD_STEPS,
    hold_m: float | None = None,
    truth_note: str | None = None,
) -> str:
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
        f"- ground truth: {truth_source(prepared)}",
        *([f"- {truth_note}"] if truth_note else []),
        f"- seed: {prepared.seed} (the filters' generators, and the synthetic odometry's)",
        f"- filter updates (every algorithm): {ev.update_policy}",
        f"- sensor model: {describe_sensor(ev.sensor)}",
        f"- {len(ev.windows)} start points, windows of {ev.window} "
        f"({min(lengths)}-{max(lengths)} scans)",
        f"- success: within {POSITION_TOL_M} m and {HEADING_TOL_RAD} rad from a step on to the "
        f"end of the window, for at least "
        + (f"{hold} steps" if hold_m is None else f"{hold_m:g} m of travel")
        + "; times, distances and RMSEs over successful runs; RMSE from first: from the first "
        "scan inside the tolerances to the end, excursions included (runs ever inside); "
        "confidently wrong: runs ending with >= 90 % of the weight on one wrong hypothesis; "
        "likelihood evaluations: poses scored against a scan, the global initialisation "
        "included (- where the filter does not count them)",
        f"- windows: {ev.window}",
        "",
        "| algorithm | runs | success | confidently wrong | time to converge [s] | "
        "scans to converge | distance to converge [m] | position RMSE [m] | "
        "RMSE from first [m] | heading RMSE [rad] | mean particles | mean step [ms] | "
        "median step [ms] | "
        "initialisation [ms] | updates per run | mean update [ms] | median update [ms] | "
        "likelihood evaluations per run |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    digits = {
        "time_to_converge_s": 1,
        "scans_to_converge": 1,
        "distance_to_converge_m": 1,
        "position_rmse_m": 3,
        "position_rmse_from_first_m": 3,
        "heading_rmse_rad": 3,
        "mean_particles": 0,
        "mean_step_ms": 1,
        "median_step_ms": 1,
        "initialisation_ms": 0,
        "updates_per_run": 0,
        "mean_update_ms": 1,
        "median_update_ms": 1,
        "likelihood_evaluations": 0,
    }
    for row in ev.table:
        algo = row["algorithm"]
        cells = [
            global_cell(algo, fmt(row[key], d, "-"), "-")
            if key in _GLOBAL
            else particles_cell(algo, fmt(row[key], d, "-"))
            if key == "mean_particles"
            else fmt(row[key], d, "-")
            for key, d in digits.items()
        ]
        success, wrong = global_cells(
            algo, (f"{100 * row['success_rate']:.0f}%", str(row["confidently_wrong"]))
        )
        lines.append(
            f"| {algo} | {row['runs']} | {success} | {wrong} | " + " | ".join(cells) + " |"
        )
    lines.extend(_paired_lines(ev.paired))
    for note in global_notes(row["algorithm"] for row in ev.table):
        lines.append(f"\n{note} (its measured figures are in `evaluate.csv`)")
    for algo, why in ev.skipped.items():
        lines.append(f"\n{algo} skipped: {why}")
    return "\n".join(lines) + "\n"


def _paired_lines(paired: list[dict[str, Any]]) -> list[str]:
    """The section of ``evaluate.md`` that compares likelihood evaluations at equal success
    (:func:`~ceamcl.experiments.evaluate_log.paired_evaluations`), or nothing."""
    if not paired:
        return []
    first = paired[0]["algorithm"]
    lines = [
        "",
        "## Likelihood evaluations at equal success",
        "",
        f"Over the windows where both {first} and the other algorithm localised, the mean "
        "likelihood evaluations a run of each (the global initialisation included) and "
        f"{first}'s as a share of the other's. The table above averages over every run, the "
        "failed ones too.",
        "",
        "| pair | windows both localised | evaluations a run, first | the other's | ratio |",
        "|---|---:|---:|---:|---:|",
    ]
    for row in paired:
        lines.append(
            f"| {first} / {row['against']} | {row['windows']} | "
            f"{fmt(row['evaluations'], 0, '-')} | {fmt(row['against_evaluations'], 0, '-')} | "
            f"{fmt(row['ratio'], 3, '-')} |"
        )
    return lines
