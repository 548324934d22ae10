"""``ceamcl play LOG``: publish a recorded log as ROS 2 topics (docs/ros.md).

The log is read and its truth and odometry decided as ``ceamcl run`` decides them (the same
reading options, ``--truth``, ``--truth-from``, ``--laser-mount``, ``--repair-times`` and the
same synthetic odometry for a seed), so a node fed by ``play`` sees what ``run``'s filter sees.
"""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.markup import escape

from ceamcl.cli.common import (
    make_progress,
    non_negative_float,
    positive_float,
)
from ceamcl.cli.node import import_ros
from ceamcl.cli.run import (
    add_log_arguments,
    add_map_arguments,
    add_truth_arguments,
    check_truth_from,
    log_path,
    map_resolution,
    open_kwargs,
)
from ceamcl.errors import CeamclError, ConfigError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl play``."""
    p = sub.add_parser(
        "play",
        help="publish a log (CARMEN, ROS bag) as ROS 2 topics: map, scan, TF, ground truth",
        description="Publish LOG as ROS 2 topics for `ceamcl node` (or Nav2's amcl), RViz or "
        "Foxglove: map (latched), scan, /tf odom -> base, /tf_static base -> laser and "
        "ground_truth where the log knows it. The log, its truth and its odometry are read and "
        "decided as `ceamcl run` decides them (same options, same synthetic odometry for a "
        "seed). Needs the [ros] extra.",
    )
    add_log_arguments(p, frames=False)
    add_truth_arguments(p, seed_help="seed of the synthetic odometry (as `ceamcl run`'s)")
    p.add_argument(
        "--synthetic-odometry",
        action="store_true",
        help="the same as --truth yes: the log's poses are the ground truth and the odometry is "
        "drawn from them (--truth auto does so for a log whose content says it is corrected)",
    )
    add_map_arguments(p)
    p.add_argument("--rate", type=positive_float, default=1.0, help="speed-up over real time")
    p.add_argument(
        "--base-frame",
        default="base_footprint",
        help="the robot's TF frame: published, and read from a bag's /tf odometry (Nav2's name)",
    )
    p.add_argument(
        "--odom-frame",
        default="odom",
        help="the odometry's TF frame: published, and read from a bag's /tf odometry",
    )
    p.add_argument("--map-frame", default="map", help="the map's frame (/map's header)")
    p.add_argument("--laser-frame", default="laser", help="the scans' frame")
    p.add_argument(
        "--wait",
        type=non_negative_float,
        default=5.0,
        help="seconds to wait for a subscriber to scan",
    )
    p.add_argument(
        "--delay",
        type=non_negative_float,
        default=2.0,
        help="seconds between the map and the first scan (the localiser takes the map in)",
    )
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=run, handles_ctrl_c=True)  # Ctrl-C ends the playback: exit 0


def truth_mode(args: argparse.Namespace) -> str:
    """``--truth``, with ``--synthetic-odometry`` as ``--truth yes``; conflicts refused."""
    given = None if args.truth == "auto" else f"--truth {args.truth}"
    check_truth_from(args.truth_from, "--synthetic-odometry" if args.synthetic_odometry else given)
    if args.synthetic_odometry:
        if args.truth == "no":
            raise ConfigError(
                "truth: --synthetic-odometry draws odometry from the poses as ground truth, "
                "--truth no says they are not; expected one of them"
            )
        return "yes"
    return str(args.truth)


def run(args: argparse.Namespace, console: Console) -> int:
    from ceamcl.checks import physical_warnings
    from ceamcl.replay import obtain_map, prepare_log

    mode = truth_mode(args)
    resolution = map_resolution(args)
    path = log_path(args)
    ros_play = import_ros("play", "play")
    kwargs = open_kwargs(args)
    prepared = prepare_log(
        path,
        seed=args.seed,
        truth=mode,  # type: ignore[arg-type]
        repair_times=args.repair_times,
        truth_from=args.truth_from,
        laser_mount=args.laser_mount,
        **kwargs,
    )
    log = prepared.log
    if len(log) == 0:
        raise CeamclError(f"{path}: no scan to play")
    truth = log.true_poses if prepared.has_truth else None
    grid, map_source = obtain_map(
        prepared.map_log, args.map, resolution, own=prepared.truth_log is None
    )
    physical_warnings(log, grid, args.map or f"the map built from {prepared.map_log.path}")
    if not args.quiet:
        console.print(
            f"truth: {prepared.truth_reason}; odometry: {prepared.odometry}", markup=False
        )
        console.print(f"map: {map_source}", markup=False)
    frames = ros_play.Frames(args.map_frame, args.odom_frame, args.base_frame, args.laser_frame)
    progress = make_progress(f"[bold]play[/] {escape(log.name)}", console, quiet=args.quiet)
    with progress:
        task = progress.add_task("scans", total=len(log))
        played = ros_play.play(
            log,
            grid,
            truth,
            rate=args.rate,
            frames=frames,
            wait_s=args.wait,
            delay_s=args.delay,
            on_scan=lambda k: progress.update(task, completed=k + 1),
            args=["ceamcl", *args.ros_args],
        )
    if not args.quiet:
        console.print(f"played {played} of {len(log)} scans")
    return 0
