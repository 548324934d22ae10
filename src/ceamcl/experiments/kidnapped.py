"""Kidnapped robot: mid-run the robot is carried to another pose; does the filter find it?

The built-in course is the office tour on ``small-office``, kidnapped at 25 s into the
north-east room. small-office has no symmetry, so "relocalised" has one meaning: the estimate
back at the true pose. The filter is *localised* at a step when its estimate is within 0.5 m and
0.3 rad of the truth. It *recovers* when, at some step within ``window_s`` after the kidnap,
it becomes localised and stays localised to the end of the run; the recovery time is that
step's time minus the kidnap's.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ceamcl.errors import ConfigError
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
    HEADING_TOL_RAD,
    POSITION_TOL_M,
    PrecisionSummary,
    precision_summary,
    recovery_step,
    within,
)
from ceamcl.experiments.trials import TrialRecord
from ceamcl.filters import registry
from ceamcl.io.results import ensure_output_dir

DEFAULT_WINDOW_S = 30.0


@dataclass(frozen=True)
class KidnapOutcome:
    """One trial: localised just before the kidnap, recovered, and how fast."""

    kidnap_s: float
    localised_before: bool
    recovered: bool
    recovery_s: float | None


def localised_steps(record: TrialRecord) -> np.ndarray:
    """Per step: is the estimate within the tolerances of the truth?"""
    return within(record.estimates, record.truth)


def kidnap_outcome(record: TrialRecord, window_s: float) -> KidnapOutcome:
    if not record.kidnapped_at:
        raise ConfigError(f"trial {record.route}: the run has no kidnap (was it cut short?)")
    k = record.kidnapped_at[0]
    dt = float(np.median(np.diff(record.times)))
    loc = localised_steps(record)
    r = recovery_step(loc, k, round(window_s / dt))
    return KidnapOutcome(
        kidnap_s=float(record.times[k] - record.times[0]),
        localised_before=bool(loc[k - 1]),
        recovered=r is not None,
        recovery_s=None if r is None else float(record.times[r] - record.times[k]),
    )


@dataclass(frozen=True)
class KidnapSummary:
    algorithm: str
    runs: int
    localised_before_rate: float
    recovery_rate: float
    mean_recovery_s: float | None
    median_recovery_s: float | None
    mean_particles: float
    mean_step_ms: float
    precision: PrecisionSummary  # at the end of the runs


@dataclass
class KidnapResult:
    settings: ExperimentSettings
    window_s: float
    records: list[TrialRecord]
    outcomes: list[KidnapOutcome]
    summaries: list[KidnapSummary]


def summarise(
    algorithm: str, records: Sequence[TrialRecord], outcomes: Sequence[KidnapOutcome]
) -> KidnapSummary:
    times = [o.recovery_s for o in outcomes if o.recovery_s is not None]
    return KidnapSummary(
        algorithm=algorithm,
        runs=len(outcomes),
        localised_before_rate=float(np.mean([o.localised_before for o in outcomes])),
        recovery_rate=float(np.mean([o.recovered for o in outcomes])),
        mean_recovery_s=float(np.mean(times)) if times else None,
        median_recovery_s=float(np.median(times)) if times else None,
        mean_particles=float(np.mean([r.metrics.mean_particles for r in records])),
        mean_step_ms=float(np.mean([r.metrics.mean_step_ms for r in records])),
        precision=precision_summary([r.metrics for r in records]),
    )


def run_kidnapped(
    settings: ExperimentSettings,
    window_s: float = DEFAULT_WINDOW_S,
    *,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
) -> KidnapResult:
    missing = [r.name for r in settings.course.routes if r.kidnap is None]
    if missing:
        raise ConfigError(
            f"routes: route {missing[0]!r} has no `kidnap` entry; the kidnapped experiment "
            "needs one on every route"
        )
    if not window_s > 0:
        raise ConfigError(f"recovery-window: expected a positive time, got {window_s}")
    kidnaps = {r.name: r.kidnap.at_s for r in settings.course.routes if r.kidnap is not None}
    last = max(kidnaps, key=lambda name: kidnaps[name])
    if settings.max_time_s is not None and settings.max_time_s <= kidnaps[last]:
        raise ConfigError(
            f"max-time: expected more than the kidnap's {kidnaps[last]:g} s (route {last!r}), "
            f"got {settings.max_time_s:g} s: the runs would end before it"
        )
    trials = make_trials("kidnapped", settings)
    records = run_trials(trials, settings, label="kidnapped trials", progress=progress, quiet=quiet)
    outcomes = [kidnap_outcome(r, window_s) for r in records]
    summaries = []
    for alg, idx in group_by(range(len(records)), lambda i: records[i].algorithm).items():
        summaries.append(summarise(alg, [records[i] for i in idx], [outcomes[i] for i in idx]))
    return KidnapResult(settings, window_s, records, outcomes, summaries)


def error_curves(result: KidnapResult) -> list[Curve]:
    return [
        curve(a, rs, lambda r: r.position_errors)
        for a, rs in group_by(result.records, lambda r: r.algorithm).items()
    ]


def kidnapped_markdown(result: KidnapResult, meta: dict[str, Any]) -> str:
    header = [
        "algorithm",
        "runs",
        "localised before kidnap",
        "recovered",
        "recovery time (s) mean / median",
        "mean particles",
        "step ms",
        *PRECISION_HEADER,
    ]
    rows = [
        [
            s.algorithm,
            str(s.runs),
            # the start is a global localisation: not comparable for a filter without one
            registry.global_cell(s.algorithm, pct(s.localised_before_rate)),
            pct(s.recovery_rate),
            f"{fmt(s.mean_recovery_s, 1, '-')} / {fmt(s.median_recovery_s, 1, '-')}",
            registry.particles_cell(s.algorithm, f"{s.mean_particles:.0f}"),
            f"{s.mean_step_ms:.1f}",
            *precision_cells(s.precision),
        ]
        for s in result.summaries
    ]
    return "\n".join(
        [
            f"# Kidnapped robot on {result.settings.course.name}",
            "",
            f"Recovered: within {result.window_s:g} s of the kidnap the estimate comes within "
            f"{POSITION_TOL_M} m and {HEADING_TOL_RAD} rad of the truth and stays there to the "
            "end of the run. Recovery time: from the kidnap to that moment (recovered runs).",
            "",
            markdown_table(header, rows),
            *(
                f"{note} (before the kidnap; its measured figures are in `kidnapped.csv`).\n"
                for note in registry.global_notes(s.algorithm for s in result.summaries)
            ),
            PRECISION_DEFINITIONS.replace("at the goal", "at the end of the run"),
            "",
            metadata_markdown(meta, result.settings.skipped),
        ]
    )


def summary_row(s: KidnapSummary) -> dict[str, Any]:
    """One row of ``kidnapped.csv`` (the precision side as flat columns)."""
    row = asdict(s)
    del row["precision"]
    row.update(precision_columns(s.precision))
    return row


def write_kidnapped(
    result: KidnapResult, out: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    out_dir = ensure_output_dir(out)
    from ceamcl.experiments.figures import plot_kidnapped

    rows = trial_rows(result.records)
    for row, o in zip(rows, result.outcomes, strict=True):
        row.update(asdict(o))
    kidnap_s = float(np.mean([o.kidnap_s for o in result.outcomes]))
    return [
        write_csv(out_dir / "kidnapped.csv", [summary_row(s) for s in result.summaries]),
        write_csv(out_dir / "trials.csv", rows),
        plot_kidnapped(
            error_curves(result),
            kidnap_s,
            result.window_s,
            out_dir / "kidnapped.png",
            f"Kidnapped robot on {result.settings.course.name}: position error (median)",
        ),
        write_text(out_dir / "kidnapped.md", kidnapped_markdown(result, meta)),
    ]
