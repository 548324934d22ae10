"""``ceamcl experiment``: the paper's experiments (Table 1, Figs. 4-7), marked-hall and the
kidnapped robot, over many seeded trials on local processes or a Dask cluster."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console

from ceamcl import budget
from ceamcl.cli.common import non_negative_int, positive_float, positive_int
from ceamcl.errors import ConfigError
from ceamcl.viz.outputs import OutputOptions, add_output_arguments

if TYPE_CHECKING:
    from ceamcl.experiments.common import ExperimentSettings, TrialOutputs
    from ceamcl.experiments.trials import TrialRecord

EXPERIMENTS: dict[str, str] = {
    "table1": "the paper's Table 1 and Figs. 4-6: every algorithm from each of the four rooms",
    "delta": "Fig. 7: CEAMCL's sample size over time for several delta",
    "marked": "marked-hall: share of runs whose final estimate is right",
    "kidnapped": "kidnapped robot on small-office: recovery rate and time",
}


def _names(text: str) -> list[str]:
    return [t for t in (p.strip() for p in text.split(",")) if t]


def _indices(text: str) -> list[int]:
    try:
        return [int(t) for t in _names(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated route numbers, got {text!r}"
        ) from None


def _floats(text: str) -> list[float]:
    return [positive_float(t) for t in _names(text)]


def _add_common(p: argparse.ArgumentParser, name: str, default_trials: int) -> None:
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
        help="algorithms to run, space- or comma-separated (default: all; see --help of "
        "`ceamcl experiment`)",
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
        "--starts",
        type=_indices,
        default=None,
        metavar="I,J",
        help="only these start routes (0-based; default all)",
    )
    p.add_argument("--seed", type=non_negative_int, default=0, help="base seed (default 0)")
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
    from ceamcl.experiments.algorithms import all_algorithms

    exp = sub.add_parser(
        "experiment",
        help="run the paper's experiments over many seeded trials",
        description="Run an experiment over many seeded trials. Algorithms: "
        + ", ".join(all_algorithms())
        + ". Definitions of every measure: docs/experiments.md.",
    )
    which = exp.add_subparsers(dest="experiment", required=True)
    for name, text in EXPERIMENTS.items():
        p = which.add_parser(name, help=text, description=text)
        _add_common(p, name, 10 if name == "kidnapped" else 5)
        if name == "delta":
            p.add_argument(
                "--deltas",
                type=_floats,
                default=None,
                metavar="D1,D2",
                help="resources per m² to compare (default 20,40,80,160)",
            )
        if name == "kidnapped":
            p.add_argument(
                "--recovery-window",
                type=positive_float,
                default=30.0,
                metavar="S",
                help="seconds after the kidnap within which the filter must relocalise "
                "(default 30)",
            )
        p.set_defaults(run=run)


def _settings(args: argparse.Namespace, console: Console) -> Any:
    from ceamcl.experiments.algorithms import resolve_algorithms
    from ceamcl.experiments.common import ExperimentSettings
    from ceamcl.experiments.routes import resolve_course

    names = None
    if args.algorithms is not None:
        names = [n for a in args.algorithms for n in _names(a)]
        if not names:
            raise ConfigError(
                f"algorithms: expected one or more algorithm names, got {args.algorithms!r} "
                "(leave --algorithms out to run all)"
            )
    course = resolve_course(args.experiment, args.world, args.routes).select(args.starts)
    skipped: dict[str, str] = {}
    if args.experiment == "delta":
        algorithms = ["ceamcl"]
        if names and names != ["ceamcl"]:
            raise ConfigError("algorithms: the delta experiment runs CEAMCL only")
    else:
        algorithms, skipped = resolve_algorithms(names)
    for alg, reason in skipped.items():
        console.print(f"[yellow]skipping {alg}[/]: {reason}")
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
    from ceamcl.experiments import delta, kidnapped, marked, table1
    from ceamcl.experiments.common import run_metadata
    from ceamcl.io.results import ensure_output_dir

    settings = _settings(args, console)
    outputs = _output_options(args)  # refuses --mp4 without ffmpeg before the trials
    runs = len(settings.algorithms) * len(settings.course.routes) * settings.trials
    if args.experiment == "delta":
        runs *= len(args.deltas or delta.DEFAULT_DELTAS)
    budget.require("--trials x routes x algorithms", runs, RUN_BYTES, "runs")
    ensure_output_dir(args.out)  # fail on an unwritable folder before hours of trials
    if not args.quiet:
        console.print(
            f"[bold]{args.experiment}[/] on {settings.course.name}: {runs} runs "
            f"({', '.join(settings.algorithms)}) on executor {settings.executor}"
        )
    meta = run_metadata(settings)
    started = time.perf_counter()
    write: Callable[[], list[Any]]
    if args.experiment == "table1":
        r1 = table1.run_table1(settings, console=console, quiet=args.quiet)
        records = r1.records
        table = table1.table1_rich(r1)
        write = lambda: table1.write_table1(r1, args.out, meta)  # noqa: E731
    elif args.experiment == "delta":
        r2 = delta.run_delta(
            settings, args.deltas or delta.DEFAULT_DELTAS, console=console, quiet=args.quiet
        )
        records = r2.records
        table = delta.delta_rich(r2)
        write = lambda: delta.write_delta(r2, args.out, meta)  # noqa: E731
    elif args.experiment == "marked":
        r3 = marked.run_marked(settings, console=console, quiet=args.quiet)
        records = r3.records
        table = marked.marked_rich(r3)
        write = lambda: marked.write_marked(r3, args.out, meta)  # noqa: E731
    else:
        r4 = kidnapped.run_kidnapped(
            settings, args.recovery_window, console=console, quiet=args.quiet
        )
        records = r4.records
        table = kidnapped.kidnapped_rich(r4)
        write = lambda: kidnapped.write_kidnapped(r4, args.out, meta)  # noqa: E731
    meta["wall_time_s"] = round(time.perf_counter() - started, 1)
    paths = write()
    if not args.quiet:
        console.print(table)
        console.print(
            f"{runs} runs in {meta['wall_time_s']:.1f} s; wrote "
            + ", ".join(p.name for p in paths)
            + f" to {args.out}"
        )
    if outputs.any:
        _write_run_outputs(records, settings, args, outputs, console)
    return 0


def _output_options(args: argparse.Namespace) -> OutputOptions:
    """The visual outputs asked for; ``--mcap FILE`` keeps only FILE's name, for a file in
    each algorithm's ``OUT/runs/ALGORITHM/`` folder."""
    options = OutputOptions.from_args({**vars(args), "mcap": None})
    if args.mcap is None:
        return options
    name = Path(args.mcap).name
    if not name or name in (".", ".."):
        raise ConfigError(f"mcap: expected a file name, got {args.mcap!r}")
    return replace(options, mcap=Path(name))


def _write_run_outputs(
    records: list[TrialRecord],
    settings: ExperimentSettings,
    args: argparse.Namespace,
    outputs: OutputOptions,
    console: Console,
) -> None:
    """Run the first trial of each algorithm again, with its particles, and write its visual
    outputs into ``OUT/runs/ALGORITHM/``."""
    from ceamcl.experiments.common import first_records

    for record in first_records(records):
        out_dir = Path(args.out) / "runs" / record.algorithm
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
    from ceamcl.cli.common import RunProgress, make_progress
    from ceamcl.experiments.common import write_trial_outputs

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
