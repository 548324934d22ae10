"""The tuning sweep behind the presets ``mcl-tuned``, ``gmcl-tuned`` and ``kld-amcl-tuned``.

Table 1's protocol (the symmetric hall, a run from each of the four rooms, ``trials`` seeded
runs per room, :mod:`ceamcl.experiments.trials`) for each baseline over a grid of sensor
settings (``max_beams``, ``temper``), particle counts and initialisation budgets
(``init_test_poses``), on seeds disjoint from the ones reported (base seed
:data:`TUNING_SEED`; ``table1`` reports base seed 0). KLD-AMCL scores scans as ROS amcl does,
to which tempering does not apply: its grid has ``temper = 1`` only.

Score, in this order (:func:`score_key`): the share of runs that kept all four images, the
success rate, the mean converged time (runs that never converged count as never), and fewer
likelihood evaluations per run (initialisation included). docs/tuning.md has the sweep that
chose the presets; ``docs/tuning.csv`` is its every row, and a test holds each preset to the
best row of its algorithm there.

Library use::

    from ceamcl.experiments.tuning import DEFAULT_GRID, run_tuning, write_tuning
    result = run_tuning(settings, DEFAULT_GRID)          # settings.seed = TUNING_SEED
    write_tuning(result, "out", meta)                     # tuning.csv, tuning.md
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from ceamcl.errors import ConfigError
from ceamcl.experiments.common import (
    ExperimentSettings,
    fmt,
    markdown_table,
    metadata_markdown,
    pct,
    write_csv,
    write_text,
)
from ceamcl.experiments.executors import ProgressCallback, map_trials, open_executor
from ceamcl.experiments.trials import Trial, localise_trial, record_trial
from ceamcl.filters import registry
from ceamcl.filters.headings import HeadingPrior
from ceamcl.io.results import ensure_output_dir

#: The baselines the sweep tunes.
BASELINES: tuple[str, ...] = ("mcl", "gmcl", "kld-amcl")
#: The sweep's base seed: disjoint from the seeds experiments report (base seed 0 and up,
#: ``trials`` per route: seeds are SeedSequence(seed, (route, repetition))).
TUNING_SEED = 10_000
#: The preset each baseline's best row becomes.
PRESETS: dict[str, str] = {a: f"{a}-tuned" for a in BASELINES}


@dataclass(frozen=True)
class TuningGrid:
    """The values swept (every combination; ``temper`` only for the product scoring)."""

    max_beams: tuple[int, ...] = (30, 60)
    temper: tuple[float, ...] = (1.0, 0.3, 0.1, 0.03)
    n_particles: tuple[int, ...] = (1000, 2000, 5000)
    init_test_poses: tuple[int, ...] = (0, 100_000, 1_000_000)
    init_headings: tuple[bool, ...] = (False, True)

    def __post_init__(self) -> None:
        for name in ("max_beams", "temper", "n_particles", "init_test_poses", "init_headings"):
            if not getattr(self, name):
                raise ConfigError(f"{name}: expected at least one value to sweep")
        if not any(self.init_test_poses) and all(self.init_headings):
            # headings from the scan guide test poses, and there are none: every configuration
            # is skipped (candidates), and an empty sweep wrote empty tables with exit 0
            raise ConfigError(
                "init-headings: headings from the scan apply only with test poses, and the "
                "grid has none (init_test_poses 0): no configuration to run; add uniform to "
                "--init-headings or a budget above 0 to --init-test-poses"
            )


DEFAULT_GRID = TuningGrid()


@dataclass(frozen=True)
class Candidate:
    """One configuration of one baseline."""

    algorithm: str
    max_beams: int
    temper: float
    n_particles: int
    init_test_poses: int
    init_headings: bool = False

    def config(self) -> Any:
        """The algorithm's config: its default with this particle budget and start (the test
        poses' headings from the scan's geometry with ``init_headings``, as CEAMCL's)."""
        spec = registry.get(self.algorithm)
        cfg = spec.default()
        if spec.with_particles is not None:
            cfg = spec.with_particles(cfg, self.n_particles)
        headings = HeadingPrior() if self.init_headings else cfg.init_headings
        return replace(cfg, init_test_poses=self.init_test_poses, init_headings=headings)

    def sensor_settings(self) -> dict[str, Any]:
        """The sensor settings (temper only where it applies: not to amcl's scoring). The
        product's temper is always given: left out, the sensor's default (0.2) would apply,
        as it did to every "temper 1" row of the sweep until 2026-11-29 (docs/tuning.md)."""
        out: dict[str, Any] = {"max_beams": self.max_beams}
        if _scoring(self.algorithm) != "ros":
            out["temper"] = self.temper
        return out


