"""``ceamcl experiment``: the paper's experiments (Table 1, Figs. 4-7), marked-hall and the
kidnapped robot, over many seeded trials on local processes or a Dask cluster."""

from __future__ import annotations

import argparse
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

from rich.console import Console, Group, RenderableType
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from ceamcl import budget
from ceamcl.cli.common import (
    RunProgress,
    TrialsProgress,
    add_output_arguments,
    algorithm_names,
    check_output_files,
    hush_dask_graph_warnings,
    make_progress,
    non_negative_int,
    plain_table,
    plural,
    positive_float,
    positive_int,
    warm_kernels,
    write_error,
)
from ceamcl.errors import ConfigError
from ceamcl.experiments import delta, kidnapped, marked, table1, tuning
from ceamcl.experiments import state as state_experiment
from ceamcl.experiments.common import (
    RUNS_FOLDER,
    ExperimentSettings,
    TrialOutputs,
    clear_earlier_runs,
    compact_count,
    first_records,
    fmt,
    pct,
    run_metadata,
    write_trial_outputs,
)
from ceamcl.experiments.delta import DeltaResult
from ceamcl.experiments.executors import ProgressCallback, check_executor
from ceamcl.experiments.kidnapped import KidnapResult
from ceamcl.experiments.marked import MarkedResult
from ceamcl.experiments.metrics import PrecisionSummary
from ceamcl.experiments.routes import resolve_course
from ceamcl.experiments.table1 import Table1Result
from ceamcl.experiments.trials import TrialRecord
from ceamcl.filters import registry
from ceamcl.io import created
from ceamcl.io.results import ensure_output_dir
from ceamcl.outputs import OutputOptions


@dataclass(frozen=True)
class Experiment:
    """One ``ceamcl experiment NAME``: how to run it, show it and write it.

    ``run(settings, args, progress)`` returns the experiment's result (with ``.records``);
    ``table(result)`` is the table printed; ``write(result, out, meta)`` writes its files.
    ``repeats(args)``: runs per trial (the delta experiment runs every trial once per delta);
    ``algorithms``: a fixed set of algorithms, or ``None`` for the registry's.
    ``default_algorithms``: what runs without ``--algorithms`` (``None``: every algorithm).
    ``default_seed``: the base seed without ``--seed``.
    ``count(settings, args)``: the exact number of runs where it is not algorithms x routes x
    trials x repeats (the tuning sweep; the state experiment's three scenarios and real logs),
    and ``where(args)`` names what it runs on.
    ``visuals``: whether its result keeps trial records to run again for the visual outputs
    (``--gif``, ``--mp4``, ``--report``, ``--mcap``); without, those flags are refused before
    any trial runs.
    ``check_algorithms(names)``: refuses names given with ``--algorithms`` that the
    experiment cannot run (the tuning sweep: the baselines only), before any work.
    ``files``: the names of the files ``write`` writes into ``--out`` (checked before the
    runs: a folder in the place of one is refused then, not after every run).
    """

    help: str
    default_trials: int
    run: Callable[[ExperimentSettings, argparse.Namespace, ProgressCallback], Any]
    table: Callable[[Any], RenderableType]
    write: Callable[[Any, str, dict[str, Any]], list[Path]]
    repeats: Callable[[argparse.Namespace], int] = lambda args: 1
    add_arguments: Callable[[argparse.ArgumentParser], None] = lambda p: None
    algorithms: tuple[str, ...] | None = None
    default_algorithms: tuple[str, ...] | None = None
    default_seed: int = 0
    count: Callable[[ExperimentSettings, argparse.Namespace], int] | None = None
    where: Callable[[argparse.Namespace], str] | None = None
    visuals: bool = True
    check_algorithms: Callable[[Sequence[str]], None] | None = None
    files: tuple[str, ...] = ()


