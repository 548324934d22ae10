"""``ceamcl play LOG``: a recorded log as ROS 2 topics, so a node (ours or Nav2's) can localise
on it and RViz or Foxglove can show it.

Publishes, at the log's pace times ``rate``: ``map`` (latched: the map given, or one built from
the log's poses), ``/tf_static`` ``base -> laser`` (``/tf`` when the mount changes from scan to
scan), ``/tf`` ``odom -> base`` and ``scan`` at each scan, and ``ground_truth``
(``geometry_msgs/PoseStamped`` in the map frame) where the log knows the true pose. Stamps are
wall-clock time, so no ``use_sim_time`` is needed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import LaserScan as LaserScanMsg
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

from ceamcl.errors import CeamclError, ConfigError
from ceamcl.io.logs import RecordedLog
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.ros import messages as m

ACK_WAIT_S = 2.0  # at most, for the last reliable messages to be acknowledged
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


@dataclass(frozen=True)
class Frames:
    map: str = "map"
    odom: str = "odom"
    base: str = "base_footprint"
    laser: str = "laser"


def pose2(p: np.ndarray) -> m.Pose2:
    return (float(p[0]), float(p[1]), float(p[2]))


def grid_msg(grid: OccupancyGrid, frame: str, stamp: float) -> OccupancyGridMsg:
    msg = OccupancyGridMsg()
    msg.header = Header(stamp=m.time_msg(stamp), frame_id=frame)
    msg.info.map_load_time = m.time_msg(stamp)
    msg.info.resolution = grid.resolution
    msg.info.width, msg.info.height = grid.width, grid.height
    msg.info.origin = m.pose_msg(grid.origin)
    msg.data = grid.data.reshape(-1).tolist()
    return msg


def scan_msg(log: RecordedLog, k: int, frame: str, stamp: float) -> LaserScanMsg:
    msg = LaserScanMsg()
    msg.header = Header(stamp=m.time_msg(stamp), frame_id=frame)
    ranges = log.ranges(k)
    msg.angle_min = float(log.angle_min[k])
    msg.angle_increment = float(log.angle_increment[k])
    msg.angle_max = msg.angle_min + msg.angle_increment * max(ranges.size - 1, 0)
    msg.range_min, msg.range_max = float(log.range_min[k]), float(log.range_max[k])
    msg.time_increment, msg.scan_time = 0.0, 0.0
    msg.ranges = ranges.astype(np.float32).tolist()
    return msg


def play(
    log: RecordedLog,
    grid: OccupancyGrid,
    truth: np.ndarray | None,
    *,
    rate: float = 1.0,
    frames: Frames = Frames(),
    wait_s: float = 5.0,
    delay_s: float = 0.0,
    on_scan: Callable[[int], None] | None = None,
    args: list[str] | None = None,
) -> int:
    """Publish ``log`` (scans ``0 .. n-1``) in real time divided by ``rate``; the number of
    scans published. Waits up to ``wait_s`` for a subscriber to ``scan`` first, then
    ``delay_s`` more (a localiser needs a moment to take in the map)."""
    if not rate > 0:
        raise ConfigError(f"rate: expected a positive number, got {rate}")
    for name, value in (("wait", wait_s), ("delay", delay_s)):
        if not value >= 0:
            raise ConfigError(f"{name}: expected a non-negative number of seconds, got {value}")
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rclpy raises its own RCLError for bad --ros-args
        raise CeamclError(f"ROS 2 could not start: {exc}") from None
    node = rclpy.create_node("ceamcl_play")
    try:
        map_pub = node.create_publisher(OccupancyGridMsg, "map", LATCHED)
        scan_pub = node.create_publisher(LaserScanMsg, "scan", qos_profile_sensor_data)
        tf_pub = node.create_publisher(TFMessage, "/tf", 100)
        static_pub = node.create_publisher(TFMessage, "/tf_static", LATCHED)
        # reliable with a deep history: a recorder or a test gets every pose even at high rates
        truth_pub = node.create_publisher(PoseStamped, "ground_truth", 1000)
        start = time.time()
        map_pub.publish(grid_msg(grid, frames.map, start))
        mounts = log.laser_mount
        fixed_mount = bool(np.all(mounts == mounts[0]))
        if fixed_mount:
            static_pub.publish(
                TFMessage(
                    transforms=[m.transform_msg(frames.base, frames.laser, pose2(mounts[0]), start)]
                )
            )
        deadline = time.monotonic() + wait_s
        while scan_pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(delay_s)
        t0_wall, t0_log = time.time(), float(log.times[0])
        for k in range(len(log)):
            due = t0_wall + (float(log.times[k]) - t0_log) / rate
            pause = due - time.time()
            if pause > 0:
                time.sleep(pause)
            stamp = due
            transforms = [m.transform_msg(frames.odom, frames.base, pose2(log.odometry[k]), stamp)]
            if not fixed_mount:
                transforms.append(
                    m.transform_msg(frames.base, frames.laser, pose2(mounts[k]), stamp)
                )
            tf_pub.publish(TFMessage(transforms=transforms))
            scan_pub.publish(scan_msg(log, k, frames.laser, stamp))
            if truth is not None and np.all(np.isfinite(truth[k])):  # NaN: not paired
                truth_pub.publish(
                    PoseStamped(
                        header=Header(stamp=m.time_msg(stamp), frame_id=frames.map),
                        pose=m.pose_msg(truth[k]),
                    )
                )
            if on_scan is not None:
                on_scan(k)
        # a reliable message still in flight is lost when the node goes: let the last poses
        # and transforms reach their subscribers first (bounded, a gone subscriber never acks)
        for pub in (truth_pub, tf_pub):
            pub.wait_for_all_acked(Duration(seconds=ACK_WAIT_S))
        return len(log)
    except KeyboardInterrupt:
        return 0
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
