"""``ceamcl evaluate-log``: global localisation from many start points of a real log, scored
per algorithm (success rate, time to converge, RMSE, particles, step time)."""

from __future__ import annotations

import argparse

from rich.console import Console

from ceamcl import budget
from ceamcl.checks import physical_warnings
from ceamcl.cli.common import TrialsProgress, plain_table, plural, positive_float, positive_int
from ceamcl.cli.experiment import RUN_BYTES
from ceamcl.cli.run import (
    add_log_arguments,
    add_truth_arguments,
    log_path,
    open_kwargs,
    print_truth,
)
from ceamcl.errors import ConfigError
from ceamcl.experiments.common import fmt, pct
from ceamcl.experiments.evaluate_log import evaluate_log
from ceamcl.experiments.log_windows import DEFAULT_WINDOW_M
from ceamcl.experiments.metrics import HOLD_STEPS
from ceamcl.filters import registry
from ceamcl.replay import obtain_map, prepare_log


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl evaluate-log``."""
    p = sub.add_parser(
        "evaluate-log",
        help="score global localisation from many start points of a real log",
        description="Global localisation from K start points spread over a SLAM-corrected "
        "log, each run over a window of the log, with every algorithm; writes evaluate.csv, "
        "evaluate.md, errors.png and success.png.",
    )
    add_log_arguments(p)
    p.add_argument(
        "--map", default=None, metavar="MAP.yaml", help="ROS map (default: built from the log)"
    )
    p.add_argument(
        "--resolution", type=positive_float, default=0.05, help="cell side of a built map [m]"
    )
    p.add_argument("--starts", type=positive_int, default=20, metavar="K", help="start points")
    p.add_argument(
        "--algorithms",
        nargs="+",
        choices=registry.names(),
        default=None,
        metavar="A",
        help=f"algorithms to run (default all: {', '.join(registry.names())})",
    )
    window = p.add_mutually_exclusive_group()
    window.add_argument(
        "--window-m",
        type=positive_float,
        default=None,
        metavar="M",
        help=f"each run covers M metres of travel (default {DEFAULT_WINDOW_M:g})",
    )
    window.add_argument(
        "--window-s",
        type=positive_float,
        default=None,
        metavar="S",
        help="each run covers S seconds of the log",
    )
    window.add_argument(
        "--scans", type=positive_int, default=None, metavar="N", help="each run covers N scans"
    )
    p.add_argument(
        "--hold",
        type=positive_int,
        default=HOLD_STEPS,
        help="steps a run must stay within tolerance at the end to count as a success",
    )
    add_truth_arguments(p)
    p.add_argument(
        "--executor",
        default="local",
        metavar="SPEC",
        help="where runs go: local (processes, default), serial, dask or dask://HOST:PORT",
    )
    p.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="worker processes for local/dask (default: CPU count)",
    )
    p.add_argument("--out", default="evaluate-out", help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress bar or table")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    algos, skipped = registry.resolve(args.algorithms)
    if not algos:
        raise ConfigError("algorithms: none of the chosen algorithms can run here")
    budget.require("--starts x algorithms", args.starts * len(algos), RUN_BYTES, "runs")
    prepared = prepare_log(
        log_path(args),
        seed=args.seed,
        truth=args.truth,
        repair_times=args.repair_times,
        **open_kwargs(args),
    )
    grid, map_source = obtain_map(prepared.log, args.map, args.resolution)
    physical_warnings(prepared.log, grid, args.map or f"the map built from {prepared.log.path}")
    if not args.quiet:
        console.print(f"map: {map_source}")
        print_truth(console, prepared)
        for name, why in skipped.items():
            console.print(f"[yellow]{name} skipped[/]: {why}")
    with TrialsProgress(console, quiet=args.quiet) as progress:
        ev = evaluate_log(
            prepared,
            grid,
            algos,
            starts=args.starts,
            scans=args.scans,
            window_s=args.window_s,
            window_m=args.window_m,
            hold=args.hold,
            map_source=map_source,
            executor=args.executor,
            workers=args.workers,
            out=args.out,
            progress=progress,
            skipped=skipped,
        )
    if not args.quiet:
        title = (
            f"evaluate-log {prepared.log.name}: {plural(len(ev.windows), 'start')}, "
            f"windows of {ev.window}"
        )
        header = (
            "algorithm",
            "success",
            "conv. [s]",
            "conv. [scans]",
            "pos RMSE [m]",
            "head RMSE [rad]",
            "particles",
            "step [ms]",
        )
        rows = [
            (
                row["algorithm"],
                pct(row["success_rate"]),
                fmt(row["time_to_converge_s"], 1, "-"),
                fmt(row["scans_to_converge"], 1, "-"),
                fmt(row["position_rmse_m"], 3, "-"),
                fmt(row["heading_rmse_rad"], 3, "-"),
                fmt(row["mean_particles"], 0, "-"),
                fmt(row["mean_step_ms"], 1, "-"),
            )
            for row in ev.table
        ]
        table = plain_table(title, header, rows)
        console.print(table)
        console.print(f"results written to [bold]{ev.out_dir}[/]")
    return 0