# ---------------------------------------------------------------- the tables printed
#: The precision side's columns of the console tables (:func:`precision_row`); the weights
#: are shares at the goal, the nearest hypothesis' error its position and heading error.
PRECISION_COLUMNS = (
    "weight images / truth / spurious",
    "conf. wrong",
    "nearest [m, rad]",
    "evals/run",
)


def precision_row(p: PrecisionSummary, algorithm: str | None = None) -> tuple[str, ...]:
    """One row of :data:`PRECISION_COLUMNS`; with ``algorithm``, for an algorithm without a
    global localisation of its own the first figure reads "not comparable", the rest "-"."""
    measured: tuple[str, ...] = (
        f"{pct(p.true_image_weight)} / {pct(p.truth_weight)} / {pct(p.spurious_weight)}",
        pct(p.confidently_wrong_rate),
        f"{fmt(p.nearest_position_error_mean_m, 2, '-')}, "
        f"{fmt(p.nearest_heading_error_mean_rad, 2, '-')}",
    )
    if algorithm is not None:
        measured = tuple(registry.global_cells(algorithm, measured))
    return (*measured, compact_count(p.likelihood_evaluations, "not counted"))


def _notes(algorithms: Iterable[str]) -> list[Text]:
    """Beneath a table: why an algorithm's global-localisation figures are not comparable."""
    return [Text(note) for note in registry.global_notes(algorithms)]


def precision_table(
    title: str,
    labels: tuple[str, ...],
    rows: Sequence[tuple[tuple[str, ...], PrecisionSummary]],
    *,
    global_localisation: bool = True,
) -> Table:
    """The precision side (docs/experiments.md) as its own plain table: one row per label,
    whose first element is the algorithm; ``global_localisation``: the rows measure a global
    localisation (an algorithm without one of its own reads "not comparable")."""
    return plain_table(
        f"{title}: precision side (docs/experiments.md)",
        (*labels, *PRECISION_COLUMNS),
        [
            (*label, *precision_row(p, label[0] if global_localisation else None))
            for label, p in rows
        ],
        left=len(labels),
    )


def table1_rich(result: Table1Result) -> Group:
    n_images = result.settings.course.n_images
    header = (
        "algorithm",
        "conv. [s]",
        "exp. [s]",
        "success",
        f"all {n_images}",
        "err [m]",
        "N",
        "step [ms]",
    )
    rows = []
    for s in result.summaries:
        exp = (
            "-"
            if s.converged_runs == 0
            else f"{fmt(s.expired_s)} {s.expired_runs}/{s.converged_runs}"
        )
        # figures of a global localisation: "not comparable" in the success column, "-" in
        # the rest, for an algorithm without one of its own
        follows = partial(registry.global_cell, s.algorithm, instead="-")
        rows.append(
            (
                s.algorithm,
                follows(f"{fmt(s.converged_s)} {s.converged_runs}/{s.runs}"),
                follows(exp),
                registry.global_cell(s.algorithm, pct(s.success_rate)),
                follows(pct(s.kept_all_rate)),
                follows(fmt(s.final_error_mean_m, 2, "-")),
                registry.particles_cell(s.algorithm, fmt(s.mean_particles, 0, "-")),
                fmt(s.median_step_ms, 1, "-"),
            )
        )
    name = result.settings.course.name
    return Group(
        plain_table(f"Table 1 on {name} (docs/experiments.md)", header, rows),
        precision_table(
            f"At the goal on {name}",
            ("algorithm",),
            [((s.algorithm,), s.precision) for s in result.summaries],
        ),
        *_notes(s.algorithm for s in result.summaries),
    )


def delta_rich(result: DeltaResult) -> Table:
    t = Table(title=f"delta on {result.settings.course.name}")
    for col in ("delta", "runs", "initial", "mean", "final", "kept all", "success"):
        t.add_column(col, justify="right")
    for s in result.summaries:
        t.add_row(*delta.summary_cells(s))
    return t


