"""``ceamcl evaluate-log``: global localisation from many start points of a real log, scored
per algorithm (success rate, time to converge, RMSE, particles, step time)."""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.markup import escape

from ceamcl import budget
from ceamcl.cli.common import (
    TrialsProgress,
    algorithm_names,
    check_output_files,
    check_particles,
    hush_dask_graph_warnings,
    plain_table,
    plural,
    positive_float,
    positive_int,
    warm_kernels,
)
from ceamcl.cli.experiment import RUN_BYTES
from ceamcl.cli.run import (
    add_log_arguments,
    add_map_arguments,
    add_pace_arguments,
    add_sensor_argument,
    add_truth_arguments,
    open_inputs,
    print_sensor_note,
    print_truth,
    truth_doubt,
)
from ceamcl.errors import ConfigError
from ceamcl.experiments.common import fmt, pct
from ceamcl.experiments.evaluate_log import evaluate_log
from ceamcl.experiments.executors import Batch, check_executor
from ceamcl.experiments.log_windows import DEFAULT_WINDOW_M
from ceamcl.experiments.metrics import DEFAULT_HOLD_M, HOLD_STEPS
from ceamcl.experiments.tracking_log import DEFAULT_TRACKING_PARTICLES, track_log
from ceamcl.filters import registry
from ceamcl.io.results import ensure_output_dir
from ceamcl.io.truth_check import TruthDoubt
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.replay import PreparedLog, UpdatePace