def _scoring(algorithm: str) -> str:
    """How ``algorithm`` combines beams by default: amcl's ``"ros"`` takes no tempering."""
    return str(getattr(registry.get(algorithm).default(), "scoring", "product"))


def check_algorithms(algorithms: Iterable[str]) -> None:
    """Refuse, naming them, algorithms the sweep does not tune (they were dropped without a
    word when given beside a baseline: ``--algorithms mcl,ceamcl`` tuned mcl alone)."""
    chosen = list(algorithms)
    other = [a for a in chosen if a not in BASELINES]
    if other:
        raise ConfigError(
            f"algorithms: the tuning sweep tunes {', '.join(BASELINES)} only; got "
            f"{', '.join(other)}, which it does not tune"
        )
    if not chosen:
        raise ConfigError(f"algorithms: the tuning sweep tunes {', '.join(BASELINES)}")


def candidates(algorithms: Iterable[str], grid: TuningGrid) -> list[Candidate]:
    """Every configuration of the grid for each algorithm (KLD-AMCL with ``scoring="ros"``,
    its default, takes temper 1 only; headings from the scan only with test poses); an
    algorithm the sweep does not tune is refused (:func:`check_algorithms`)."""
    algorithms = list(algorithms)
    check_algorithms(algorithms)
    out = []
    for alg in algorithms:
        tempers = (1.0,) if _scoring(alg) == "ros" else grid.temper
        for beams in grid.max_beams:
            for temper in tempers:
                for n in grid.n_particles:
                    for n_test in grid.init_test_poses:
                        for guided in grid.init_headings:
                            if guided and n_test == 0:
                                continue  # uniform particles have no test poses to guide
                            out.append(Candidate(alg, beams, temper, n, n_test, guided))
    return out


@dataclass(frozen=True)
class TuningOutcome:
    """What the score needs of one run."""

    candidate: int
    kept_all: bool
    success: bool
    converged_s: float | None
    likelihood_evaluations: int


def run_tuning_trial(item: tuple[int, Trial]) -> TuningOutcome:
    """One run of the sweep (top-level and picklable for the executors)."""
    index, trial = item
    log, result = localise_trial(trial)
    m = record_trial(trial, log, result).metrics
    evaluations = sum(int(d.record.likelihood_evaluations) for d in result.diagnostics)
    return TuningOutcome(index, bool(m.kept_all), bool(m.success), m.converged_s, evaluations)


@dataclass(frozen=True)
class TuningRow:
    """One configuration's results (means over its runs)."""

    algorithm: str
    max_beams: int
    temper: float
    n_particles: int
    init_test_poses: int
    runs: int
    kept_all_rate: float
    success_rate: float
    converged_runs: int
    converged_s: float | None
    likelihood_evaluations: float
    init_headings: bool = False

    @property
    def candidate(self) -> Candidate:
        return Candidate(
            self.algorithm,
            self.max_beams,
            self.temper,
            self.n_particles,
            self.init_test_poses,
            self.init_headings,
        )


def score_key(row: TuningRow) -> tuple[float, float, float, float]:
    """Best first: more runs keeping all images, more successes, sooner converged (never
    converged: infinitely late), fewer likelihood evaluations. Rates compare to six decimals,
    as ``tuning.csv`` keeps them: 10 of 12 read back from the file ties 10 of 12 computed."""
    conv = math.inf if row.converged_s is None else row.converged_s
    return (
        -round(row.kept_all_rate, 6),
        -round(row.success_rate, 6),
        conv,
        row.likelihood_evaluations,
    )


@dataclass
class TuningResult:
    settings: ExperimentSettings
    grid: TuningGrid
    rows: list[TuningRow]  # sorted best first within each algorithm

    def best(self) -> dict[str, TuningRow]:
        return best_rows(self.rows)


def best_rows(rows: Sequence[TuningRow]) -> dict[str, TuningRow]:
    """Each algorithm's best row by :func:`score_key`."""
    out: dict[str, TuningRow] = {}
    for row in rows:
        if row.algorithm not in out or score_key(row) < score_key(out[row.algorithm]):
            out[row.algorithm] = row
    return out


