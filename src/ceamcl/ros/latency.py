"""Scan-in to pose-out latency through the ROS 2 node (``ceamcl bench --ros-latency``).

The node runs as its own process (``python -m ceamcl.ros --autostart``), as on a robot; this
process publishes the paper's hall run one scan at a time (odometry TF first, then the scan)
and times, on one clock, from publishing a scan to receiving the ``amcl_pose`` stamped with it.
Scans where the odometry did not move (no update by Nav2's rule) are sent but not timed. DDS
stays on this machine unless ``ROS_AUTOMATIC_DISCOVERY_RANGE`` says otherwise.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import rclpy
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan as LaserScanMsg
from tf2_msgs.msg import TFMessage

from ceamcl.errors import CeamclError
from ceamcl.ros import messages as m
from ceamcl.ros.play import LATCHED, grid_msg, pose2
from ceamcl.sensors.scan import LaserGeometry
from ceamcl.simulation.scenarios import paper_scenario


def simulated_scan_msg(
    ranges: np.ndarray, geometry: LaserGeometry, stamp: float, frame: str = "laser"
) -> LaserScanMsg:
    """One simulated scan (``SimulatedLog.ranges[k]`` of ``SimulatedLog.laser``) as a message."""
    msg = LaserScanMsg()
    msg.header.frame_id, msg.header.stamp = frame, m.time_msg(stamp)
    msg.angle_min, msg.angle_increment = geometry.angle_min, geometry.angle_increment
    msg.angle_max = geometry.angle_min + geometry.angle_increment * (geometry.n_beams - 1)
    msg.range_min, msg.range_max = geometry.range_min, geometry.range_max
    msg.ranges = ranges.astype(np.float32).tolist()
    return msg


def measure_latency(
    algorithm: str,
    n_particles: int,
    *,
    scans: int = 150,
    seed: int = 0,
    timeout_s: float = 180.0,
    on_scan: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """p50 / p95 / max (ms) of scan-in to ``amcl_pose``-out for ``algorithm`` with a particle
    budget ``n_particles`` (``max_particles``), over the first ``scans`` scans of the hall run
    after global localisation. Raises :class:`CeamclError` when the node does not answer."""
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    params = {
        "algorithm": algorithm,
        "max_particles": n_particles,
        "min_particles": min(500, n_particles),
        "seed": seed,
        "update_min_d": 0.0,
        "update_min_a": 0.0,
        "base_frame_id": "base_footprint",
    }
    args = [a for k, v in params.items() for a in ("-p", f"{k}:={v}")]
    scenario = paper_scenario(0, "symmetric-hall")
    log = scenario.simulate(np.random.default_rng(seed))
    n = min(scans + 1, len(log))
    deadline = time.monotonic() + timeout_s
    node_log = tempfile.TemporaryFile()  # the node's log (a pipe could fill and stall it)
    proc = subprocess.Popen(
        [sys.executable, "-m", "ceamcl.ros", "--autostart", "--ros-args", *args],
        stdout=node_log,
        stderr=subprocess.STDOUT,
        env=env,
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("ceamcl_latency", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    received: dict[float, float] = {}
    try:
        node.create_subscription(
            PoseWithCovarianceStamped,
            "amcl_pose",
            lambda msg: received.__setitem__(m.seconds(msg.header.stamp), time.perf_counter()),
            LATCHED,
        )
        map_pub = node.create_publisher(OccupancyGridMsg, "map", LATCHED)
        scan_pub = node.create_publisher(LaserScanMsg, "scan", qos_profile_sensor_data)
        tf_pub = node.create_publisher(TFMessage, "/tf", 100)
        static_pub = node.create_publisher(TFMessage, "/tf_static", LATCHED)

        def spin_until(done: Callable[[], bool], limit_s: float) -> bool:
            end = min(time.monotonic() + limit_s, deadline)
            while not done() and time.monotonic() < end:
                if proc.poll() is not None:
                    node_log.seek(0)
                    raise CeamclError(f"the node ended: {node_log.read().decode()[-500:]}")
                executor.spin_once(timeout_sec=0.01)
            return done()

        if not spin_until(lambda: scan_pub.get_subscription_count() > 0, 60.0):
            raise CeamclError("the node did not subscribe to scan within 60 s")
        t0 = time.time()
        static_pub.publish(
            TFMessage(transforms=[m.transform_msg("base_footprint", "laser", log.laser.pose, t0)])
        )
        map_pub.publish(grid_msg(scenario.grid(), "map", t0))
        latencies: list[float] = []
        for k in range(n):
            stamp = t0 + float(log.times[k])
            odom = pose2(log.odometry[k])
            tf_pub.publish(
                TFMessage(transforms=[m.transform_msg("odom", "base_footprint", odom, stamp)])
            )
            key = m.seconds(m.time_msg(stamp))
            moved = k == 0 or not np.array_equal(log.odometry[k], log.odometry[k - 1])
            # the first scan may wait for the map: resend it until the node answers
            for _ in range(30 if k == 0 else 1):
                sent = time.perf_counter()
                scan_pub.publish(simulated_scan_msg(log.ranges[k], log.laser, stamp))

                def answered(key: float = key) -> bool:
                    return key in received

                if spin_until(answered, 2.0 if k == 0 else 30.0):
                    break
            if moved and key not in received:
                raise CeamclError(f"no amcl_pose for scan {k}")
            if k > 0 and moved:
                latencies.append(1000.0 * (received[key] - sent))
            if on_scan is not None:
                on_scan(k)
        lat = np.array(latencies)
        return {
            "algorithm": algorithm,
            "particles": n_particles,
            "scans": int(lat.size),
            "p50_ms": float(np.percentile(lat, 50)),
            "p95_ms": float(np.percentile(lat, 95)),
            "max_ms": float(lat.max()),
        }
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        node_log.close()
