"""marked-hall: how often each algorithm ends at the true pose once the mark breaks symmetry.

A run counts when its final *estimate* (the one pose it reports) is within 0.5 m and 0.3 rad
of the truth. Per start route, because only the routes that pass the mark (from room 0, and
room 3 where the mark stands) give the robot the clue; the others can at best rule one room out.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ceamcl.experiments.common import (
    PRECISION_DEFINITIONS,
    PRECISION_HEADER,
    ExperimentSettings,
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
)
from ceamcl.experiments.routes import RESERVED_ROUTE_NAME
from ceamcl.experiments.trials import TrialRecord
from ceamcl.filters import registry
from ceamcl.io.results import ensure_output_dir

ALL_ROUTES = RESERVED_ROUTE_NAME


@dataclass
class MarkedResult:
    settings: ExperimentSettings
    records: list[TrialRecord]
    #: shares[algorithm][route or "all"]: share of runs whose final estimate is right.
    shares: dict[str, dict[str, float]]
    runs: dict[str, dict[str, int]]
    #: precision[algorithm][route or "all"]: the precision side at the goal.
    precision: dict[str, dict[str, PrecisionSummary]]


def precision_by_route(records: list[TrialRecord]) -> dict[str, dict[str, PrecisionSummary]]:
    """The precision side per algorithm, per start route and over all routes."""
    out: dict[str, dict[str, PrecisionSummary]] = {}
    for alg, rs in group_by(records, lambda r: r.algorithm).items():
        out[alg] = {
            route: precision_summary([r.metrics for r in rr])
            for route, rr in group_by(rs, lambda r: r.route).items()
        }
        out[alg][ALL_ROUTES] = precision_summary([r.metrics for r in rs])
    return out


def final_estimate_shares(
    records: list[TrialRecord],
) -> tuple[dict[str, dict[str, float]], dict[str, dict[str, int]]]:
    shares: dict[str, dict[str, float]] = {}
    runs: dict[str, dict[str, int]] = {}
    for alg, rs in group_by(records, lambda r: r.algorithm).items():
        shares[alg], runs[alg] = {}, {}
        for route, rr in group_by(rs, lambda r: r.route).items():
            shares[alg][route] = float(np.mean([r.metrics.final_estimate_ok for r in rr]))
            runs[alg][route] = len(rr)
        shares[alg][ALL_ROUTES] = float(np.mean([r.metrics.final_estimate_ok for r in rs]))
        runs[alg][ALL_ROUTES] = len(rs)
    return shares, runs


def run_marked(
    settings: ExperimentSettings, *, progress: ProgressCallback | None = None, quiet: bool = False
) -> MarkedResult:
    trials = make_trials("marked", settings)
    records = run_trials(trials, settings, label="marked trials", progress=progress, quiet=quiet)
    shares, runs = final_estimate_shares(records)
    return MarkedResult(settings, records, shares, runs, precision_by_route(records))


def route_columns(result: MarkedResult) -> list[str]:
    return [r.name for r in result.settings.course.routes] + [ALL_ROUTES]


def marked_markdown(result: MarkedResult, meta: dict[str, Any]) -> str:
    cols = route_columns(result)
    rows = [
        [
            alg,
            *(
                registry.global_cell(
                    alg, f"{pct(result.shares[alg].get(c))} of {result.runs[alg].get(c, 0)}"
                )
                for c in cols
            ),
        ]
        for alg in result.shares
    ]
    detail = [
        [
            alg,
            c,
            str(result.runs[alg][c]),
            registry.global_cell(alg, pct(result.shares[alg][c])),
            *precision_cells(result.precision[alg][c], alg),
        ]
        for alg in result.shares
        for c in cols
        if c in result.precision[alg]
    ]
    return "\n".join(
        [
            f"# Final estimate right on {result.settings.course.name}",
            "",
            f"Share of runs whose final estimate is within {POSITION_TOL_M} m and "
            f"{HEADING_TOL_RAD} rad of the true pose, per start route.",
            "",
            markdown_table(["algorithm", *cols], rows),
            "## Per start route: the precision side at the goal",
            "",
            markdown_table(
                [
                    "algorithm",
                    "route",
                    "runs",
                    "final estimate right",
                    *PRECISION_HEADER,
                ],
                detail,
            ),
            PRECISION_DEFINITIONS,
            "",
            "The hall's four images stay the true image set on marked-hall (the box is seen "
            "from room 3 only; elsewhere the images look alike), so weight at a wrong room's "
            "image is not spurious here. The weight *at truth* is the share held by the "
            "hypotheses within the tolerances of the truth itself: what the mark decides.",
            "",
            *(f"{note}.\n" for note in registry.global_notes(result.shares)),
            metadata_markdown(meta, result.settings.skipped),
        ]
    )


def write_marked(
    result: MarkedResult, out: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    out_dir = ensure_output_dir(out)
    from ceamcl.experiments.figures import plot_shares

    rows = [
        {
            "algorithm": alg,
            "route": c,
            "runs": result.runs[alg][c],
            "final_estimate_ok_rate": v,
            **precision_columns(result.precision[alg][c]),
            # False: the figures measure a start that is not a global localisation
            "localises_globally": registry.localises_globally(alg),
        }
        for alg, by_route in result.shares.items()
        for c, v in by_route.items()
    ]
    return [
        write_csv(out_dir / "marked.csv", rows),
        write_csv(out_dir / "trials.csv", trial_rows(result.records)),
        plot_shares(
            # an algorithm without a global localisation of its own gets no bar (marked.md
            # says why)
            {a: v for a, v in result.shares.items() if registry.localises_globally(a)},
            out_dir / "marked.png",
            f"Final estimate within {POSITION_TOL_M} m and {HEADING_TOL_RAD} rad "
            f"on {result.settings.course.name}",
            "runs with the final estimate right (%)",
        ),
        write_text(out_dir / "marked.md", marked_markdown(result, meta)),
    ]