def tuning_trials(settings: ExperimentSettings, cands: Sequence[Candidate]) -> list[Trial]:
    """Table 1's trials (every route, ``settings.trials`` repetitions) for each candidate."""
    return [
        Trial(
            "tune",
            c.algorithm,
            settings.course,
            route,
            rep,
            settings.seed,
            max_time_s=settings.max_time_s,
            config=c.config(),
            sensor_settings=tuple(c.sensor_settings().items()),
        )
        for c in cands
        for route in range(len(settings.course.routes))
        for rep in range(settings.trials)
    ]


def run_tuning(
    settings: ExperimentSettings,
    grid: TuningGrid = DEFAULT_GRID,
    *,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
    done: Sequence[TuningRow] = (),
    on_row: Callable[[TuningRow], None] | None = None,
) -> TuningResult:
    """Run the sweep over ``settings.algorithms`` (baselines only: :func:`check_algorithms`)
    and score it.

    Configurations run one after another (their runs in parallel on the settings' executor);
    ``on_row(row)`` is called as each finishes (the CLI appends it to a file), and rows in
    ``done`` (from an interrupted sweep with the same seed and trials) are not run again.
    """
    algorithms = list(settings.algorithms)
    check_algorithms(algorithms)
    per = len(settings.course.routes) * settings.trials
    finished = finished_rows(done, settings)
    cands = candidates(algorithms, grid)
    todo = [c for c in cands if c not in finished]
    total = len(todo) * per
    report = None if quiet else progress

    def chunk_progress(offset: int) -> ProgressCallback:
        def inner(label: str, k: int, _n: int) -> None:
            if report is not None:
                report(label, offset + k, total)

        return inner

    rows = dict(finished)
    with open_executor(settings.executor, settings.workers, progress=report) as ex:
        for n, c in enumerate(todo):
            items = [(0, t) for t in tuning_trials(settings, [c])]
            outcomes = map_trials(
                ex,
                run_tuning_trial,
                items,
                label="tuning runs",
                progress=chunk_progress(n * per),
                quiet=quiet,
            )
            rows[c] = summarise(c, outcomes)
            if on_row is not None:
                on_row(rows[c])
    ordered = [rows[c] for c in cands]
    ordered.sort(key=lambda r: (algorithms.index(r.algorithm), score_key(r)))
    return TuningResult(settings, grid, ordered)


def summarise(c: Candidate, outcomes: Sequence[TuningOutcome]) -> TuningRow:
    conv = [o.converged_s for o in outcomes if o.converged_s is not None]
    return TuningRow(
        algorithm=c.algorithm,
        max_beams=c.max_beams,
        temper=c.temper,
        n_particles=c.n_particles,
        init_test_poses=c.init_test_poses,
        runs=len(outcomes),
        kept_all_rate=float(np.mean([o.kept_all for o in outcomes])),
        success_rate=float(np.mean([o.success for o in outcomes])),
        converged_runs=len(conv),
        converged_s=float(np.mean(conv)) if conv else None,
        likelihood_evaluations=float(np.mean([o.likelihood_evaluations for o in outcomes])),
        init_headings=c.init_headings,
    )


# ------------------------------------------------------------------ files
def tuning_markdown(result: TuningResult, meta: dict[str, Any], top: int = 5) -> str:
    header = [
        "algorithm",
        "max_beams",
        "temper",
        "N",
        "init_test_poses",
        "headings",
        "kept all",
        "success",
        "converged (s)",
        "evaluations / run",
    ]

    def cells(r: TuningRow) -> list[str]:
        return [
            r.algorithm,
            str(r.max_beams),
            f"{r.temper:g}",
            str(r.n_particles),
            f"{r.init_test_poses:,}",
            "scan" if r.init_headings else "uniform",
            pct(r.kept_all_rate),
            pct(r.success_rate),
            f"{fmt(r.converged_s)} ({r.converged_runs}/{r.runs})",
            f"{r.likelihood_evaluations:,.0f}",
        ]

    best = result.best()
    text = [
        f"# Tuning sweep on {result.settings.course.name}",
        "",
        f"{len(result.rows)} configurations x {result.rows[0].runs if result.rows else 0} "
        f"runs (base seed {result.settings.seed}). Score: kept all images, then success, "
        "then converged time, then fewer likelihood evaluations.",
        "",
        "## Chosen presets (each algorithm's best row)",
        "",
        markdown_table(header, [cells(best[a]) for a in best]),
    ]
    for alg in best:
        rows = [r for r in result.rows if r.algorithm == alg][:top]
        text += [
            f"## {alg}: the best {len(rows)}",
            "",
            markdown_table(header, [cells(r) for r in rows]),
        ]
    text.append(metadata_markdown(meta, result.settings.skipped))
    return "\n".join(text)


