"""Fig. 7: CEAMCL's total sample size over time for several delta (resources per m^2)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ceamcl.errors import ConfigError
from ceamcl.experiments.common import (
    Curve,
    ExperimentSettings,
    curve,
    group_by,
    make_trials,
    markdown_table,
    metadata_markdown,
    pct,
    run_trials,
    trial_rows,
    write_csv,
    write_text,
)
from ceamcl.experiments.executors import ProgressCallback
from ceamcl.experiments.trials import TrialRecord
from ceamcl.io.results import ensure_output_dir

#: The paper's default is 80 per m^2; Fig. 7 shows a few values around it.
DEFAULT_DELTAS: tuple[float, ...] = (20.0, 40.0, 80.0, 160.0)


@dataclass(frozen=True)
class DeltaSummary:
    delta_per_m2: float
    runs: int
    initial_particles: float
    mean_particles: float
    final_particles: float
    kept_all_rate: float
    success_rate: float
    mean_step_ms: float


@dataclass
class DeltaResult:
    settings: ExperimentSettings
    deltas: tuple[float, ...]
    records: list[TrialRecord]
    summaries: list[DeltaSummary]


def summarise(delta: float, records: Sequence[TrialRecord]) -> DeltaSummary:
    ms = [r.metrics for r in records]
    return DeltaSummary(
        delta_per_m2=delta,
        runs=len(records),
        initial_particles=float(np.mean([r.n_particles[0] for r in records])),
        mean_particles=float(np.mean([m.mean_particles for m in ms])),
        final_particles=float(np.mean([m.final_particles for m in ms])),
        kept_all_rate=float(np.mean([bool(m.kept_all) for m in ms])),
        success_rate=float(np.mean([m.success for m in ms])),
        mean_step_ms=float(np.mean([m.mean_step_ms for m in ms])),
    )


def run_delta(
    settings: ExperimentSettings,
    deltas: Sequence[float] = DEFAULT_DELTAS,
    *,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
) -> DeltaResult:
    """CEAMCL with each delta on every route, ``settings.trials`` times (same logs for all)."""
    values = tuple(dict.fromkeys(float(d) for d in deltas))
    if not values or any(not (d > 0 and np.isfinite(d)) for d in values):
        raise ConfigError(f"deltas: expected positive numbers, got {list(deltas)}")
    trials = make_trials("delta", settings, algorithms=("ceamcl",), deltas=values)
    records = run_trials(trials, settings, label="delta trials", progress=progress, quiet=quiet)
    groups = group_by(records, lambda r: r.delta_per_m2)
    return DeltaResult(settings, values, records, [summarise(d, groups[d]) for d in values])


def sample_curves(result: DeltaResult) -> list[Curve]:
    groups = group_by(result.records, lambda r: r.delta_per_m2)
    return [
        curve(f"delta = {d:g} / m²", groups[d], lambda r: r.n_particles.astype(float), stat="mean")
        for d in result.deltas
    ]


def summary_cells(s: DeltaSummary) -> list[str]:
    """delta, runs, initial/mean/final sample size, kept all, success: a row of its tables."""
    return [
        f"{s.delta_per_m2:g}",
        str(s.runs),
        f"{s.initial_particles:.0f}",
        f"{s.mean_particles:.0f}",
        f"{s.final_particles:.0f}",
        pct(s.kept_all_rate),
        pct(s.success_rate),
    ]


def delta_markdown(result: DeltaResult, meta: dict[str, Any]) -> str:
    n_images = result.settings.course.n_images
    header = [
        "delta (per m²)",
        "runs",
        "initial samples",
        "mean samples",
        "final samples",
        f"kept all {n_images}",
        "success",
        "step ms",
    ]
    rows = [[*summary_cells(s), f"{s.mean_step_ms:.1f}"] for s in result.summaries]
    return "\n".join(
        [
            f"# Effect of delta on CEAMCL's sample size on {result.settings.course.name} (Fig. 7)",
            "",
            "Sample sizes are means over runs (and over steps for the mean). A larger delta "
            "gives every species more resources, so species compete less and more samples "
            "survive (the paper, section 4).",
            "",
            markdown_table(header, rows),
            metadata_markdown(meta, result.settings.skipped),
        ]
    )


def write_delta(
    result: DeltaResult, out: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    out_dir = ensure_output_dir(out)
    from ceamcl.experiments.figures import plot_delta

    return [
        write_csv(out_dir / "delta.csv", [asdict(s) for s in result.summaries]),
        write_csv(out_dir / "trials.csv", trial_rows(result.records)),
        plot_delta(
            sample_curves(result),
            out_dir / "fig7_delta.png",
            f"CEAMCL sample size for several delta on {result.settings.course.name} (Fig. 7)",
        ),
        write_text(out_dir / "delta.md", delta_markdown(result, meta)),
    ]
