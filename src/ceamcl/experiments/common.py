"""Shared machinery of the experiments: settings, running trials, run metadata, curves, files."""

from __future__ import annotations

import csv
import datetime
import os
import platform
import sys
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from ceamcl.experiments.executors import ProgressCallback, filter_bytes, map_trials, open_executor
from ceamcl.experiments.metrics import CONFIDENT_SHARE, PrecisionSummary
from ceamcl.experiments.routes import Course
from ceamcl.experiments.trials import Trial, TrialRecord, localise_trial, run_trial
from ceamcl.filters import registry
from ceamcl.io.results import atomic_write, ensure_output_dir, write_json
from ceamcl.outputs import OutputOptions, clear_run_files, write_outputs

T = TypeVar("T")


@dataclass(frozen=True)
class ExperimentSettings:
    """What every experiment takes: the course, the algorithms, trials per route, the seed,
    where trials run, and (for quick checks only) a cut-off of every run."""

    course: Course
    algorithms: tuple[str, ...]
    trials: int = 5
    seed: int = 0
    executor: str = "local"
    workers: int | None = None
    max_time_s: float | None = None
    skipped: tuple[tuple[str, str], ...] = ()  # (algorithm, reason) not run


def make_trials(
    experiment: str,
    settings: ExperimentSettings,
    *,
    algorithms: Sequence[str] | None = None,
    deltas: Sequence[float | None] = (None,),
) -> list[Trial]:
    """Every (algorithm, delta, route, repetition) trial; the log depends only on the route
    and the repetition, so all algorithms and deltas see the same logs."""
    return [
        Trial(
            experiment,
            alg,
            settings.course,
            route,
            rep,
            settings.seed,
            delta,
            settings.max_time_s,
        )
        for alg in (algorithms if algorithms is not None else settings.algorithms)
        for delta in deltas
        for route in range(len(settings.course.routes))
        for rep in range(settings.trials)
    ]


def run_trials(
    trials: Sequence[Trial],
    settings: ExperimentSettings,
    *,
    label: str,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
) -> list[TrialRecord]:
    """Run the trials on the settings' executor, with a progress bar; records in input order.
    Each worker builds filters on its trials' map, which the worker count makes room for (a
    route file's map may be large: :func:`~ceamcl.experiments.executors.filter_bytes`)."""
    courses = {id(t.course): t.course for t in trials}.values()
    each = max((filter_bytes(c.grid()) for c in courses), default=0)
    report = None if quiet else progress
    with open_executor(settings.executor, settings.workers, each, report) as ex:
        return map_trials(ex, run_trial, trials, label=label, progress=progress, quiet=quiet)


def run_metadata(settings: ExperimentSettings, argv: Sequence[str] | None = None) -> dict[str, Any]:
    """How and where the numbers were made: command, seed, executor, machine, versions."""

    return {
        "command": " ".join(["ceamcl", *(argv if argv is not None else sys.argv[1:])]),
        "seed": settings.seed,
        "trials_per_route": settings.trials,
        "routes": [r.name for r in settings.course.routes],
        "course": settings.course.name,
        "executor": settings.executor,
        "workers": settings.workers,
        "max_time_s": settings.max_time_s,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.node()} ({platform.machine()}, {os.cpu_count()} cores, "
        f"{platform.system()} {platform.release()})",
        "python": platform.python_version(),
        "numpy": np.__version__,
    }


# ------------------------------------------------------------------ visual outputs
def trial_of(record: TrialRecord, settings: ExperimentSettings) -> Trial:
    """The trial that made ``record`` (trials are seeded: running it again gives the record)."""
    return Trial(
        record.experiment,
        record.algorithm,
        settings.course,
        record.route_index,
        record.repetition,
        record.seed,
        record.delta_per_m2,
        settings.max_time_s,
    )


def first_records(records: Sequence[TrialRecord]) -> list[TrialRecord]:
    """The first trial of each algorithm (records in trial order: the first route, the first
    repetition and, for ``delta``, the first delta)."""
    return [rs[0] for rs in group_by(records, lambda r: r.algorithm).values()]


@dataclass(frozen=True)
class TrialOutputs:
    """The visual outputs of one re-run trial, and whether the re-run equals its record."""

    algorithm: str
    out_dir: Path
    files: list[Path]
    same_as_record: bool