def write_tuning(
    result: TuningResult, out: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    """``tuning.csv`` (every configuration, best first per algorithm) and ``tuning.md``."""
    out_dir = ensure_output_dir(out)
    return [
        write_csv(out_dir / "tuning.csv", [asdict(r) for r in result.rows]),
        write_text(out_dir / "tuning.md", tuning_markdown(result, meta)),
    ]


def protocol_key(settings: ExperimentSettings) -> str:
    """A short digest of what a sweep's rows depend on besides the configuration: the course
    (map, routes with their numbers, simulator settings), the seed, the trials and the cut-off.
    Rows of another protocol are never taken for this one's."""
    c = settings.course
    what = {
        "course": [c.name, c.world, c.map_path, repr(c.config), c.transforms.tolist()],
        "routes": [[c.number(i), repr(r)] for i, r in enumerate(c.routes)],
        "seed": settings.seed,
        "trials": settings.trials,
        "max_time_s": settings.max_time_s,
    }
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()[:12]


def partial_path(out: str | os.PathLike[str], settings: ExperimentSettings) -> Path:
    """Where the CLI keeps the rows of a sweep in progress (resumed when run again with the
    same protocol, :func:`protocol_key`)."""
    return Path(out) / (
        f"tuning-partial-seed{settings.seed}-trials{settings.trials}-{protocol_key(settings)}.csv"
    )


def read_partial(out: str | os.PathLike[str], settings: ExperimentSettings) -> list[TuningRow]:
    """The rows an interrupted sweep of this protocol left in ``out`` (none: a new sweep)."""
    partial = partial_path(out, settings)
    return read_tuning_csv(partial) if partial.exists() else []


def finished_rows(done: Sequence[TuningRow], settings: ExperimentSettings) -> dict[Any, TuningRow]:
    """The configurations of ``done`` whose every run finished (resumed, not run again)."""
    per = len(settings.course.routes) * settings.trials
    return {r.candidate: r for r in done if r.runs == per}


def append_row(path: Path, row: TuningRow) -> None:
    """Append one row to a partial ``tuning.csv`` (its header first)."""
    new = not path.exists()
    with path.open("a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=[f.name for f in fields(TuningRow)])
        if new:
            writer.writeheader()
        writer.writerow({k: "" if v is None else v for k, v in asdict(row).items()})


def _flag(text: str) -> bool:
    """A ``tuning.csv`` boolean (``True`` / ``False``; absent in sweeps before the column)."""
    if text not in ("True", "False"):
        raise ValueError(f"init_headings: expected True or False, got {text!r}")
    return text == "True"


def read_tuning_csv(path: str | os.PathLike[str]) -> list[TuningRow]:
    """The rows of a ``tuning.csv`` written by :func:`write_tuning` (or :func:`append_row`)."""
    rows = []
    with Path(path).open(newline="") as fh:
        for i, r in enumerate(csv.DictReader(fh), start=2):
            try:
                rows.append(
                    TuningRow(
                        algorithm=r["algorithm"],
                        max_beams=int(r["max_beams"]),
                        temper=float(r["temper"]),
                        n_particles=int(r["n_particles"]),
                        init_test_poses=int(r["init_test_poses"]),
                        runs=int(r["runs"]),
                        kept_all_rate=float(r["kept_all_rate"]),
                        success_rate=float(r["success_rate"]),
                        converged_runs=int(r["converged_runs"]),
                        converged_s=float(r["converged_s"]) if r["converged_s"] else None,
                        likelihood_evaluations=float(r["likelihood_evaluations"]),
                        init_headings=_flag(r.get("init_headings") or "False"),
                    )
                )
            except (KeyError, ValueError) as exc:
                raise ConfigError(f"{path}:{i}: expected a tuning.csv row ({exc})") from None
    return rows


__all__ = [
    "BASELINES",
    "DEFAULT_GRID",
    "PRESETS",
    "TUNING_SEED",
    "Candidate",
    "TuningGrid",
    "TuningOutcome",
    "TuningResult",
    "TuningRow",
    "append_row",
    "best_rows",
    "candidates",
    "check_algorithms",
    "partial_path",
    "read_tuning_csv",
    "run_tuning",
    "run_tuning_trial",
    "score_key",
    "tuning_markdown",
    "tuning_trials",
    "write_tuning",
]
