"""Nav2's contract beyond the happy path: lifecycle transitions, bad parameters, the two
services, and bad input messages, each logged and survived (the node keeps localising)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ceamcl.simulation.scenarios import paper_scenario

pytestmark = pytest.mark.needs_ros

TOLERANCE_S = 0.2


@pytest.fixture(scope="module")
def hall_log():  # type: ignore[no-untyped-def]
    scenario = paper_scenario(0, "symmetric-hall")
    return scenario, scenario.simulate(np.random.default_rng(1))


def wait_for_log(node, text: str, timeout_s: float = 10.0) -> bool:  # type: ignore[no-untyped-def]
    return bool(node.wait_for(text, timeout_s))


def test_bad_parameters_leave_the_node_unconfigured(driver, tmp_path: Path) -> None:
    from lifecycle_msgs.msg import Transition

    from tests.ros.harness import NodeProcess

    args = ["--ros-args", "-p", "alhpa1:=0.3", "-p", "max_beams:=-4", "-p", "algorithm:=nope"]
    with NodeProcess(tmp_path, args) as node:
        assert not driver.transition(Transition.TRANSITION_CONFIGURE)
        assert driver.state() == "unconfigured"
        assert wait_for_log(node, "cannot configure")
        log = node.log()
        assert "unknown parameter: alhpa1" in log
        assert "max_beams: expected at least 2, got -4" in log
        assert "algorithm: unknown algorithm 'nope'" in log
        assert node.alive


def test_params_file_and_lifecycle(driver, hall_log, tmp_path: Path) -> None:
    from lifecycle_msgs.msg import Transition

    from tests.ros.harness import NodeProcess

    params = tmp_path / "nav2_params.yaml"
    params.write_text(
        "amcl:\n  ros__parameters:\n    algorithm: gmcl\n    max_particles: 800\n"
        f"    transform_tolerance: {TOLERANCE_S}\n    gmcl:\n      cluster_cell_m: 0.4\n"
        "controller_server:\n  ros__parameters:\n    anything: 1\n"
    )
    scenario, log = hall_log
    with NodeProcess(tmp_path, ["--params", str(params)]) as node:
        assert driver.state() == "unconfigured"
        driver.configure_and_activate()
        assert driver.state() == "active"
        assert wait_for_log(node, "configured: gmcl")
        # its kernels were readied while it configured, before any scan (ceamcl.warmup)
        assert wait_for_log(node, "compiled-kernel signatures ready")
        driver.start_run(node, log, scenario.grid())
        assert driver.step(log, 0, 2_000.0, TOLERANCE_S)
        # inactive: scans are ignored, nothing is published
        assert driver.transition(Transition.TRANSITION_DEACTIVATE)
        assert driver.state() == "inactive"
        assert not driver.step(log, 1, 2_000.0, TOLERANCE_S, timeout_s=1.0)
        assert driver.transition(Transition.TRANSITION_ACTIVATE)
        assert driver.step(log, 2, 2_000.0, TOLERANCE_S)
        assert driver.transition(Transition.TRANSITION_DEACTIVATE)
        assert driver.transition(Transition.TRANSITION_CLEANUP)
        assert driver.state() == "unconfigured"
        # configured again from scratch: the map (transient local) comes back by itself
        driver.configure_and_activate()
        assert node.wait_for("map received", 10.0, count=2)
        assert driver.step(log, 3, 2_000.0, TOLERANCE_S)
        assert node.alive


def test_services_and_bad_messages_are_survived(driver, hall_log, tmp_path: Path) -> None:
    from std_srvs.srv import Empty

    from tests.ros.harness import NodeProcess

    scenario, log = hall_log
    t0 = 3_000.0
    args = ["--ros-args", "-p", f"transform_tolerance:={TOLERANCE_S}", "-p", "seed:=3"]
    with NodeProcess(tmp_path, args) as node:
        driver.configure_and_activate()
        driver.start_run(node, log, scenario.grid())
        for k in range(5):
            assert driver.step(log, k, t0, TOLERANCE_S)

        # no motion: no update, until one is requested
        driver.poses.clear()
        stamp = t0 + float(log.times[4]) + 0.05
        same = log.odometry[4]
        driver.publish_odom(same, stamp)
        driver.scan_pub.publish(driver.scan_msg(log.ranges[4], log, stamp, "laser"))
        assert driver.spin_until(lambda: stamp + TOLERANCE_S in driver.map_to_odom, 10.0)
        assert driver.spin_until(lambda: len(driver.poses) > 0, 1.0) is False
        driver.call(driver.nomotion, Empty.Request())
        stamp += 0.05
        driver.publish_odom(same, stamp)
        driver.scan_pub.publish(driver.scan_msg(log.ranges[4], log, stamp, "laser"))
        assert driver.spin_until(lambda: len(driver.poses) > 0, 10.0)
        assert wait_for_log(node, "request for an update without motion")

        driver.call(driver.reinit, Empty.Request())
        assert driver.step(log, 5, t0, TOLERANCE_S)
        assert wait_for_log(node, "global localisation requested")

        # NaN ranges (half the scan): processed, the pose stays finite
        driver.poses.clear()
        ranges = log.ranges[6].copy()
        ranges[::2] = math.nan
        assert driver.step(log, 6, t0, TOLERANCE_S, ranges=ranges)
        assert driver.spin_until(lambda: len(driver.poses) > 0, 10.0)
        p = driver.poses[-1].pose.pose.position
        assert math.isfinite(p.x) and math.isfinite(p.y)
        # all NaN
        driver.poses.clear()
        assert driver.step(log, 7, t0, TOLERANCE_S, ranges=np.full(log.laser.n_beams, np.nan))
        if driver.spin_until(lambda: len(driver.poses) > 0, 2.0):
            p = driver.poses[-1].pose.pose.position
            assert math.isfinite(p.x) and math.isfinite(p.y)

        # a scan in a frame TF does not know: held for its transform like tf2's message
        # filter, dropped with a log line once ten later scans have pushed it out
        assert not driver.step(log, 8, t0, TOLERANCE_S, frame="nowhere", timeout_s=1.0)
        for k in range(9, 20):
            assert driver.step(log, k, t0, TOLERANCE_S)
        assert wait_for_log(node, "scan in frame 'nowhere' dropped: no transform from")

        # an empty map: logged, the old map kept
        from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg

        empty = OccupancyGridMsg()
        empty.header.frame_id = "map"
        empty.info.resolution = 0.05
        driver.map_pub.publish(empty)
        assert wait_for_log(node, "map: empty map (0 x 0 cells)")
        assert driver.step(log, 20, t0, TOLERANCE_S), node.log()[-3000:]

        # a map of another size where cells and data disagree: logged, the old map kept
        bad = OccupancyGridMsg()
        bad.header.frame_id = "map"
        bad.info.resolution, bad.info.width, bad.info.height = 0.05, 10, 10
        bad.data = [0] * 50
        driver.map_pub.publish(bad)
        assert wait_for_log(node, "data has 50 cells, expected 10 x 10 = 100")

        # a map change: the filter restarts on the new map at the last pose
        marked = paper_scenario(0, "marked-hall").grid()
        driver.publish_map(marked)
        assert wait_for_log(node, "map changed")
        for k in range(21, 26):
            assert driver.step(log, k, t0, TOLERANCE_S)

        # an initial pose in the wrong frame: refused with a reason
        from geometry_msgs.msg import PoseWithCovarianceStamped

        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "odom"
        msg.pose.pose.orientation.w = 1.0
        driver.initial_pub.publish(msg)
        assert wait_for_log(node, "initial pose in frame 'odom'")
        # and a good one: the node tracks from there
        truth = log.true_poses[26]
        from ceamcl.ros.messages import pose_msg

        msg.header.frame_id = "map"
        msg.pose.pose = pose_msg(truth)
        msg.pose.covariance = list(np.diag([0.01, 0.01, 0, 0, 0, 0.01]).reshape(-1).astype(float))
        driver.initial_pub.publish(msg)
        assert wait_for_log(node, "initial pose set")
        driver.poses.clear()
        for k in range(26, 50):
            assert driver.step(log, k, t0, TOLERANCE_S)
        assert driver.spin_until(lambda: len(driver.poses) > 0, 10.0)
        from ceamcl.ros.messages import pose2_from_msg
        from tests.ros.harness import pose_error

        d, a = pose_error(pose2_from_msg(driver.poses[-1].pose.pose), log.true_poses[49])
        assert d < 0.3 and a < 0.3
        assert node.alive
        assert "Traceback" not in node.log()
        tail = node.log()[-2000:]
        code = node.stop()
        assert code == 0, f"exit code {code} on SIGINT\n{tail}\n{node.log()[-2000:]}"


def test_every_static_broadcasters_transform_reaches_the_node(
    driver, hall_log, tmp_path: Path
) -> None:
    """A robot has several static broadcasters (robot_state_publisher, a driver's own): each
    latches its last /tf_static message. Read with depth 1, only one of them reached a node
    started after them, the laser mount was lost and no scan was ever used."""
    from tf2_msgs.msg import TFMessage

    from ceamcl.ros import messages as m
    from tests.ros.harness import BASE, LATCHED, NodeProcess

    scenario, log = hall_log
    others = [driver.node.create_publisher(TFMessage, "/tf_static", LATCHED) for _ in range(2)]
    driver.publish_mount(log.laser.pose)  # the mount first, then two other broadcasters
    for pub, child in zip(others, ("imu_link", "camera_link"), strict=True):
        pub.publish(TFMessage(transforms=[m.transform_msg(BASE, child, (0.1, 0.0, 0.0), 0.0)]))
    driver.publish_map(scenario.grid())
    driver.spin_until(lambda: False, 0.5)
    args = ["--ros-args", "-p", f"transform_tolerance:={TOLERANCE_S}", "-p", "algorithm:=mcl"]
    with NodeProcess(tmp_path, [*args, "-p", "max_particles:=500"]) as node:
        driver.configure_and_activate()
        assert wait_for_log(node, "map received", 20.0)
        t0 = 700.0
        assert all(driver.step(log, k, t0, TOLERANCE_S, timeout_s=10.0) for k in range(4))
        assert "not connected" not in node.log()
