"""The ``ceamcl`` command line: a thin layer over the library."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from ceamcl import __version__
from ceamcl.errors import CeamclError, ConfigError
from ceamcl.filters import ALGORITHMS, SENSOR_MODELS
from ceamcl.maps.worlds import WORLD_NAMES, describe_worlds, get_world

DEFAULT_ALGORITHM = "ceamcl"


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative number, got {value}")
    return value


def _positive_int(text: str) -> int:
    value = _non_negative_int(text)
    if value == 0:
        raise argparse.ArgumentTypeError("expected a positive number, got 0")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ceamcl",
        description="Coevolution-based adaptive Monte Carlo localisation and its baselines.",
    )
    parser.add_argument("--version", action="version", version=f"ceamcl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="simulate the paper's run and localise globally")
    demo.add_argument("--algorithm", choices=ALGORITHMS, default=DEFAULT_ALGORITHM)
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
    demo.add_argument("--seed", type=_non_negative_int, default=0)
    demo.add_argument("--sensor", choices=SENSOR_MODELS, default="likelihood-field")
    demo.add_argument(
        "--particles",
        type=_positive_int,
        default=None,
        help="sample size of fixed-size filters (MCL, GMCL)",
    )
    demo.add_argument("--out", default="demo-out", help="folder for the results")
    demo.add_argument("--quiet", action="store_true", help="no progress bar or table")

    world = sub.add_parser("world", help="export a built-in world as a ROS map (YAML + image)")
    world.add_argument("name", nargs="?", choices=WORLD_NAMES)
    world.add_argument("-o", "--output", help="path of the map YAML to write")
    world.add_argument("--format", choices=("pgm", "png"), default="pgm")
    world.add_argument("--list", action="store_true", help="list the built-in worlds")
    return parser


def _cmd_demo(args: argparse.Namespace, console: Console) -> int:
    from ceamcl.demo import run_demo

    progress = Progress(
        TextColumn(f"[bold]{args.algorithm}[/] on {args.world}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=args.quiet,
        transient=False,
    )
    with progress:
        task = progress.add_task("steps", total=None)

        def start(total: int) -> None:
            progress.update(task, total=total)

        def step(k: int) -> None:
            progress.update(task, completed=k + 1)

        outcome = run_demo(
            args.algorithm,
            world=args.world,
            start_room=args.start_room,
            seed=args.seed,
            sensor=args.sensor,
            n_particles=args.particles,
            out=args.out,
            on_step=step,
            on_start=start,
        )
    if not args.quiet:
        table = Table(title=f"ceamcl demo ({args.algorithm}, seed {args.seed})")
        table.add_column("measure")
        table.add_column("value", justify="right")
        s = outcome.summary
        for key in (
            "steps",
            "final_position_error_m",
            "final_heading_error_rad",
            "closest_hypothesis_error_m",
            "mean_step_ms",
            "median_step_ms",
            "samples_initial",
            "samples_final",
            "species_final",
            "symmetric_images_covered",
        ):
            if key in s and s[key] is not None:
                v = s[key]
                table.add_row(key, f"{v:.3f}" if isinstance(v, float) else str(v))
        table.add_row("hypotheses at the end", str(len(s["hypotheses_final"])))
        console.print(table)
        console.print(f"results written to [bold]{outcome.out_dir}[/]")
    return 0


def _cmd_world(args: argparse.Namespace, console: Console) -> int:
    if args.list or args.name is None:
        for name, desc in describe_worlds().items():
            console.print(f"{name:16s} {desc}")
        return 0
    if not args.output:
        raise ConfigError("world: -o/--output MAP.yaml is required to export a world")
    from ceamcl.maps.ros_io import save_map

    path = save_map(get_world(args.name), args.output, image_format=args.format)
    console.print(f"wrote {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    console = Console(stderr=False)
    try:
        if args.command == "demo":
            return _cmd_demo(args, console)
        if args.command == "world":
            return _cmd_world(args, console)
    except CeamclError as exc:
        print(f"ceamcl: error: {exc}", file=sys.stderr)
        return 2
    parser.error(f"unknown command {args.command!r}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