def write_trial_outputs(
    record: TrialRecord,
    settings: ExperimentSettings,
    out_dir: str | os.PathLike[str],
    options: OutputOptions,
    *,
    on_start: Callable[[int], None] | None = None,
    on_step: Callable[[int], None] | None = None,
    on_frame: Callable[[int, int], None] | None = None,
) -> TrialOutputs:
    """Run the trial of ``record`` again in this process, keeping the particles every
    ``options.stride`` steps, and write ``options``' outputs (``ceamcl.outputs.
    OutputOptions``: ``run.gif``, ``run.mp4``, ``report.html``; ``options.mcap`` is taken as a
    file *name* inside ``out_dir``) plus ``summary.json`` into ``out_dir``.

    The run is checked against the record: ``same_as_record`` is whether the estimates of
    every step are bit for bit those the experiment counted (``summary.json`` says so too).
    An earlier run's files (:data:`ceamcl.outputs.RUN_FILES`) are removed from ``out_dir``
    first, so it holds this run's only (a ``run.gif`` of a longer earlier run stayed beside
    this one's ``summary.json``).
    """
    out = ensure_output_dir(out_dir)
    _clear_marked(out)
    clear_run_files(out)
    trial = trial_of(record, settings)
    log, result = localise_trial(
        trial, snapshot_every=options.stride, on_start=on_start, on_step=on_step
    )
    same = bool(np.array_equal(result.estimates, record.estimates)) and bool(
        np.array_equal(result.times, record.times)
    )
    summary: dict[str, Any] = {
        "trial": trial.name,
        "experiment": trial.experiment,
        "algorithm": trial.algorithm,
        "course": settings.course.name,
        "route": trial.route,
        "repetition": trial.repetition,
        "seed": trial.seed,
        "delta_per_m2": trial.delta_per_m2,
        "max_time_s": trial.max_time_s,
        "steps": result.steps,
        "same_as_recorded_trial": same,
        **asdict(record.metrics),
    }
    if options.mcap is not None:
        options = replace(options, mcap=out / Path(options.mcap).name)
    files = write_outputs(
        result,
        trial.course.grid(),
        out,
        options,
        log=log,
        summary=summary,
        title=f"{trial.experiment}: {trial.algorithm} on {trial.route}, "
        f"repetition {trial.repetition}, seed {trial.seed}",
        on_frame=on_frame,
    )
    files.append(write_json(out / "summary.json", summary))
    write_text(out / RUN_MARKER, "".join(f"{Path(f).name}\n" for f in files))
    return TrialOutputs(trial.algorithm, out, files, same)


#: The folder of ``OUT`` that holds each algorithm's re-run, ``OUT/runs/ALGORITHM/``.
RUNS_FOLDER = "runs"
#: The list of the files a re-run wrote into its folder, one name a line: what a later
#: experiment may remove there, and nothing else (a user's files, a bag's ``.mcap``, stay).
RUN_MARKER = ".ceamcl-run"


def _clear_marked(folder: Path) -> list[Path]:
    """The files ``folder``'s :data:`RUN_MARKER` lists (plain files, by name, inside
    ``folder``), then the marker; nothing without a marker."""
    marker = folder / RUN_MARKER
    if not marker.is_file() or marker.is_symlink():
        return []
    gone: list[Path] = []
    for name in marker.read_text(errors="replace").splitlines():
        f = folder / name
        if name and Path(name).name == name and (f.is_file() or f.is_symlink()):
            f.unlink()
            gone.append(f)
    marker.unlink()
    return [*gone, marker]


def clear_earlier_runs(out: str | os.PathLike[str]) -> list[Path]:
    """Remove an earlier experiment's visual outputs from ``OUT/runs/``: in each folder the
    files its re-run listed in :data:`RUN_MARKER` (the run files and the ``--mcap`` file it
    wrote), then the folders this leaves empty (``runs/`` too). A folder without the marker, a
    symbolic link, and any file the marker does not list are left alone. Returns what was
    removed.

    An experiment calls it when it writes its tables, so ``OUT/runs/`` holds the runs of those
    tables only: the algorithms this run draws, none when it draws none (an algorithm's folder
    from an earlier run it did not have stayed whole)."""
    runs = Path(out) / RUNS_FOLDER
    if runs.is_symlink() or not runs.is_dir():
        return []
    gone: list[Path] = []
    for folder in sorted(p for p in runs.iterdir() if p.is_dir() and not p.is_symlink()):
        cleared = _clear_marked(folder)
        gone += cleared
        if cleared and not any(folder.iterdir()):
            folder.rmdir()
            gone.append(folder)
    if gone and not any(runs.iterdir()):
        runs.rmdir()
        gone.append(runs)
    return gone


