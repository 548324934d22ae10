"""Table 1 of the paper and Figs. 4-6: every algorithm from every start, N seeded trials each.

Library use::

    from ceamcl.experiments.table1 import run_table1, write_table1
    result = run_table1(settings)                 # measures (no files)
    write_table1(result, "out", meta)            # table1.csv/.md, trials.csv, fig4-6
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ceamcl.experiments.common import (
    PRECISION_DEFINITIONS,
    PRECISION_HEADER,
    Curve,
    ExperimentSettings,
    curve,
    fmt,
    group_by,
    make_trials,
    markdown_table,
    metadata_markdown,
    pct,
    precision_cells,
    precision_columns,
    run_trials,
    trial_rows,
    write_csv,
    write_text,
)
from ceamcl.experiments.executors import ProgressCallback
from ceamcl.experiments.metrics import (
    GATHERED_SHARE,
    HEADING_TOL_RAD,
    HOLD_S,
    POSITION_TOL_M,
    PrecisionSummary,
    precision_summary,
)
from ceamcl.experiments.trials import TrialRecord
from ceamcl.filters import registry
from ceamcl.io.results import ensure_output_dir

#: The paper's Table 1: converged time (s), expired time (s, None = never), success rate.
PAPER_TABLE1: dict[str, tuple[float, float | None, float]] = {
    "ceamcl": (6.87, None, 1.00),
    "gmcl": (6.41, 30.44, 0.82),
    "mcl": (9.76, 36.46, 0.86),
}


@dataclass(frozen=True)
class AlgorithmSummary:
    """One row of Table 1 (means over the runs where the quantity exists)."""

    algorithm: str
    runs: int
    converged_runs: int
    converged_s: float | None
    expired_runs: int
    expired_s: float | None
    success_rate: float
    kept_all_rate: float | None
    final_error_mean_m: float
    final_error_median_m: float
    mean_particles: float
    mean_step_ms: float
    median_step_ms: float
    precision: PrecisionSummary


def summarise(algorithm: str, records: Sequence[TrialRecord]) -> AlgorithmSummary:
    """Table 1's row of one algorithm from its trials."""
    ms = [r.metrics for r in records]
    conv = [m.converged_s for m in ms if m.converged_s is not None]
    exp = [m.expired_s for m in ms if m.expired_s is not None]
    kept = [m.kept_all for m in ms if m.kept_all is not None]
    errs = np.array([m.final_position_error_m for m in ms])
    steps = np.concatenate([r.step_ms[1:] if r.step_ms.size > 1 else r.step_ms for r in records])
    return AlgorithmSummary(
        algorithm=algorithm,
        runs=len(ms),
        converged_runs=len(conv),
        converged_s=float(np.mean(conv)) if conv else None,
        expired_runs=len(exp),
        expired_s=float(np.mean(exp)) if exp else None,
        success_rate=float(np.mean([m.success for m in ms])),
        kept_all_rate=float(np.mean(kept)) if kept else None,
        final_error_mean_m=float(errs.mean()),
        final_error_median_m=float(np.median(errs)),
        mean_particles=float(np.mean([m.mean_particles for m in ms])),
        mean_step_ms=float(np.mean([m.mean_step_ms for m in ms])),
        median_step_ms=float(np.median(steps)),
        precision=precision_summary(ms),
    )


@dataclass
class Table1Result:
    settings: ExperimentSettings
    records: list[TrialRecord]
    summaries: list[AlgorithmSummary]

    def by_algorithm(self) -> dict[str, list[TrialRecord]]:
        return group_by(self.records, lambda r: r.algorithm)


def run_table1(
    settings: ExperimentSettings, *, progress: ProgressCallback | None = None, quiet: bool = False
) -> Table1Result:
    """Run every algorithm on every route ``settings.trials`` times and summarise."""
    trials = make_trials("table1", settings)
    records = run_trials(trials, settings, label="table1 trials", progress=progress, quiet=quiet)
    groups = group_by(records, lambda r: r.algorithm)
    return Table1Result(settings, records, [summarise(a, rs) for a, rs in groups.items()])


# ------------------------------------------------------------------ curves (Figs. 4-6)
def error_curves(result: Table1Result) -> tuple[list[Curve], list[Curve]]:
    groups = result.by_algorithm()
    est = [curve(a, rs, lambda r: r.position_errors) for a, rs in groups.items()]
    track = [curve(a, rs, lambda r: r.tracking_error) for a, rs in groups.items()]
    return est, track


def step_time_curves(result: Table1Result) -> list[Curve]:
    """Fig. 5's time per iteration: step 0, the global initialisation, is left out (NaN), as
    the tables' step times leave it out (its cost is the evaluations' column)."""
    return [curve(a, rs, _iteration_ms) for a, rs in result.by_algorithm().items()]


def _iteration_ms(record: TrialRecord) -> NDArray[np.float64]:
    ms = np.asarray(record.step_ms, dtype=np.float64).copy()
    ms[:1] = np.nan
    return ms


