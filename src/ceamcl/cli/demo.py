"""``ceamcl demo``: simulate the paper's run and localise globally."""

from __future__ import annotations

import argparse

from rich.console import Console

from ceamcl.cli.common import (
    RunProgress,
    add_output_arguments,
    check_particles,
    make_progress,
    non_negative_int,
    positive_int,
    print_written,
    require_available,
    summary_table,
)
from ceamcl.demo import run_demo
from ceamcl.filters import registry
from ceamcl.outputs import OutputOptions

DEFAULT_ALGORITHM = "ceamcl"


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl demo``."""
    demo = sub.add_parser("demo", help="simulate the paper's run and localise globally")
    demo.add_argument(
        "--algorithm",
        choices=registry.names(),
        default=DEFAULT_ALGORITHM,
        help="any registered algorithm (nav2-amcl needs the [peers] extra)",
    )
    demo.add_argument(
        "--world", choices=("symmetric-hall", "marked-hall"), default="symmetric-hall"
    )
    demo.add_argument(
        "--start-room",
        type=int,
        choices=range(4),
        default=0,
        help="room the robot starts in (0 SW, 1 SE, 2 NE, 3 NW)",
    )
    demo.add_argument("--seed", type=non_negative_int, default=0)
    demo.add_argument(
        "--sensor",
        choices=registry.SENSOR_MODELS,
        default="likelihood-field",
        help="sensor model (nav2-amcl always uses the wheel's own beam model)",
    )
    demo.add_argument(
        "--particles",
        type=positive_int,
        default=None,
        help="sample size of fixed-size filters (MCL, GMCL)",
    )
    demo.add_argument("--out", default="demo-out", help="folder for the results")
    demo.add_argument("--quiet", action="store_true", help="no progress bar or table")
    add_output_arguments(demo, animation_default=True)
    demo.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    check_particles(args.particles)
    outputs = OutputOptions.from_args(args)
    require_available(args.algorithm)
    progress = make_progress(
        f"[bold]{args.algorithm}[/] on {args.world}", console, quiet=args.quiet
    )
    with progress:
        bar = RunProgress(progress)
        outcome = run_demo(
            args.algorithm,
            world=args.world,
            start_room=args.start_room,
            seed=args.seed,
            sensor=args.sensor,
            n_particles=args.particles,
            out=args.out,
            on_step=bar.step,
            on_start=bar.start,
            outputs=outputs,
            on_frame=bar.frame,
        )
    if not args.quiet:
        s = outcome.summary
        table = summary_table(
            f"ceamcl demo ({args.algorithm}, seed {args.seed})",
            s,
            (
                "steps",
                "final_position_error_m",
                "final_heading_error_rad",
                "closest_hypothesis_error_m",
                "mean_step_ms",
                "median_step_ms",
                "samples_initial",
                "samples_final",
                "restarts",
                "species_final",
                "symmetric_images_covered",
            ),
        )
        table.add_row("hypotheses at the end", str(len(s["hypotheses_final"])))
        console.print(table)
        print_written(console, outcome.out_dir, outcome.files)
    return 0
