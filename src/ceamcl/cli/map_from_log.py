"""``ceamcl map-from-log``: an occupancy grid map from a log's poses, saved as a ROS map."""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.markup import escape

from ceamcl.cli.common import laser_mount, positive_float, positive_int
from ceamcl.cli.run import add_log_arguments, log_path, open_kwargs
from ceamcl.io.logs import open_log
from ceamcl.mapping import MappingConfig, map_from_log
from ceamcl.maps.ros_io import save_map
from ceamcl.replay import with_laser_mount


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl map-from-log``."""
    d = MappingConfig()
    p = sub.add_parser(
        "map-from-log",
        help="build an occupancy grid map from a log's poses (ROS map format)",
        description="Occupancy grid mapping with the log's poses (log-odds, inverse sensor "
        "model). Meaningful for SLAM-corrected logs; raw odometry gives a smeared map.",
    )
    add_log_arguments(p)
    p.add_argument(
        "--resolution", type=positive_float, default=d.resolution_m, help="cell side [m]"
    )
    p.add_argument(
        "--usable-range",
        type=positive_float,
        default=d.max_range_m,
        metavar="M",
        help="longer readings clear free space up to M and mark no hit",
    )
    p.add_argument(
        "--no-return-free",
        type=positive_float,
        default=d.no_return_free_m,
        metavar="M",
        help="how far a no-return reading clears free space",
    )
    p.add_argument("--beam-stride", type=positive_int, default=1, help="use every N-th beam")
    p.add_argument(
        "--laser-mount",
        type=laser_mount,
        default=None,
        metavar="X,Y,YAW",
        help="the laser's pose on the robot (m, m, rad) at every scan, in place of the log's, as "
        "`ceamcl run --laser-mount` builds its map",
    )
    p.add_argument("-o", "--output", required=True, metavar="MAP.yaml", help="map YAML to write")
    p.add_argument("--format", choices=("pgm", "png"), default="pgm", help="image format")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    log = open_log(log_path(args), **open_kwargs(args))
    if args.laser_mount is not None:
        log = with_laser_mount(log, args.laser_mount)
    cfg = MappingConfig(
        resolution_m=args.resolution,
        max_range_m=args.usable_range,
        no_return_free_m=args.no_return_free,
        beam_stride=args.beam_stride,
    )
    grid, stats = map_from_log(log, cfg)
    out = save_map(grid, args.output, image_format=args.format)
    if not args.quiet:
        w, h = stats.size_m
        console.print(
            f"{log.name}: {stats.scans} scans, {stats.beams} beams ({stats.no_return} no-return)"
            f" -> {grid.width} x {grid.height} cells ({w:.1f} x {h:.1f} m), "
            f"{stats.free_area_m2:.0f} m^2 free, {stats.cells_occupied} occupied cells"
        )
        console.print(f"map written to [bold]{escape(str(out))}[/]")
    return 0
