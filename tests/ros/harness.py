"""What the ROS tests share: the node as a bounded subprocess, and a driver node that
publishes a simulated run (map, TF, scans) and collects what the node publishes."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseStamped, PoseWithCovarianceStamped
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import LaserScan as LaserScanMsg
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.ros import messages as m
from ceamcl.ros.latency import simulated_scan_msg
from ceamcl.ros.play import grid_msg
from ceamcl.ros.transforms import Pose2, compose
from ceamcl.simulation.simulator import SimulatedLog

#: Seconds to wait for a lifecycle transition's answer before asking the node's state.
ANSWER_WAIT_S = 5.0
#: Where each transition the tests make leads (lifecycle_msgs' primary state labels).
TRANSITION_GOALS: dict[int, str] = {
    Transition.TRANSITION_CONFIGURE: "inactive",
    Transition.TRANSITION_ACTIVATE: "active",
    Transition.TRANSITION_DEACTIVATE: "inactive",
    Transition.TRANSITION_CLEANUP: "unconfigured",
}
#: Primary states: a node in one of these is not in the middle of a transition.
STABLE_STATES = frozenset({"unconfigured", "inactive", "active", "finalized"})

LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
BASE, ODOM, MAP, LASER = "base_footprint", "odom", "map", "laser"


class NodeProcess:
    """``python -m ceamcl.ros`` (or ``command``) in a subprocess, its output in ``log_path``;
    ended (SIGINT, then SIGKILL after ``grace_s``) when the ``with`` block exits, whatever
    happened."""

    def __init__(
        self,
        tmp: Path,
        args: Sequence[str] = (),
        grace_s: float = 20.0,
        command: Sequence[str] = ("-m", "ceamcl.ros"),
        name: str = "node",
    ) -> None:
        self.log_path = tmp / f"{name}.log"
        self.command = list(command)
        self.args = list(args)
        self.grace_s = grace_s
        self.proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> NodeProcess:
        self._log = self.log_path.open("wb")
        env = dict(os.environ, PYTHONUNBUFFERED="1", RCUTILS_LOGGING_BUFFERED_STREAM="0")
        self.proc = subprocess.Popen(
            [sys.executable, *self.command, *self.args],
            stdout=self._log,
            stderr=subprocess.STDOUT,
            env=env,
        )
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def stop(self) -> int | None:
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(self.grace_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._log.close()
        code = self.proc.returncode
        self.proc = None
        return code

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def wait(self, timeout_s: float) -> int | None:
        """The exit code once it ends by itself within ``timeout_s`` (``None``: still running)."""
        assert self.proc is not None
        try:
            return self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_for(self, text: str, timeout_s: float = 10.0, count: int = 1) -> bool:
        """Until ``text`` appears ``count`` times in the node's output."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if self.log().count(text) >= count:
                return True
            time.sleep(0.05)
        return self.log().count(text) >= count


