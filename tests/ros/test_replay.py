"""A real log through ROS: ``ceamcl play`` publishes intel-corrected (map, scans, odometry TF,
ground truth) at 100 times the log's pace; the node, started at the first true pose, must
track the truth. Skipped, saying why, where ../shared/data is absent."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.needs_ros

LOG = Path(__file__).resolve().parents[3] / "shared" / "data" / "carmen" / "intel-corrected.log.gz"
RATE = 100.0


def test_intel_replay_is_tracked(driver, tmp_path: Path) -> None:
    if not LOG.is_file():
        pytest.skip(f"real log {LOG} is absent (the shared data folder is not mounted)")
    from ceamcl.io.logs import open_log
    from ceamcl.ros.messages import pose2_from_msg, seconds
    from tests.ros.harness import NodeProcess, pose_error

    first = open_log(LOG).poses[0]
    args = ["--ros-args", "-p", "set_initial_pose:=true",
            "-p", f"initial_pose.x:={first[0]}", "-p", f"initial_pose.y:={first[1]}",
            "-p", f"initial_pose.yaw:={first[2]}", "-p", "z_hit:=0.95", "-p", "z_rand:=0.05",
            "-p", "transform_tolerance:=0.2"]
    play_args = [str(LOG), "--rate", str(RATE), "--synthetic-odometry", "--seed", "0", "--quiet"]
    with NodeProcess(tmp_path, args) as node:
        driver.configure_and_activate()
        with NodeProcess(tmp_path, play_args, command=("-m", "ceamcl", "play"),
                         name="play") as player:
            done = driver.spin_until(lambda: not player.alive, 120.0)
            assert done, f"ceamcl play did not end in 120 s\n{player.log()[-2000:]}"
            assert player.wait(1.0) == 0, player.log()[-2000:]
        driver.spin_until(lambda: False, 1.0)  # the last messages
        assert node.alive and "Traceback" not in node.log(), node.log()[-3000:]

    errors = []
    for msg in driver.poses:
        stamp = seconds(msg.header.stamp)
        truth = driver.truth.get(stamp)
        if truth is not None:
            errors.append(pose_error(pose2_from_msg(msg.pose.pose), truth))
    assert len(driver.truth) > 800, f"ground truth for {len(driver.truth)} of 910 scans"
    # the node updates when the robot moved 0.25 m or turned 0.2 rad, at most once per scan
    assert len(errors) > 400, f"only {len(errors)} poses for 910 scans\n{node.log()[-2000:]}"
    d = np.array([e[0] for e in errors])
    a = np.array([e[1] for e in errors])
    assert np.median(d) < 0.15 and np.median(a) < 0.05, (np.median(d), np.median(a))
    assert d[-1] < 0.3 and a[-1] < 0.1 and math.isfinite(d.max())