def marked_rich(result: MarkedResult) -> Group:
    """The final estimate right per start route, then the precision side per start route."""
    name = result.settings.course.name
    cols = marked.route_columns(result)
    right = plain_table(
        f"final estimate right on {name}, per start route",
        ("algorithm", *cols),
        [
            (alg, *(registry.global_cell(alg, pct(by_route.get(c))) for c in cols))
            for alg, by_route in result.shares.items()
        ],
    )
    per_route = [
        ((alg, c), result.precision[alg][c])
        for alg in result.shares
        for c in cols
        if c in result.precision[alg]
    ]
    return Group(
        right,
        precision_table(f"At the goal on {name}", ("algorithm", "route"), per_route),
        *_notes(result.shares),
    )


def kidnapped_rich(result: KidnapResult) -> Group:
    header = ("algorithm", "runs", "localised before", "recovered", "recovery [s]")
    rows = [
        (
            s.algorithm,
            str(s.runs),
            # the start is a global localisation: not comparable for a filter without one
            registry.global_cell(s.algorithm, pct(s.localised_before_rate)),
            pct(s.recovery_rate),
            fmt(s.mean_recovery_s, 1, "-"),
        )
        for s in result.summaries
    ]
    name = result.settings.course.name
    return Group(
        plain_table(f"kidnapped robot on {name}", header, rows),
        precision_table(
            f"At the end on {name}",
            ("algorithm",),
            [((s.algorithm,), s.precision) for s in result.summaries],
            # after the kidnap every filter finds the robot again by its own recovery (the
            # Nav2 peer by the wheel's random particles), a comparable figure
            global_localisation=False,
        ),
        *_notes(s.algorithm for s in result.summaries),
    )


def state_rich(result: state_experiment.StateResult) -> Table:
    """The table of ``state.md``, with its figures as it prints them."""
    header = ("algorithm", "state", "precision", "recall", "support (true)", "said")
    rows = [(s.algorithm, s.state, *state_experiment.score_cells(s)) for s in result.scores]
    return plain_table(
        f"localisation state on {', '.join(result.courses)} (every step after the first)",
        header,
        rows,
    )


def _state_courses(args: argparse.Namespace) -> Any:
    """The state experiment's scenarios: the three built-in ones, or the one --world or
    --routes names."""
    if args.world is None and args.routes is None:
        return state_experiment.default_courses()
    return (resolve_course("state", args.world, args.routes).select(args.starts),)


def _state_real_logs(args: argparse.Namespace) -> bool:
    """The real logs are scored with the built-in scenarios, not with --world, --routes or a
    --max-time quick check."""
    return args.world is None and args.routes is None and args.max_time is None


def _state_runs(settings: ExperimentSettings, args: argparse.Namespace) -> int:
    """Runs of the state experiment: the scenarios' routes x trials x algorithms, and one
    run a real log whose files are present x algorithms (they are prepared later)."""
    courses = _state_courses(args)
    runs = sum(len(c.routes) for c in courses) * settings.trials * len(settings.algorithms)
    if _state_real_logs(args):
        present = state_experiment.present_real_logs()
        runs += len(present) * len(settings.algorithms)
    return runs


def _delta_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--deltas",
        type=_distinct_floats,
        default=None,
        metavar="D1,D2",
        help="resources per m² to compare (default 20,40,80,160)",
    )


def _kidnapped_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--recovery-window",
        type=positive_float,
        default=30.0,
        metavar="S",
        help="seconds after the kidnap within which the filter must relocalise (default 30)",
    )


def tuning_rich(result: tuning.TuningResult) -> Table:
    header = (
        "algorithm",
        "beams",
        "temper",
        "N",
        "N_test",
        "headings",
        "kept all",
        "success",
        "conv. [s]",
    )
    rows = [
        (
            f"{tuning.PRESETS[r.algorithm]} = {r.algorithm}",
            str(r.max_beams),
            f"{r.temper:g}",
            str(r.n_particles),
            f"{r.init_test_poses:,}",
            "scan" if r.init_headings else "uniform",
            pct(r.kept_all_rate),
            pct(r.success_rate),
            f"{fmt(r.converged_s)} {r.converged_runs}/{r.runs}",
        )
        for r in result.best().values()
    ]
    return plain_table("tuning sweep: the best row of each baseline", header, rows)