class Driver:
    """The test's node: inputs out, the localisation node's outputs in."""

    def __init__(self) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("ceamcl_test_driver", context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        n = self.node
        self.map_pub = n.create_publisher(OccupancyGridMsg, "map", LATCHED)
        self.scan_pub = n.create_publisher(LaserScanMsg, "scan", qos_profile_sensor_data)
        self.tf_pub = n.create_publisher(TFMessage, "/tf", 100)
        self.tf_static_pub = n.create_publisher(TFMessage, "/tf_static", LATCHED)
        self.initial_pub = n.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        self.poses: list[PoseWithCovarianceStamped] = []
        self.hypotheses: list[PoseArray] = []
        self.markers: list[MarkerArray] = []
        self.clouds: list[PoseArray] = []
        self.states: list[DiagnosticArray] = []
        self.map_to_odom: dict[float, Pose2] = {}
        # transient local like the node's publisher, with room for every pose of a run
        deep = QoSProfile(
            depth=1000,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        n.create_subscription(PoseWithCovarianceStamped, "amcl_pose", self.poses.append, deep)
        n.create_subscription(PoseArray, "amcl/hypotheses", self.hypotheses.append, 10)
        n.create_subscription(MarkerArray, "amcl/hypotheses/markers", self.markers.append, 10)
        n.create_subscription(DiagnosticArray, "amcl/state", self.states.append, LATCHED)
        n.create_subscription(
            PoseArray, "particle_cloud", self.clouds.append, qos_profile_sensor_data
        )
        n.create_subscription(TFMessage, "/tf", self._on_tf, 100)
        self.truth: dict[float, Pose2] = {}
        n.create_subscription(
            PoseStamped,
            "ground_truth",
            lambda msg: self.truth.__setitem__(
                m.seconds(msg.header.stamp), m.pose2_from_msg(msg.pose)
            ),
            1000,
        )
        self.change_state = n.create_client(ChangeState, "amcl/change_state")
        self.get_state = n.create_client(GetState, "amcl/get_state")
        self.reinit = n.create_client(Empty, "reinitialize_global_localization")
        self.nomotion = n.create_client(Empty, "request_nomotion_update")

    def last_state(self) -> dict[str, str]:
        """The values of the last ``~/state`` message, with its ``message``."""
        status = self.states[-1].status[0]
        return {"message": status.message, **{kv.key: kv.value for kv in status.values}}

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)

    def _on_tf(self, msg: TFMessage) -> None:
        for t in msg.transforms:
            if t.header.frame_id == MAP and t.child_frame_id == ODOM:
                self.map_to_odom[m.seconds(t.header.stamp)] = m.transform_pose2(t)[0]

    def spin_until(self, done: Callable[[], bool], timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if done():
                return True
            self.executor.spin_once(timeout_sec=0.02)
        return done()

    def call(
        self, client: Any, request: Any, timeout_s: float = 20.0, resend_s: float | None = None
    ) -> Any:
        """The service's answer to ``request``. With ``resend_s`` (idempotent requests only)
        the request is sent again every ``resend_s`` seconds until one is answered: right after
        a node starts, ``wait_for_service`` can report the service before the node has matched
        this client's response reader, and Fast DDS then drops the answer ("failed to send
        response (timeout): client will not receive response" in the node's log; the discovery
        race of ros2/rmw_fastrtps#238), so a single request can wait for ever."""
        assert client.wait_for_service(timeout_sec=timeout_s), f"{client.srv_name} not offered"
        end = time.monotonic() + timeout_s
        futures = [client.call_async(request)]
        while True:
            left = end - time.monotonic()
            slice_s = left if resend_s is None else min(resend_s, left)
            if self.spin_until(lambda: any(f.done() for f in futures), max(slice_s, 0.0)):
                return next(f for f in futures if f.done()).result()
            assert time.monotonic() < end, f"{client.srv_name}: no answer"
            futures.append(client.call_async(request))

    def transition(self, transition_id: int, timeout_s: float = 30.0) -> bool:
        """Whether the node took the lifecycle transition. A transition is not idempotent,
        so it is not simply sent again as :meth:`call` does with ``resend_s``: when no answer
        comes within :data:`ANSWER_WAIT_S` (the answer can be dropped in the discovery race
        :meth:`call` describes, after the node has made the transition), the node's state says
        what happened: at the transition's goal it was taken; still at the state it started
        from, the request is sent again; in between (configuring, ...), the state is asked
        again."""
        req = ChangeState.Request()
        req.transition = Transition(id=transition_id)
        goal = TRANSITION_GOALS.get(transition_id)
        client = self.change_state
        assert client.wait_for_service(timeout_sec=timeout_s), f"{client.srv_name} not offered"
        end = time.monotonic() + timeout_s
        futures = [client.call_async(req)]
        while True:
            wait = min(ANSWER_WAIT_S, max(end - time.monotonic(), 0.0))
            if self.spin_until(lambda: any(f.done() for f in futures), wait):
                if any(f.result().success for f in futures if f.done()):
                    return True
                # refused: a plain refusal, or a request sent again after the first was taken
                return len(futures) > 1 and goal is not None and self.state() == goal
            assert time.monotonic() < end, f"{client.srv_name}: no answer"
            label = self.state()
            if goal is not None and label == goal:
                return True
            if label in STABLE_STATES:
                futures.append(client.call_async(req))

    def state(self) -> str:
        answer = self.call(self.get_state, GetState.Request(), resend_s=2.0)
        return str(answer.current_state.label)

    def configure_and_activate(self) -> None:
        assert self.transition(Transition.TRANSITION_CONFIGURE)
        assert self.transition(Transition.TRANSITION_ACTIVATE)
        self.wait_for_subscribers()

    def wait_for_subscribers(self, timeout_s: float = 10.0) -> None:
        """Until the node's subscriptions are matched (discovery), so nothing sent is lost."""
        pubs = (self.scan_pub, self.tf_pub, self.tf_static_pub, self.map_pub, self.initial_pub)
        assert self.spin_until(
            lambda: all(p.get_subscription_count() > 0 for p in pubs), timeout_s
        ), "the node's subscriptions were not discovered"

    # ------------------------------------------------------------------ inputs
    def publish_map(self, grid: OccupancyGrid, frame: str = MAP) -> None:
        self.map_pub.publish(grid_msg(grid, frame, time.time()))

    def start_run(self, node: NodeProcess, log: SimulatedLog, grid: OccupancyGrid) -> None:
        """The laser mount and the map, and wait until the node has the map."""
        seen = node.log().count("map received")
        self.publish_mount(log.laser.pose)
        self.publish_map(grid)
        assert node.wait_for("map received", 20.0, count=seen + 1), node.log()[-2000:]

    def publish_mount(self, mount: Pose2, frame: str = LASER) -> None:
        self.tf_static_pub.publish(TFMessage(transforms=[m.transform_msg(BASE, frame, mount, 0.0)]))

    def scan_msg(self, ranges: np.ndarray, log: SimulatedLog, stamp: float, frame: str) -> Any:
        return simulated_scan_msg(ranges, log.laser, stamp, frame)

    def publish_odom(self, pose: Sequence[float], stamp: float) -> None:
        p = (float(pose[0]), float(pose[1]), float(pose[2]))
        self.tf_pub.publish(TFMessage(transforms=[m.transform_msg(ODOM, BASE, p, stamp)]))

    def step(
        self,
        log: SimulatedLog,
        k: int,
        t0: float,
        tolerance_s: float,
        *,
        ranges: np.ndarray | None = None,
        frame: str = LASER,
        timeout_s: float = 30.0,
    ) -> bool:
        """Publish step ``k`` (odometry TF, then the scan) and wait for the node's
        ``map -> odom`` stamped for this scan: the run goes at the node's pace."""
        stamp = t0 + float(log.times[k])
        self.publish_odom(log.odometry[k], stamp)
        rng = log.ranges[k] if ranges is None else ranges
        self.scan_pub.publish(self.scan_msg(rng, log, stamp, frame))
        key = stamp + tolerance_s
        return self.spin_until(
            lambda: any(abs(s - key) < 1e-6 for s in self.map_to_odom), timeout_s
        )


def pose_error(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    d = math.atan2(math.sin(a[2] - b[2]), math.cos(a[2] - b[2]))
    return math.hypot(a[0] - b[0], a[1] - b[1]), abs(d)


def composed(map_T_odom: Pose2, odom_T_base: Sequence[float]) -> Pose2:
    return compose(
        map_T_odom, (float(odom_T_base[0]), float(odom_T_base[1]), float(odom_T_base[2]))
    )
