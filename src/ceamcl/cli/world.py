"""``ceamcl world``: list the built-in worlds or export one as a ROS map."""

from __future__ import annotations

import argparse

from rich.console import Console

from ceamcl.errors import ConfigError
from ceamcl.maps.ros_io import save_map
from ceamcl.maps.worlds import WORLD_NAMES, describe_worlds, get_world


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl world``."""
    world = sub.add_parser("world", help="export a built-in world as a ROS map (YAML + image)")
    world.add_argument("name", nargs="?", choices=WORLD_NAMES)
    world.add_argument("-o", "--output", help="path of the map YAML to write")
    world.add_argument(
        "--format", choices=("pgm", "png"), default="pgm", help="image format of the map"
    )
    world.add_argument("--list", action="store_true", help="list the built-in worlds")
    world.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    if args.list or args.name is None:
        if args.output is not None:  # nothing named to write: say so instead of listing
            raise ConfigError(
                "world: -o/--output writes the world NAME names; expected a NAME"
                + (" and no --list" if args.list else "")
                + " (ceamcl world --list lists them)"
            )
        for name, desc in describe_worlds().items():
            console.print(f"{name:16s} {desc}", markup=False)
        return 0
    if not args.output:
        raise ConfigError("world: -o/--output MAP.yaml is required to export a world")
    path = save_map(get_world(args.name), args.output, image_format=args.format)
    console.print(f"wrote {path}", markup=False)
    return 0