def _counts(minimum: int) -> Callable[[str], list[int]]:
    """argparse type: comma-separated whole numbers of at least ``minimum`` (``1e6`` is read as
    1000000; ``1.7``, ``inf`` or ``nan`` are refused, not truncated or left to fail later)."""

    def parse(text: str) -> list[int]:
        values = []
        for t in _names(text):
            try:
                v = float(t)
            except ValueError:
                v = math.nan
            if not (math.isfinite(v) and v == int(v) and v >= minimum):
                raise argparse.ArgumentTypeError(
                    f"expected comma-separated whole numbers >= {minimum}, got {t!r} in {text!r}"
                )
            values.append(int(v))
        return _once(values, text)

    return parse


def _once(values: list[Any], text: str) -> list[Any]:
    """``values`` when there is at least one and none repeats (a value given twice ran once
    but was counted twice; an empty list ran the defaults without a word)."""
    if not values:
        raise argparse.ArgumentTypeError(f"expected one or more values, got {text!r}")
    twice = next((v for i, v in enumerate(values) if v in values[:i]), None)
    if twice is not None:
        raise argparse.ArgumentTypeError(f"{twice:g} given twice in {text!r}; expected each once")
    return values


def _tuning_arguments(p: argparse.ArgumentParser) -> None:
    g = tuning.DEFAULT_GRID

    def listed(values: tuple[Any, ...]) -> str:
        return ",".join(f"{v:g}" for v in values)

    p.add_argument(
        "--max-beams",
        type=_counts(1),
        default=None,
        metavar="B1,B2",
        help=f"max_beams values (default {listed(g.max_beams)})",
    )
    p.add_argument(
        "--tempers",
        type=_distinct_floats,
        default=None,
        metavar="T1,T2",
        help=f"temper values, product scoring only (default {listed(g.temper)})",
    )
    p.add_argument(
        "--particle-counts",
        type=_counts(1),
        default=None,
        metavar="N1,N2",
        help=f"particle counts (default {listed(g.n_particles)})",
    )
    p.add_argument(
        "--init-test-poses",
        type=_counts(0),
        default=None,
        metavar="M1,M2",
        help=f"initialisation budgets (default {listed(g.init_test_poses)})",
    )
    p.add_argument(
        "--init-headings",
        type=_headings,
        default=None,
        metavar="H1,H2",
        help="the test poses' headings: uniform, scan (drawn from the scan's geometry, as "
        "CEAMCL's) or both (default uniform,scan; scan only where there are test poses)",
    )


def _headings(text: str) -> list[bool]:
    names = _names(text)
    bad = [t for t in names if t not in ("uniform", "scan")]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"expected a comma-separated list of uniform and scan, got {text!r}"
        )
    return [t == "scan" for t in names]


def _tuning_grid(args: argparse.Namespace) -> tuning.TuningGrid:
    g = tuning.DEFAULT_GRID
    return tuning.TuningGrid(
        max_beams=tuple(args.max_beams or g.max_beams),
        temper=tuple(args.tempers or g.temper),
        n_particles=tuple(args.particle_counts or g.n_particles),
        init_test_poses=tuple(
            args.init_test_poses if args.init_test_poses is not None else g.init_test_poses
        ),
        init_headings=tuple(args.init_headings or g.init_headings),
    )


def _run_tuning(
    settings: ExperimentSettings, args: argparse.Namespace, progress: ProgressCallback
) -> tuning.TuningResult:
    """The sweep, each finished configuration appended to OUT/tuning-partial-*.csv; a sweep
    run again with the same --out and protocol (course, routes, --seed, --trials, --max-time:
    :func:`ceamcl.experiments.tuning.protocol_key`) goes on where it stopped.

    Once a row is in that file, an OUT the command created is kept even if the sweep then fails
    or is interrupted (the rule that removes it, :mod:`ceamcl.io.created`, deleted the
    finished rows with it, so the sweep could not resume)."""
    partial = tuning.partial_path(args.out, settings)

    def keep(row: tuning.TuningRow) -> None:
        tuning.append_row(partial, row)
        created.forget()  # OUT holds finished work now: keep it, whatever happens next

    return tuning.run_tuning(
        settings,
        _tuning_grid(args),
        progress=progress,
        done=tuning.read_partial(args.out, settings),
        on_row=keep,
    )


