"""The ``ceamcl`` command line: a thin layer over the library.

Each subcommand lives in its own module of this package with a ``register(subparsers)``
function that adds its parser and sets ``run(args, console) -> exit code`` as its default.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from importlib import import_module

from rich.console import Console

from ceamcl import __version__
from ceamcl.errors import CeamclError

#: Subcommand modules, in the order ``ceamcl --help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "demo",
    "world",
    "soak",
    "bench",
    "experiment",
    "run",
    "map_from_log",
    "evaluate_log",
    "node",
    "play",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ceamcl",
        description="Coevolution-based adaptive Monte Carlo localisation and its baselines.",
    )
    parser.add_argument("--version", action="version", version=f"ceamcl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        import_module(f"ceamcl.cli.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    words = list(sys.argv[1:] if argv is None else argv)
    # ROS's own arguments (``ceamcl node --ros-args -p name:=value``) pass through untouched
    cut = words.index("--ros-args") if "--ros-args" in words else len(words)
    args = parser.parse_args(words[:cut])
    args.ros_args = words[cut:]
    console = Console(stderr=False)
    try:
        code: int = args.run(args, console)
    except CeamclError as exc:
        print(f"ceamcl: error: {exc}", file=sys.stderr)
        return 2
    return code


if __name__ == "__main__":
    sys.exit(main())
