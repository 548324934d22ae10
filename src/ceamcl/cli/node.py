"""``ceamcl node``: the ROS 2 localisation node (Nav2 ``amcl``'s interface)."""

from __future__ import annotations

import argparse
from importlib import import_module
from pathlib import Path
from types import ModuleType

from rich.console import Console

from ceamcl.errors import CeamclError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl node``."""
    node = sub.add_parser(
        "node",
        help="run the ROS 2 node (a drop-in for Nav2's amcl; needs the [ros] extra)",
        description="Run the ROS 2 localisation node named amcl. Parameters: Nav2 AMCL's, "
        "plus algorithm, seed and <algorithm>.<field>; see docs/ros.md. Arguments after "
        "--ros-args go to ROS (e.g. --ros-args -p algorithm:=gmcl).",
    )
    node.add_argument(
        "--params", type=Path, default=None, help="ROS 2 parameter file (e.g. nav2_params.yaml)"
    )
    node.add_argument(
        "--autostart",
        action="store_true",
        help="configure and activate at once (without a Nav2 lifecycle manager)",
    )
    node.set_defaults(run=run, handles_ctrl_c=True)  # Ctrl-C is how a node ends: exit 0


def import_ros(module: str, command: str) -> ModuleType:
    """``ceamcl.ros.<module>``, or a :class:`CeamclError` saying how to get ROS 2."""
    try:
        return import_module(f"ceamcl.ros.{module}")
    except ImportError as exc:
        if exc.name == "tf2_msgs":
            raise CeamclError(
                f"ceamcl {command} needs tf2_msgs, which has no wheel on PyPI: build it into "
                "this environment with ros/build-tf2-msgs.sh from ceamcl's source (needs "
                "'ceamcl[ros-build]', cmake and a C compiler; `make` does it) or source a "
                "ROS 2 installation (docs/ros.md)"
            ) from None
        raise CeamclError(
            f"ceamcl {command} needs ROS 2 (rclpy and the message packages): install "
            f"'ceamcl[ros]' or source a ROS 2 installation ({exc})"
        ) from None


def run(args: argparse.Namespace, console: Console) -> int:
    main = import_ros("node", "node").main
    ros_args = list(args.ros_args)
    if args.params is not None:
        if not args.params.is_file():
            raise CeamclError(f"--params: {args.params}: no such file")
        from ceamcl.ros.params import load_yaml

        load_yaml(args.params)  # a broken file is named here; its values are checked at configure
        if "--ros-args" not in ros_args:
            ros_args.insert(0, "--ros-args")
        ros_args += ["--params-file", str(args.params)]
    return main(["ceamcl", *ros_args], autostart=args.autostart)