def _tuning_runs(settings: ExperimentSettings, args: argparse.Namespace) -> int:
    """Runs of the sweep: configurations x routes x trials, without the configurations a
    resumed sweep has already run."""
    cands = tuning.candidates(settings.algorithms, _tuning_grid(args))
    finished = tuning.finished_rows(tuning.read_partial(args.out, settings), settings)
    return sum(c not in finished for c in cands) * len(settings.course.routes) * settings.trials


#: The experiments, in the order ``--help`` lists them. Adding one: its module under
#: ``experiments/`` and one entry here.
EXPERIMENTS: dict[str, Experiment] = {
    "table1": Experiment(
        "the paper's Table 1 and Figs. 4-6: every algorithm from each of the four rooms",
        5,
        lambda settings, args, progress: table1.run_table1(settings, progress=progress),
        table1_rich,
        table1.write_table1,
        files=(
            "table1.csv",
            "trials.csv",
            "fig4_error.png",
            "fig5_step_time.png",
            "fig6_resources.png",
            "table1.md",
        ),
    ),
    "delta": Experiment(
        "Fig. 7: CEAMCL's sample size over time for several delta",
        5,
        lambda settings, args, progress: delta.run_delta(
            settings, args.deltas or delta.DEFAULT_DELTAS, progress=progress
        ),
        delta_rich,
        delta.write_delta,
        repeats=lambda args: len(args.deltas or delta.DEFAULT_DELTAS),
        add_arguments=_delta_arguments,
        algorithms=("ceamcl",),
        files=("delta.csv", "trials.csv", "fig7_delta.png", "delta.md"),
    ),
    "marked": Experiment(
        "marked-hall: share of runs whose final estimate is right",
        5,
        lambda settings, args, progress: marked.run_marked(settings, progress=progress),
        marked_rich,
        marked.write_marked,
        files=("marked.csv", "trials.csv", "marked.png", "marked.md"),
    ),
    "kidnapped": Experiment(
        "kidnapped robot on small-office: recovery rate and time",
        10,
        lambda settings, args, progress: kidnapped.run_kidnapped(
            settings, args.recovery_window, progress=progress
        ),
        kidnapped_rich,
        kidnapped.write_kidnapped,
        add_arguments=_kidnapped_arguments,
        files=("kidnapped.csv", "trials.csv", "kidnapped.png", "kidnapped.md"),
    ),
    "tune": Experiment(
        "the tuning sweep behind mcl-tuned, gmcl-tuned, kld-amcl-tuned (docs/tuning.md): "
        "Table 1's protocol for each baseline over a grid of beams, temper, N and N_test",
        3,
        lambda settings, args, progress: _run_tuning(settings, args, progress),
        tuning_rich,
        tuning.write_tuning,
        count=_tuning_runs,
        add_arguments=_tuning_arguments,
        default_algorithms=tuning.BASELINES,
        default_seed=tuning.TUNING_SEED,
        visuals=False,  # one row per configuration: no run to draw
        check_algorithms=tuning.check_algorithms,
        files=("tuning.csv", "tuning.md"),
    ),
    "state": Experiment(
        "the localisation state (LOCALISED / AMBIGUOUS / LOST): precision and recall on "
        "kidnapped small-office, symmetric-hall and marked-hall",
        5,
        lambda settings, args, progress: state_experiment.run_state(
            settings,
            _state_courses(args),
            real_logs=_state_real_logs(args),
            progress=progress,
        ),
        state_rich,
        state_experiment.write_state,
        default_algorithms=state_experiment.DEFAULT_ALGORITHMS,
        visuals=False,  # its runs keep their states, not their particles
        count=_state_runs,
        where=lambda args: ", ".join(c.name for c in _state_courses(args)),
        files=("state.csv", "state_by_scenario.csv", "state.md", "state.png"),
    ),
}


