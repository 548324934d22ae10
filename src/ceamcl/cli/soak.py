"""``ceamcl soak``: a very long simulated drive; checks memory stays flat and sizes in bounds."""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ceamcl.cli.common import (
    check_particles,
    make_progress,
    non_negative_int,
    positive_float,
    positive_int,
    require_available,
)
from ceamcl.filters import registry
from ceamcl.io.results import ensure_output_dir
from ceamcl.soak import (
    DEFAULT_MAX_GROWTH_PCT,
    SOAK_WORLDS,
    SoakConfig,
    run_soak,
    write_soak_outputs,
)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl soak``."""
    soak = sub.add_parser(
        "soak",
        help="run a filter for many steps on a looping simulated drive; check memory and sizes",
    )
    soak.add_argument("--steps", type=positive_int, default=100_000, help="filter steps to run")
    soak.add_argument(
        "--algorithm", choices=registry.names(), default="ceamcl", help="the filter to run"
    )
    soak.add_argument(
        "--world", choices=SOAK_WORLDS, default="small-office", help="the world driven round"
    )
    soak.add_argument(
        "--sensor",
        choices=registry.SENSOR_MODELS,
        default="likelihood-field",
        help="sensor model (nav2-amcl always uses the wheel's own beam model)",
    )
    soak.add_argument(
        "--seed", type=non_negative_int, default=0, help="seed of the drive and the filter"
    )
    soak.add_argument(
        "--particles", type=positive_int, default=None, help="sample size of MCL / GMCL"
    )
    soak.add_argument(
        "--warmup",
        type=non_negative_int,
        default=None,
        help="steps before the memory reference is taken (default: a tenth, at most 5000)",
    )
    soak.add_argument(
        "--max-growth-pct",
        type=positive_float,
        default=DEFAULT_MAX_GROWTH_PCT,
        help="RSS growth after warm-up above which the soak fails (default 5)",
    )
    soak.add_argument("--out", default="soak-out", help="folder for soak.json and soak.png")
    soak.add_argument("--quiet", action="store_true", help="no progress bar or table")
    soak.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    check_particles(args.particles, args.algorithm)
    require_available(args.algorithm)
    config = SoakConfig(
        steps=args.steps,
        algorithm=args.algorithm,
        world=args.world,
        sensor=args.sensor,
        seed=args.seed,
        particles=args.particles,
        warmup_steps=args.warmup,
        max_growth_pct=args.max_growth_pct,
    )
    out_dir = ensure_output_dir(args.out)  # fail before a long run, not after it
    progress = make_progress(
        f"[bold]soak[/] {args.algorithm} on {args.world}", console, quiet=args.quiet
    )
    with progress:
        task = progress.add_task("steps", total=args.steps)

        def step(k: int) -> None:
            if k % 50 == 0 or k == args.steps - 1:
                progress.update(task, completed=k + 1)

        report = run_soak(config, on_step=step)
    paths = write_soak_outputs(report, out_dir)
    if not args.quiet:
        table = Table(title=f"ceamcl soak ({args.algorithm}, {args.steps} steps, seed {args.seed})")
        table.add_column("measure")
        table.add_column("value", justify="right")
        rows = [
            ("RSS at start (after initialisation)", f"{report.rss_start_kb / 1024:.1f} MiB"),
            (
                f"RSS after warm-up ({report.warmup_steps} steps)",
                f"{report.rss_warm_kb / 1024:.1f} MiB",
            ),
            ("RSS at the end", f"{report.rss_end_kb / 1024:.1f} MiB"),
            ("RSS growth after warm-up", f"{report.growth_pct:+.2f} %"),
            ("peak RSS after warm-up", f"{report.rss_peak_after_warmup_kb / 1024:.1f} MiB"),
            ("steps per second", f"{report.steps_per_s:.1f}"),
            ("wall time", f"{report.wall_s:.1f} s"),
            ("sample size min / max", f"{report.samples_min} / {report.samples_max}"),
            (
                "sample size bounds",
                f"[{report.samples_bound_low}, {report.samples_bound_high}]",
            ),
            ("re-initialisations", str(report.reinitialisations)),
            ("mean position error after warm-up", f"{report.position_error_mean_m:.3f} m"),
            ("steps within 0.5 m after warm-up", f"{100 * report.share_within_0_5_m:.1f} %"),
        ]
        for key, value in rows:
            table.add_row(key, value)
        console.print(table)
        console.print(f"results written to [bold]{escape(str(paths[0].parent))}[/]")
    if not report.passed:
        reasons = []
        if not report.memory_flat:
            reasons.append(
                f"RSS grew {report.growth_pct:.2f}% after warm-up (limit {args.max_growth_pct:g}%)"
            )
        if not report.samples_within_bounds:
            reasons.append(
                f"sample size left [{report.samples_bound_low}, {report.samples_bound_high}]: "
                f"min {report.samples_min}, max {report.samples_max}"
            )
        if report.nonfinite_estimates:
            reasons.append(f"{report.nonfinite_estimates} estimates were NaN or infinite")
        console.print(f"[bold red]soak failed[/]: {escape('; '.join(reasons))}")
        return 1
    return 0