# ------------------------------------------------------------------ curves over time
def time_grid(records: Sequence[TrialRecord]) -> NDArray[np.float64]:
    """Times of the longest record (runs share their step rate)."""
    longest = max(records, key=lambda r: r.times.size)
    return longest.times - longest.times[0]


def stacked(
    records: Sequence[TrialRecord], value: Callable[[TrialRecord], NDArray[np.float64]]
) -> NDArray[np.float64]:
    """``(R, T)`` per-step values of each record, NaN-padded to the longest record."""
    n = max(r.times.size for r in records)
    out = np.full((len(records), n), np.nan)
    for i, r in enumerate(records):
        v = np.asarray(value(r), dtype=np.float64)
        out[i, : v.size] = v
    return out


@dataclass(frozen=True)
class Curve:
    """A per-step statistic over trials: centre line and a band (both ``(T,)``)."""

    label: str
    times: NDArray[np.float64]
    centre: NDArray[np.float64]
    low: NDArray[np.float64]
    high: NDArray[np.float64]


def curve(
    label: str,
    records: Sequence[TrialRecord],
    value: Callable[[TrialRecord], NDArray[np.float64]],
    *,
    stat: str = "median",
) -> Curve:
    """Median with the inter-quartile band, or mean with +-1 standard deviation."""
    data = stacked(records, value)
    times = time_grid(records)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", category=RuntimeWarning)
        if stat == "median":
            centre = np.nanmedian(data, axis=0)
            low, high = np.nanpercentile(data, [25, 75], axis=0)
        elif stat == "mean":
            centre = np.nanmean(data, axis=0)
            sd = np.nanstd(data, axis=0)
            low, high = centre - sd, centre + sd
        else:
            raise ValueError(f"stat: expected 'median' or 'mean', got {stat!r}")
    return Curve(label, times, centre, low, high)


def group_by(items: Iterable[T], key: Callable[[T], Any]) -> dict[Any, list[T]]:
    """Items grouped by ``key``, groups in first-seen order."""
    out: dict[Any, list[T]] = {}
    for item in items:
        out.setdefault(key(item), []).append(item)
    return out


# ------------------------------------------------------------------ files
def write_text(path: Path, text: str) -> Path:
    """``text`` to ``path`` through a temporary file, removed if interrupted
    (:func:`ceamcl.io.results.atomic_write`)."""
    with atomic_write(path) as tmp:
        tmp.write_text(text)
    return path


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """Rows as CSV (columns in first-seen order; cells as :func:`_cell` writes them)."""
    fields: list[str] = []
    for row in rows:
        for key in row:
            if key not in fields:
                fields.append(key)
    with atomic_write(path) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, restval="")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(v) for k, v in row.items()})
    return path


#: Significant digits of a CSV cell: a log's epoch times (10^9 s) keep their milliseconds.
CSV_DIGITS = 12


def _cell(value: Any) -> Any:
    """A CSV cell: empty for ``None`` and non-finite numbers; a whole number as one (a count
    held in a float, because another row's is NaN, is written ``1523456``, not ``1.52346e+06``);
    other floats to :data:`CSV_DIGITS` significant digits."""
    if value is None:
        return ""
    if isinstance(value, float | np.floating):
        v = float(value)
        if not np.isfinite(v):
            return ""
        if v.is_integer() and abs(v) < 10**CSV_DIGITS:
            return str(int(v))
        return f"{v:.{CSV_DIGITS}g}"
    return value