def _names(text: str) -> list[str]:
    return [t for t in (p.strip() for p in text.split(",")) if t]


def _indices(text: str) -> list[int]:
    """argparse type: comma-separated route numbers, at least one (an empty or blank list ran
    no route: empty tables, or a traceback in kidnapped and delta)."""
    try:
        numbers = [int(t) for t in _names(text)]
    except ValueError:
        numbers = []
    if not numbers:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated route numbers (one or more), got {text!r}"
        )
    return numbers


def _floats(text: str) -> list[float]:
    return [positive_float(t) for t in _names(text)]


def _distinct_floats(text: str) -> list[float]:
    """Comma-separated positive numbers, at least one, each once (:func:`_once`)."""
    return _once(_floats(text), text)


def _add_common(
    p: argparse.ArgumentParser,
    name: str,
    default_trials: int,
    fixed: tuple[str, ...] | None = None,
    default_seed: int = 0,
    default_algorithms: tuple[str, ...] | None = None,
) -> None:
    p.add_argument(
        "--trials",
        type=positive_int,
        default=default_trials,
        help=f"seeded trials per start route (default {default_trials})",
    )
    p.add_argument(
        "--algorithms",
        nargs="+",
        default=None,
        metavar="NAME",
        help="algorithms to run, space- or comma-separated (default: "
        + ("all" if default_algorithms is None else ", ".join(default_algorithms))
        + "; see --help of `ceamcl experiment`)"
        if fixed is None
        else f"only {', '.join(fixed)}: the {name} experiment is about {', '.join(fixed)} "
        "alone, other names are refused",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument("--world", default=None, help="built-in world to run on")
    where.add_argument(
        "--routes",
        default=None,
        metavar="FILE",
        help="YAML route file with a ROS map (docs/experiments.md): run on your own building",
    )
    p.add_argument(
        "--start-routes",
        dest="starts",
        type=_indices,
        default=None,
        metavar="I,J",
        help="only these start routes, by number (0-based; default all)",
    )
    # evaluate-log's --starts is a count of start points; here the routes are chosen by number
    p.add_argument("--starts", dest="starts_count", default=None, help=argparse.SUPPRESS)
    p.add_argument(
        "--seed",
        type=non_negative_int,
        default=default_seed,
        help=f"base seed (default {default_seed})",
    )
    p.add_argument(
        "--executor",
        default="local",
        metavar="SPEC",
        help="where trials run: local (processes, default), serial, dask (a local Dask "
        "cluster) or dask://HOST:PORT (an existing scheduler)",
    )
    p.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="worker processes for local/dask (default: CPU count)",
    )
    p.add_argument(
        "--max-time",
        type=positive_float,
        default=None,
        metavar="S",
        help="cut every run after S seconds (quick checks only; not the paper's protocol)",
    )
    p.add_argument("--out", default=f"experiment-{name}", help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress bar or table")
    # After the trials, the first trial of each algorithm is run again with its particles
    # kept and drawn into OUT/runs/ALGORITHM/ (docs/outputs.md); --mcap FILE names a file there.
    add_output_arguments(p, animation_default=False)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl experiment {table1,delta,marked,kidnapped}``."""
    exp = sub.add_parser(
        "experiment",
        help="run the paper's experiments over many seeded trials",
        description="Run an experiment over many seeded trials. Algorithms: "
        + ", ".join(registry.names())
        + ". Definitions of every measure: docs/experiments.md.",
    )
    which = exp.add_subparsers(dest="experiment", required=True)
    for name, experiment in EXPERIMENTS.items():
        p = which.add_parser(name, help=experiment.help, description=experiment.help)
        _add_common(
            p,
            name,
            experiment.default_trials,
            experiment.algorithms,
            experiment.default_seed,
            experiment.default_algorithms,
        )
        experiment.add_arguments(p)
        p.set_defaults(run=run)


def _settings(args: argparse.Namespace, console: Console) -> ExperimentSettings:
    names = algorithm_names(args.algorithms)
    if args.starts_count is not None:
        raise ConfigError(
            f"starts: --starts {args.starts_count} is evaluate-log's count of start points; an "
            "experiment's start routes are chosen by number with --start-routes I,J (0-based)"
        )
    if args.experiment == "state" and args.world is None and args.routes is None:
        if args.starts is not None:  # each built-in scenario numbers its own routes
            raise ConfigError(
                "start-routes: the state experiment's three scenarios each have their own "
                "routes; choose one with --world or --routes to pick its start routes"
            )
    course = resolve_course(args.experiment, args.world, args.routes).select(args.starts)
    skipped: dict[str, str] = {}
    fixed = EXPERIMENTS[args.experiment].algorithms
    if fixed is not None:
        algorithms = list(fixed)
        if names and names != algorithms:
            raise ConfigError(
                f"algorithms: the {args.experiment} experiment runs {', '.join(fixed)} only, "
                f"got {', '.join(names)}"
            )
    else:
        wanted = names if names is not None else EXPERIMENTS[args.experiment].default_algorithms
        algorithms, skipped = registry.resolve(wanted)  # an unknown name first
        check = EXPERIMENTS[args.experiment].check_algorithms
        if check is not None and names is not None:
            check(names)
    for alg, reason in skipped.items():
        console.print(f"[yellow]skipping {alg}[/]: {escape(reason)}")
    if not algorithms:
        raise ConfigError("algorithms: nothing left to run")
    return ExperimentSettings(
        course=course,
        algorithms=tuple(algorithms),
        trials=args.trials,
        seed=args.seed,
        executor=args.executor,
        workers=args.workers,
        max_time_s=args.max_time,
        skipped=tuple(skipped.items()),
    )


#: Memory a finished trial's record holds (its error and sample-size series).
RUN_BYTES = 256 * 1024


def run(args: argparse.Namespace, console: Console) -> int:
    experiment = EXPERIMENTS[args.experiment]
    check_executor(args.executor, args.workers)  # before any course or log is prepared
    if args.quiet:
        hush_dask_graph_warnings()
    settings = _settings(args, console)
    outputs = _output_options(args)  # refuses --mp4 without ffmpeg before the trials
    if outputs.any and not experiment.visuals:
        raise ConfigError(
            f"--gif/--mp4/--report/--mcap: the {args.experiment} experiment writes tables, "
            "not runs to draw; expected none of these flags (ceamcl experiment table1, marked, "
            "delta and kidnapped draw their first run of each algorithm)"
        )
    place = settings.course.name if experiment.where is None else experiment.where(args)
    if experiment.count is not None:
        runs = experiment.count(settings, args)
    else:
        runs = len(settings.algorithms) * len(settings.course.routes) * settings.trials
        runs *= experiment.repeats(args)
    budget.require("--trials x routes x algorithms", runs, RUN_BYTES, "runs")
    ensure_output_dir(args.out)  # fail on an unwritable folder before hours of trials
    check_output_files(args.out, experiment.files, f"experiment {args.experiment}")
    if not args.quiet:
        console.print(
            f"[bold]{args.experiment}[/] on {place}: {plural(runs, 'run')} "
            f"({', '.join(settings.algorithms)}) on executor {settings.executor}"
        )
    meta = run_metadata(settings)
    started = time.perf_counter()
    with TrialsProgress(console, quiet=args.quiet) as progress:
        warm_kernels(progress.progress)
        result = experiment.run(settings, args, progress)
    meta["wall_time_s"] = round(time.perf_counter() - started, 1)
    paths = _write_staged(experiment, result, Path(args.out), meta)
    # OUT holds finished tables now: an interrupted or failed re-run for the visual outputs
    # must not remove the folder the command created (ceamcl.io.created)
    created.forget()
    if experiment.visuals:  # OUT/runs/ holds the runs of these tables only
        clear_earlier_runs(args.out)
    if not args.quiet:
        console.print(experiment.table(result))
        console.print(
            f"{plural(runs, 'run')} in {meta['wall_time_s']:.1f} s; wrote "
            + ", ".join(p.name for p in paths)
            + f" to {args.out}"
        )
    if outputs.any:
        _write_run_outputs(result.records, settings, args, outputs, console)
    return 0


def _write_staged(
    experiment: Experiment, result: Any, out: Path, meta: dict[str, Any]
) -> list[Path]:
    """``experiment.write`` into a new folder inside ``out``, then each file moved over
    ``out``'s: a write that fails (a full disk, a permission) leaves ``out``'s earlier files
    as they were instead of some new and some old, and is one line naming the file."""
    try:
        staging = Path(tempfile.mkdtemp(prefix=".ceamcl-writing-", dir=out))
    except OSError as exc:
        raise write_error(exc, out) from None
    try:
        try:
            paths = experiment.write(result, str(staging), meta)
        except OSError as exc:
            raise write_error(exc, out) from None
        # ``files`` was checked before the runs: it must name what ``write`` writes
        assert {p.name for p in staging.iterdir()} <= set(experiment.files), experiment.files
        for staged in sorted(staging.iterdir()):
            try:
                os.replace(staged, out / staged.name)
            except OSError as exc:
                raise write_error(exc, out) from None
        return [out / p.name for p in paths]
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _output_options(args: argparse.Namespace) -> OutputOptions:
    """The visual outputs asked for; ``--mcap NAME`` is a file name, written in each
    algorithm's ``OUT/runs/ALGORITHM/`` folder (a path with folders is refused: its folders
    would be dropped without a word)."""
    options = OutputOptions.from_args({**vars(args), "mcap": None})
    if args.mcap is None:
        return options
    path = Path(args.mcap)
    if path.name in ("", ".", "..") or path.parent != Path("."):
        raise ConfigError(
            f"mcap: expected a file name (each algorithm's is written to OUT/runs/ALGORITHM/), "
            f"got {args.mcap!r}"
        )
    return replace(options, mcap=path)


def _write_run_outputs(
    records: list[TrialRecord],
    settings: ExperimentSettings,
    args: argparse.Namespace,
    outputs: OutputOptions,
    console: Console,
) -> None:
    """Run the first trial of each algorithm again, with its particles, and write its visual
    outputs into ``OUT/runs/ALGORITHM/``."""
    for record in first_records(records):
        out_dir = Path(args.out) / RUNS_FOLDER / record.algorithm
        done = _rerun(record, settings, out_dir, outputs, console, quiet=args.quiet)
        if not done.same_as_record:
            console.print(
                f"[yellow]warning[/]: the re-run of {record.algorithm}'s first trial differs "
                "from the trial the experiment counted (its summary.json says so)"
            )
        if not args.quiet:
            console.print(
                f"{record.algorithm}: wrote "
                + ", ".join(p.name for p in done.files)
                + f" to {done.out_dir}"
            )


def _rerun(
    record: TrialRecord,
    settings: ExperimentSettings,
    out_dir: Path,
    outputs: OutputOptions,
    console: Console,
    *,
    quiet: bool,
) -> TrialOutputs:
    """One re-run with progress bars over its steps and the animation's frames."""
    progress = make_progress(
        f"[bold]{record.algorithm}[/] on {record.route}, repetition {record.repetition}, "
        "again for the visual outputs",
        console,
        quiet=quiet,
    )
    with progress:
        bar = RunProgress(progress)
        return write_trial_outputs(
            record,
            settings,
            out_dir,
            outputs,
            on_start=bar.start,
            on_step=bar.step,
            on_frame=bar.frame,
        )