def sample_curves(result: Table1Result) -> tuple[list[Curve], list[Curve]]:
    groups = result.by_algorithm()
    samples = [
        curve(a, rs, lambda r: r.n_particles.astype(float), stat="mean") for a, rs in groups.items()
    ]
    resources = [
        curve(a, rs, lambda r: r.resources, stat="mean")
        for a, rs in groups.items()
        if any(np.isfinite(r.resources).any() for r in rs)
    ]
    return samples, resources


# ------------------------------------------------------------------ outputs
def summary_rows(result: Table1Result) -> list[dict[str, Any]]:
    rows = []
    for s in result.summaries:
        paper = PAPER_TABLE1.get(s.algorithm)
        row = asdict(s)
        del row["precision"]
        row.update(precision_columns(s.precision))  # likelihood_evaluations among them
        row["paper_converged_s"] = None if paper is None else paper[0]
        row["paper_expired_s"] = None if paper is None else (paper[1] if paper[1] else "never")
        row["paper_success_rate"] = None if paper is None else paper[2]
        # False: the figures above measure a start that is not a global localisation
        row["localises_globally"] = registry.localises_globally(s.algorithm)
        rows.append(row)
    return rows


def _conv(s: AlgorithmSummary) -> str:
    return f"{fmt(s.converged_s)} ({s.converged_runs}/{s.runs})"


def _exp(s: AlgorithmSummary) -> str:
    if s.converged_runs == 0:
        return "n/a (never converged)"
    return f"{fmt(s.expired_s)} ({s.expired_runs}/{s.converged_runs})"


def table1_markdown(result: Table1Result, meta: dict[str, Any]) -> str:
    n_images = result.settings.course.n_images
    header = [
        "algorithm",
        "converged (s)",
        "paper",
        "expired (s)",
        "paper",
        "success",
        "paper",
        f"kept all {n_images}",
        "final error (m) mean / median",
        "mean particles",
        "step ms mean / median",
        *PRECISION_HEADER,
    ]
    rows = []
    for s in result.summaries:
        paper = PAPER_TABLE1.get(s.algorithm)
        measured = partial(registry.global_cell, s.algorithm, instead="-")
        rows.append(
            [
                s.algorithm,
                measured(_conv(s)),
                "-" if paper is None else f"{paper[0]:.2f}",
                measured(_exp(s)),
                "-" if paper is None else fmt(paper[1], never="never"),
                registry.global_cell(s.algorithm, pct(s.success_rate)),
                "-" if paper is None else pct(paper[2]),
                measured(pct(s.kept_all_rate)),
                measured(f"{s.final_error_mean_m:.2f} / {s.final_error_median_m:.2f}"),
                registry.particles_cell(s.algorithm, f"{s.mean_particles:.0f}"),
                f"{s.mean_step_ms:.1f} / {s.median_step_ms:.1f}",
                *precision_cells(s.precision, s.algorithm),
            ]
        )
    notes = registry.global_notes(s.algorithm for s in result.summaries)
    routes = ", ".join(r.name for r in result.settings.course.routes)
    text = [
        f"# Table 1 on {result.settings.course.name}",
        "",
        f"{result.settings.trials} trial(s) per start ({routes}); "
        f"{len(result.records)} runs in all. Times are seconds since the start of a run: "
        "means over the runs that converged (expired), with the count in brackets.",
        "",
        markdown_table(header, rows),
        "Definitions (docs/experiments.md): an image of the true pose is *covered* when a "
        f"hypothesis lies within {POSITION_TOL_M} m and {HEADING_TOL_RAD} rad of it. "
        f"*Converged*: all {n_images} images covered and the hypotheses there hold at least "
        f"{GATHERED_SHARE:.0%} of the weight. *Expired*: after convergence, an image uncovered "
        f"for {HOLD_S:g} s or more. *Success*: the true pose covered at the goal. "
        "Single-estimate algorithms (nav2-amcl) are measured by their estimate alone.",
        "",
        *(f"{note} (its measured figures are in `table1.csv`)." for note in notes),
        *([""] if notes else []),
        PRECISION_DEFINITIONS,
        "",
        "The paper's numbers are 5 runs per start on a real Pioneer II in its hall (its Table "
        "1); ours are simulated runs of the same protocol.",
        "",
        metadata_markdown(meta, result.settings.skipped),
    ]
    return "\n".join(text)


def write_table1(
    result: Table1Result, out: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    """table1.csv, table1.md, trials.csv and the figures fig4/5/6 in ``out``."""
    out_dir = ensure_output_dir(out)
    from ceamcl.experiments.figures import plot_error_over_time, plot_resources, plot_step_time

    name = result.settings.course.name
    est, track = error_curves(result)
    samples, resources = sample_curves(result)
    return [
        write_csv(out_dir / "table1.csv", summary_rows(result)),
        write_csv(out_dir / "trials.csv", trial_rows(result.records)),
        plot_error_over_time(
            est, track, out_dir / "fig4_error.png", f"Position error over time on {name} (Fig. 4)"
        ),
        plot_step_time(
            step_time_curves(result),
            out_dir / "fig5_step_time.png",
            f"Time per iteration on {name} (Fig. 5)",
        ),
        plot_resources(
            samples,
            resources,
            out_dir / "fig6_resources.png",
            f"Sample size and resources on {name} (Fig. 6)",
        ),
        write_text(out_dir / "table1.md", table1_markdown(result, meta)),
    ]