def trial_rows(records: Sequence[TrialRecord]) -> list[dict[str, Any]]:
    """One row per trial for ``trials.csv``."""
    rows = []
    for r in records:
        m = r.metrics
        rows.append(
            {
                "experiment": r.experiment,
                "algorithm": r.algorithm,
                "delta_per_m2": r.delta_per_m2,
                "route": r.route,
                "repetition": r.repetition,
                "seed": r.seed,
                "steps": int(r.times.size),
                "converged_s": m.converged_s,
                "expired_s": m.expired_s,
                "success": int(m.success),
                "kept_all_images": None if m.kept_all is None else int(m.kept_all),
                "final_estimate_ok": int(m.final_estimate_ok),
                "final_position_error_m": m.final_position_error_m,
                "final_heading_error_rad": m.final_heading_error_rad,
                "true_image_weight": m.true_image_weight,
                "spurious_weight": m.spurious_weight,
                "truth_weight": m.truth_weight,
                "heaviest_weight": m.heaviest_weight,
                "confidently_wrong": int(m.confidently_wrong),
                "confidently_wrong_share": m.confidently_wrong_share,
                "nearest_position_error_m": m.nearest_position_error_m,
                "nearest_heading_error_rad": m.nearest_heading_error_rad,
                "likelihood_evaluations": m.likelihood_evaluations,
                "initialisation_likelihood_evaluations": m.initialisation_likelihood_evaluations,
                "mean_particles": m.mean_particles,
                "final_particles": m.final_particles,
                "mean_step_ms": m.mean_step_ms,
                "median_step_ms": m.median_step_ms,
            }
        )
    return rows


def fmt(value: float | None, digits: int = 2, never: str = "never") -> str:
    """A number for a table, or ``never`` for ``None``/NaN."""
    if value is None or not np.isfinite(value):
        return never
    return f"{value:.{digits}f}"


def pct(value: float | None) -> str:
    return "n/a" if value is None or not np.isfinite(value) else f"{100 * value:.0f}%"


def evaluations(value: float | None) -> str:
    """Likelihood evaluations for a table: ``1,012,345``, or ``not counted``."""
    return "not counted" if value is None else f"{value:,.0f}"


def precision_columns(p: PrecisionSummary) -> dict[str, Any]:
    """The precision side as flat CSV columns (evaluations per run as whole numbers)."""
    row = asdict(p)
    for key in ("likelihood_evaluations", "initialisation_likelihood_evaluations"):
        if row[key] is not None:
            row[key] = round(row[key])
    return row


def compact_count(value: float | None, missing: str = "-") -> str:
    """A large count for a narrow column: ``1.14M``, ``505k``, ``840``; ``missing`` for none."""
    if value is None or not np.isfinite(value):
        return missing
    if value >= 1e6:
        return f"{value / 1e6:.2f}M"
    if value >= 1e4:
        return f"{value / 1e3:.0f}k"
    return f"{value:.0f}"


#: The precision side's columns of the Markdown tables (:func:`precision_cells`).
PRECISION_HEADER = (
    "weight true images / at truth / spurious",
    "confidently wrong",
    "nearest hypothesis error (m) mean / median, (rad) mean",
    "likelihood evaluations per run",
)


def precision_cells(p: PrecisionSummary, algorithm: str | None = None) -> list[str]:
    """The cells of :data:`PRECISION_HEADER` for one row; with ``algorithm``, those that
    measure global localisation read "-" for one that has none of its own (its success
    column says "not comparable": :func:`ceamcl.filters.registry.global_cell`)."""
    measured = [
        f"{pct(p.true_image_weight)} / {pct(p.truth_weight)} / {pct(p.spurious_weight)}",
        pct(p.confidently_wrong_rate),
        f"{fmt(p.nearest_position_error_mean_m, never='-')} / "
        f"{fmt(p.nearest_position_error_median_m, never='-')}, "
        f"{fmt(p.nearest_heading_error_mean_rad, never='-')}",
    ]
    if algorithm is not None:
        measured = [registry.global_cell(algorithm, c, "-") for c in measured]
    return [*measured, evaluations(p.likelihood_evaluations)]


PRECISION_DEFINITIONS = (
    "Precision side (docs/experiments.md), at the goal: the *true images* are the hypotheses "
    "within the tolerances of the truth or one of its symmetric images, the others are "
    "*spurious*; the columns give their shares of the weight (mean over runs), and *at truth* "
    "the part of the true images' that covers the truth itself. *Confidently "
    f"wrong*: the estimate misses the truth while one hypothesis holds >= {CONFIDENT_SHARE:.0%} "
    "of the weight (share of runs). *Nearest hypothesis*: the one nearest the truth. "
    "*Likelihood evaluations*: poses scored against a scan over the run, the global "
    "initialisation included (mean per run)."
)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def metadata_markdown(meta: Mapping[str, Any], skipped: Sequence[tuple[str, str]]) -> str:
    lines = ["## How these numbers were made", ""]
    lines += [f"- {k.replace('_', ' ')}: `{v}`" for k, v in meta.items()]
    for alg, reason in skipped:
        lines.append(f"- skipped `{alg}`: {reason}")
    return "\n".join(lines) + "\n"
