"""``ceamcl play LOG``: publish a recorded log as ROS 2 topics (docs/ros.md)."""

from __future__ import annotations

import argparse

from rich.console import Console

from ceamcl.cli.common import (
    make_progress,
    non_negative_float,
    non_negative_int,
    positive_float,
)
from ceamcl.cli.node import import_ros
from ceamcl.errors import CeamclError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl play``."""
    p = sub.add_parser(
        "play",
        help="publish a log (CARMEN, ROS bag) as ROS 2 topics: map, scan, TF, ground truth",
        description="Publish LOG as ROS 2 topics for `ceamcl node` (or Nav2's amcl), RViz or "
        "Foxglove: map (latched), scan, /tf odom -> base, /tf_static base -> laser and "
        "ground_truth where the log knows it. Needs the [ros] extra.",
    )
    p.add_argument("log", help="CARMEN .log/.clf (plain or gzip), ROS 1 .bag or ROS 2 bag folder")
    p.add_argument("--map", default=None, help="ROS map YAML (default: built from the log's poses)")
    p.add_argument("--rate", type=positive_float, default=1.0, help="speed-up over real time")
    p.add_argument(
        "--synthetic-odometry",
        action="store_true",
        help="the log's poses become the ground truth and odometry is drawn from them with "
        "ROS amcl's default noise (for SLAM-corrected logs, whose odometry is the truth)",
    )
    p.add_argument("--seed", type=non_negative_int, default=0, help="seed of that odometry")
    p.add_argument("--max-range", type=positive_float, default=None, help="metres")
    p.add_argument("--base-frame", default="base_footprint", help="the robot's TF frame")
    p.add_argument("--odom-frame", default="odom", help="the odometry's TF frame")
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


def run(args: argparse.Namespace, console: Console) -> int:
    import numpy as np

    from ceamcl.io.logs import open_log, poses_look_corrected
    from ceamcl.motion.odometry import OdometryNoise

    ros_play = import_ros("play", "play")
    log = open_log(args.log, max_range_m=args.max_range)
    if len(log) == 0:
        raise CeamclError(f"{args.log}: no scan to play")
    if args.synthetic_odometry:
        log = log.with_synthetic_odometry(OdometryNoise(), np.random.default_rng(args.seed))
    truth = log.true_poses
    if truth is None and poses_look_corrected(log)[0]:
        truth = log.poses
    if args.map is not None:
        from ceamcl.maps.ros_io import load_map

        grid = load_map(args.map)
    else:
        from ceamcl.mapping import map_from_log

        grid, _ = map_from_log(log)
    frames = ros_play.Frames(args.map_frame, args.odom_frame, args.base_frame, args.laser_frame)
    progress = make_progress(f"[bold]play[/] {log.name}", console, quiet=args.quiet)
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