#: Start points of the windowed protocol when --starts is not given.
DEFAULT_STARTS = 20


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
    add_map_arguments(p)
    p.add_argument(
        "--starts",
        type=positive_int,
        default=None,
        metavar="K",
        help=f"start points of the windowed protocol (default: {DEFAULT_STARTS})",
    )
    p.add_argument(
        "--algorithms",
        nargs="+",
        default=None,
        metavar="A",
        help="algorithms to run, space- or comma-separated, as for `ceamcl experiment` "
        f"(default all: {', '.join(registry.names())})",
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
    hold = p.add_mutually_exclusive_group()
    hold.add_argument(
        "--hold-m",
        type=positive_float,
        default=None,
        metavar="M",
        help=f"metres of travel a run must stay within tolerance at the end to count as a "
        f"success (default {DEFAULT_HOLD_M:g}; the whole window when shorter)",
    )
    hold.add_argument(
        "--hold",
        type=positive_int,
        default=None,
        metavar="N",
        help="... or N scans instead of metres",
    )
    add_truth_arguments(p)
    add_pace_arguments(p)
    add_sensor_argument(p)
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
    p.add_argument(
        "--tracking",
        action="store_true",
        help="pose tracking instead of global localisation: every algorithm starts from the "
        "true pose moved 0.5 m and turned 0.3 rad (seeded) and runs over the whole log; "
        "reports the APE (RMSE, median, max) and writes TUM files for evo_ape",
    )
    p.add_argument(
        "--particles",
        type=positive_int,
        default=None,
        metavar="N",
        help=f"--tracking: the particle budget of every algorithm (default "
        f"{DEFAULT_TRACKING_PARTICLES}, Nav2's max_particles)",
    )
    p.add_argument("--out", default="evaluate-out", help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress bar or table")
    p.set_defaults(run=run)


def _check_mode(args: argparse.Namespace) -> None:
    """Options of one mode refused in the other, before any work (each would be ignored)."""
    if args.tracking:
        windowed = {
            "starts": args.starts is not None,
            "window-m": args.window_m is not None,
            "window-s": args.window_s is not None,
            "scans": args.scans is not None,
            "hold-m": args.hold_m is not None,
            "hold": args.hold is not None,
        }
        given = [f"--{k}" for k, v in windowed.items() if v]
        if given:
            raise ConfigError(
                f"{given[0][2:]}: {', '.join(given)} only with the windowed protocol; --tracking "
                "runs the whole log from one start"
            )
        if args.particles is not None:
            check_particles(args.particles)
    elif args.particles is not None:
        raise ConfigError("particles: only with --tracking (global localisation uses defaults)")
    check_executor(args.executor, args.workers)


def run(args: argparse.Namespace, console: Console) -> int:
    _check_mode(args)
    if args.quiet:
        hush_dask_graph_warnings()
    algos, skipped = registry.resolve(algorithm_names(args.algorithms))
    if not algos:
        raise ConfigError("algorithms: none of the chosen algorithms can run here")
    starts = DEFAULT_STARTS if args.starts is None else args.starts
    runs = len(algos) if args.tracking else starts * len(algos)
    budget.require("--starts x algorithms", runs, RUN_BYTES, "runs")
    prepared, grid, map_source, pace = open_inputs(args)
    # a folder that cannot take the results is refused before the runs, not after them
    ensure_output_dir(args.out)
    files = (
        ["tracking.csv", "tracking.md", "groundtruth.tum", "ape.png"]
        + [f"tracking-{a}.tum" for a in algos]
        if args.tracking
        else ["evaluate.csv", "evaluate.md", "errors.png", "success.png"]
    )
    check_output_files(args.out, files, "evaluate-log")
    doubt = truth_doubt(prepared, grid)
    if not args.quiet:
        console.print(f"map: {map_source}", markup=False)
        print_truth(console, prepared, doubt)
        console.print(
            f"filter updates (every algorithm): {'every scan' if pace is None else pace.describe()}"
        )
        console.print(f"sensor model: {registry.describe_sensor(args.sensor)}", markup=False)
        print_sensor_note(console, args.sensor, algos)
        for name, why in skipped.items():
            console.print(f"[yellow]{name} skipped[/]: {escape(why)}")
    if args.tracking:
        return run_tracking(args, console, prepared, grid, map_source, algos, skipped, pace, doubt)
    with TrialsProgress(console, quiet=args.quiet) as progress:
        warm_kernels(progress.progress, args.sensor, algos)
        ev = evaluate_log(
            prepared,
            grid,
            algos,
            starts=starts,
            scans=args.scans,
            window_s=args.window_s,
            window_m=args.window_m,
            hold=HOLD_STEPS if args.hold is None else args.hold,
            hold_m=None if args.hold is not None else (args.hold_m or DEFAULT_HOLD_M),
            map_source=map_source,
            executor=args.executor,
            workers=args.workers,
            out=args.out,
            progress=progress,
            skipped=skipped,
            pace=pace,
            truth_doubt=doubt,
            sensor=args.sensor,
        )
    if not args.quiet:
        title = (
            f"evaluate-log {prepared.log.name}: {plural(len(ev.windows), 'start')}, "
            f"windows of {ev.window}"
        )
        header = (
            "algorithm",
            "success",
            "conf. wrong",
            "conv. [s]",
            "conv. [m]",
            "pos RMSE [m]",
            "from 1st [m]",
            "head RMSE [rad]",
            "particles",
            "median step [ms]",
        )
        rows = [
            (
                row["algorithm"],
                *registry.global_cells(
                    row["algorithm"],
                    (
                        pct(row["success_rate"]),
                        str(row["confidently_wrong"]),
                        fmt(row["time_to_converge_s"], 1, "-"),
                        fmt(row["distance_to_converge_m"], 1, "-"),
                        fmt(row["position_rmse_m"], 3, "-"),
                        fmt(row["position_rmse_from_first_m"], 3, "-"),
                        fmt(row["heading_rmse_rad"], 3, "-"),
                    ),
                ),
                registry.particles_cell(row["algorithm"], fmt(row["mean_particles"], 0, "-")),
                fmt(row["median_step_ms"], 1, "-"),
            )
            for row in ev.table
        ]
        console.print(plain_table(title, header, rows))
        if pace is not None:  # most scans only add their odometry: the median step is ~0 ms
            updates = ", ".join(
                f"{row['algorithm']} {fmt(row['mean_update_ms'], 1, '-')} / "
                f"{fmt(row['median_update_ms'], 1, '-')} ms"
                for row in ev.table
            )
            console.print(f"update mean / median (the scans that updated the filter): {updates}")
        for row in ev.paired:  # issue 17's "at equal success"
            console.print(
                f"evaluations where both localised ({row['windows']} windows): "
                f"{row['algorithm']} {fmt(row['evaluations'], 0, '-')}, {row['against']} "
                f"{fmt(row['against_evaluations'], 0, '-')}, ratio {fmt(row['ratio'], 3, '-')}",
                markup=False,
            )
        for note in registry.global_notes(row["algorithm"] for row in ev.table):
            console.print(note, highlight=False)
        console.print(f"results written to [bold]{escape(str(ev.out_dir))}[/]")
    return 0


def run_tracking(
    args: argparse.Namespace,
    console: Console,
    prepared: PreparedLog,
    grid: OccupancyGrid,
    map_source: str,
    algos: list[str],
    skipped: dict[str, str],
    pace: UpdatePace | None,
    doubt: TruthDoubt | None = None,
) -> int:
    """``evaluate-log --tracking``: APE of pose tracking over the whole log."""
    particles = args.particles or DEFAULT_TRACKING_PARTICLES
    with TrialsProgress(console, quiet=args.quiet) as progress:
        warm_kernels(progress.progress, args.sensor, algos)
        tr = track_log(
            prepared,
            grid,
            algos,
            particles=particles,
            pace=pace,
            map_source=map_source,
            batch=Batch(args.executor, args.workers, progress),
            out=args.out,
            skipped=skipped,
            truth_doubt=doubt,
            sensor=args.sensor,
        )
    if not args.quiet:
        # two tables: eleven columns do not fit a 100-column console without cutting figures
        accuracy = ["algorithm", "scored", "updates", "APE RMSE [m]", "median [m]", "max [m]"]
        accuracy += ["RMSE, truth sound [m]"]
        cost = ["algorithm", "heading RMSE [rad]", "within 2 sigma", "particles", "update [ms]"]
        acc_rows = [
            [
                r.algorithm,
                str(r.scored_scans),
                str(r.updates),
                fmt(r.ape_rmse_m, 3),
                fmt(r.ape_median_m, 3),
                fmt(r.ape_max_m, 3),
                fmt(r.ape_rmse_outside_doubtful_m, 3),
            ]
            for r in tr.results
        ]
        cost_rows = [
            [
                r.algorithm,
                fmt(r.heading_rmse_rad, 3),
                pct(r.within_2sigma),  # as tracking.md prints it
                registry.particles_cell(r.algorithm, fmt(r.mean_particles, 0)),
                fmt(r.median_update_ms, 1),
            ]
            for r in tr.results
        ]
        title = (
            f"tracking on {prepared.log.name}: {particles} particles, start moved "
            f"0.5 m / 0.3 rad (seed {prepared.seed})"
        )
        console.print(plain_table(title, accuracy, acc_rows))
        console.print(plain_table("heading, calibration and cost", cost, cost_rows))
        console.print(f"results written to [bold]{escape(str(tr.out_dir))}[/]")
    return 0
