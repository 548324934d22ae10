"""The ROS 2 node: a drop-in for ``nav2_amcl`` that publishes every hypothesis.

Nav2's contract (docs/ros.md has the table): a lifecycle node named ``amcl``; subscribes
``scan`` (sensor-data QoS), ``map`` (reliable, transient local) and ``initialpose``; reads
odometry from TF ``odom -> base``; publishes ``amcl_pose`` (transient local), ``particle_cloud``
(PoseArray, sensor-data QoS) and TF ``map -> odom`` post-dated by ``transform_tolerance``;
serves ``reinitialize_global_localization`` and ``request_nomotion_update``. Beyond Nav2:
``~/hypotheses`` (PoseArray, best first), ``~/hypotheses/markers`` (MarkerArray) and
``~/hypotheses/status`` (DiagnosticArray of the measured weights and fitness).

Where Nav2 waits for an initial pose, this node localises globally from the first scan
(``set_initial_pose: false``), as CEAMCL is built to.
"""

from __future__ import annotations

import traceback
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rcl_interfaces.msg import SetParametersResult
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import LaserScan as LaserScanMsg
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from ceamcl.errors import CeamclError
from ceamcl.filters import registry
from ceamcl.filters.base import PoseEstimate
from ceamcl.ros import messages as m
from ceamcl.ros.localiser import DEFAULT_INIT_COV, Localiser, cap_notice
from ceamcl.ros.params import NAV2_DEFAULTS, OWN_DEFAULTS, NodeParams, parse
from ceamcl.ros.transforms import (
    Pose2,
    TransformBuffer,
    TransformError,
    compose,
    inverse,
)
from ceamcl.warmup import warm_up

#: Seconds between repeats of the same warning.
THROTTLE_S = 5.0
#: Hypotheses described by markers and status (the heaviest; ~/hypotheses carries all).
MAX_DESCRIBED = 50
#: Scans held while their transforms are on the way (Nav2's message filter holds 10).
SCAN_QUEUE = 10
#: ``/tf_static`` as tf2's static listener reads it (depth 100, transient local): each static
#: broadcaster's latched message reaches a late reader; with depth 1 only one of them did, and
#: a robot with a second static broadcaster lost its laser mount for good.
STATIC_TF_QOS = QoSProfile(
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


class LocalisationNode(LifecycleNode):
    """``amcl``'s interface around any registered filter (parameter ``algorithm``)."""

    def __init__(self, name: str = "amcl", **kwargs: Any) -> None:
        super().__init__(
            name,
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
            **kwargs,
        )
        # what the command line and parameter files set (declared from the overrides above);
        # every other parameter is declared with Nav2's default, which must not count as set
        self.given: set[str] = set(self.get_parameters_by_prefix("")) - {"use_sim_time"}
        for pname, default in {**NAV2_DEFAULTS, **OWN_DEFAULTS}.items():
            if not self.has_parameter(pname):
                self.declare_parameter(pname, default)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.params: NodeParams | None = None
        self._entities: list[Any] = []
        self._reset_state()

    # ------------------------------------------------------------------ state
    def _reset_state(self) -> None:
        self.active = False
        self.localiser: Localiser | None = None
        self.tf = TransformBuffer()
        self.upside_down: set[str] = set()
        self.map_T_odom: Pose2 | None = None
        # scans whose transforms have not arrived yet (tf2's message filter)
        self.waiting: deque[tuple[LaserScanMsg, str]] = deque()

    # ------------------------------------------------------------------ lifecycle
    def _values(self, changed: Iterable[Parameter] = ()) -> dict[str, Any]:
        values = {name: p.value for name, p in self.get_parameters_by_prefix("").items()}
        values.update({p.name: p.value for p in changed})
        return values

    def _on_set_parameters(self, changed: list[Parameter]) -> SetParametersResult:
        """``ros2 param set``: refused while the node is configured (it reads its parameters
        at configure; Nav2's amcl applies many at once, this node does not, and a set that
        succeeded without effect, or broke the next configure, said nothing); before that,
        checked as configure will check them, and remembered as set."""
        names = [p.name for p in changed]
        if self.params is not None:
            return SetParametersResult(
                successful=False,
                reason=f"{', '.join(names)}: this node reads its parameters at configure; "
                "deactivate and clean it up, set them, and configure it again",
            )
        try:
            parse(self._values(changed), self.given | set(names))
        except CeamclError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.given |= set(names)
        return SetParametersResult(successful=True)

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        values = self._values()
        try:
            params = parse(values, self.given)
        except CeamclError as exc:
            self.get_logger().error(f"cannot configure: {exc}")
            return TransitionCallbackReturn.FAILURE
        for warning in params.warnings:
            self.get_logger().warning(warning)
        self.params = params
        self._reset_state()
        # every kernel loaded (compiled on a cold Numba cache) now, before the robot moves:
        # compiled mid-drive, the first updates stalled for seconds (ceamcl.warmup)
        beam = params.sensor == "beam" or params.algorithm in registry.OWN_SENSOR
        self.get_logger().info(warm_up(beam_model=beam).describe())
        self.localiser = Localiser(params)
        self._create_interfaces(params)
        self.get_logger().info(
            f"configured: {params.algorithm} "
            f"({registry.sensor_of(params.algorithm, params.sensor)} model, seed {params.seed})"
        )
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        assert self.params is not None and self.localiser is not None
        if self.params["set_initial_pose"]:
            p = self.params.nav2
            pose = (p["initial_pose.x"], p["initial_pose.y"], p["initial_pose.yaw"])
            self.localiser.set_pose(pose)
            self.get_logger().info(f"initial pose from parameters: {pose}")
        self.active = True
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self.waiting.clear()  # held scans are not stepped while inactive (Nav2 drops them)
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._destroy_interfaces()
        self._reset_state()
        self.params = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self.on_cleanup(state)

    # ------------------------------------------------------------------ interfaces
    def _create_interfaces(self, params: NodeParams) -> None:
        latched = QoSProfile(
            depth=1,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self.pose_pub = self.create_lifecycle_publisher(
            PoseWithCovarianceStamped, "amcl_pose", latched
        )
        self.cloud_pub = self.create_lifecycle_publisher(
            PoseArray, "particle_cloud", qos_profile_sensor_data
        )
        self.hyp_pub = self.create_lifecycle_publisher(PoseArray, "~/hypotheses", 10)
        self.marker_pub = self.create_lifecycle_publisher(MarkerArray, "~/hypotheses/markers", 10)
        self.status_pub = self.create_lifecycle_publisher(
            DiagnosticArray, "~/hypotheses/status", 10
        )
        self.state_pub = self.create_lifecycle_publisher(DiagnosticArray, "~/state", latched)
        self.tf_pub = self.create_lifecycle_publisher(TFMessage, "/tf", 100)
        self._entities = [
            # TF first: the executor serves ready subscriptions in this order, so a scan's
            # odometry is read before the next scan pushes it out of the queue
            self.create_subscription(TFMessage, "/tf", self._guard("tf", self._on_tf), 100),
            self.create_subscription(
                TFMessage,
                "/tf_static",
                self._guard("tf_static", self._on_tf_static),
                STATIC_TF_QOS,
            ),
            self.create_subscription(
                LaserScanMsg,
                params["scan_topic"],
                self._guard("scan", self._on_scan),
                qos_profile_sensor_data,
            ),
            self.create_subscription(
                OccupancyGridMsg, params["map_topic"], self._guard("map", self._on_map), latched
            ),
            self.create_subscription(
                PoseWithCovarianceStamped,
                "initialpose",
                self._guard("initialpose", self._on_initial_pose),
                10,
            ),
            self.create_service(Empty, "reinitialize_global_localization", self._on_reinitialise),
            self.create_service(Empty, "request_nomotion_update", self._on_nomotion),
        ]

    def _destroy_interfaces(self) -> None:
        for entity in self._entities:
            if hasattr(entity, "srv_type"):
                self.destroy_service(entity)
            else:
                self.destroy_subscription(entity)
        self._entities = []
        for name in (
            "pose_pub",
            "cloud_pub",
            "hyp_pub",
            "marker_pub",
            "status_pub",
            "state_pub",
            "tf_pub",
        ):
            pub = getattr(self, name, None)
            if pub is not None:
                self.destroy_lifecycle_publisher(pub)
                setattr(self, name, None)

    def _guard(self, topic: str, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        """``callback`` that logs whatever it raises (naming the topic) and carries on."""

        def guarded(msg: Any) -> None:
            try:
                callback(msg)
            except CeamclError as exc:
                self.get_logger().warning(f"{topic}: message ignored: {exc}")
            except Exception as exc:  # a node must outlive any one message
                self.get_logger().error(
                    f"{topic}: message ignored after an unexpected error: {exc!r}\n"
                    + traceback.format_exc()
                )

        return guarded

    # ------------------------------------------------------------------ inputs
    def _on_tf(self, msg: TFMessage, static: bool = False) -> None:
        assert self.params is not None
        own = (self.params["global_frame_id"], self.params["odom_frame_id"])
        for t in msg.transforms:
            parent, child = t.header.frame_id.lstrip("/"), t.child_frame_id.lstrip("/")
            if (parent, child) == own:
                continue  # our own map -> odom
            pose, flipped = m.transform_pose2(t)
            try:
                self.tf.set_transform(parent, child, pose, m.seconds(t.header.stamp), static=static)
            except TransformError as exc:
                self.get_logger().warning(f"tf: {exc}", throttle_duration_sec=THROTTLE_S)
                continue
            if flipped:
                self.upside_down.add(child)
            else:
                self.upside_down.discard(child)
        self._retry_waiting()

    def _on_tf_static(self, msg: TFMessage) -> None:
        self._on_tf(msg, static=True)

    def _on_map(self, msg: OccupancyGridMsg) -> None:
        assert self.params is not None and self.localiser is not None
        grid = m.grid_from_msg(msg)
        if msg.header.frame_id.lstrip("/") != self.params["global_frame_id"]:
            self.get_logger().warning(
                f"map: frame {msg.header.frame_id!r} is not global_frame_id "
                f"{self.params['global_frame_id']!r}; using it as that frame"
            )
        news = self.localiser.set_map(grid)
        if news is not None:
            self.get_logger().info(news)

    def _on_initial_pose(self, msg: PoseWithCovarianceStamped) -> None:
        assert self.params is not None
        frame = msg.header.frame_id.lstrip("/")
        if frame != self.params["global_frame_id"]:
            raise CeamclError(
                f"initial pose in frame {frame!r}; initial poses must be in "
                f"{self.params['global_frame_id']!r}"
            )
        pose = m.pose2_from_msg(msg.pose.pose)
        cov = m.covariance_from_msg(msg.pose.covariance)
        # as Nav2 takes it: zero variances put the particles on the pose (nav2_simple_commander
        # sends an all-zero covariance); only one that is no covariance is replaced
        if not np.all(np.isfinite(cov)) or np.any(np.linalg.eigvalsh((cov + cov.T) / 2) < -1e-12):
            self.get_logger().warning(
                "initialpose: covariance not positive semi-definite; Nav2's default used"
            )
            cov = DEFAULT_INIT_COV
        assert self.localiser is not None
        self.localiser.set_pose(pose, cov)
        self.get_logger().info(f"initial pose set: {pose[0]:.3f} {pose[1]:.3f} {pose[2]:.3f}")

    def _on_reinitialise(self, request: Any, response: Any) -> Any:
        if self.localiser is not None:
            self.localiser.request_global()
        self.get_logger().info("global localisation requested: from the next scan")
        return response

    def _on_nomotion(self, request: Any, response: Any) -> Any:
        if self.localiser is not None:
            self.localiser.request_update()
        self.get_logger().info("request for an update without motion")
        return response

    def _on_scan(self, msg: LaserScanMsg) -> None:
        if not self.active:
            return
        assert self.params is not None
        p = self.params
        if self.localiser is None or self.localiser.filter is None:
            self.get_logger().warning(
                "scan: no map yet; waiting for one on " + p["map_topic"],
                throttle_duration_sec=THROTTLE_S,
            )
            return
        if self.waiting:
            self._retry_waiting()
        reason = self._process(msg)
        if reason is None:
            self._drop_waiting_before(m.seconds(msg.header.stamp))
        else:
            self._wait(msg, reason)

    def _wait(self, msg: LaserScanMsg, reason: str) -> None:
        """Hold a scan whose transforms have not arrived, as tf2's message filter does: up to
        :data:`SCAN_QUEUE` scans, the oldest dropped (and logged, with the reason) beyond."""
        if len(self.waiting) == SCAN_QUEUE:
            self._drop(*self.waiting.popleft())
        self.waiting.append((msg, reason))

    def _drop(self, msg: LaserScanMsg, reason: str) -> None:
        self.get_logger().warning(
            f"scan in frame {msg.header.frame_id!r} dropped: {reason}",
            throttle_duration_sec=THROTTLE_S,
        )

    def _drop_waiting_before(self, stamp: float) -> None:
        """A held scan older than one just used can no longer be used: drop it."""
        while self.waiting and m.seconds(self.waiting[0][0].header.stamp) < stamp:
            self._drop(*self.waiting.popleft())

    def _retry_waiting(self) -> None:
        """Process the held scans, oldest first, that can be now; keep the others (none
        while inactive: an odometry transform after deactivate steps no held scan)."""
        if not self.active:
            self.waiting.clear()
            return
        kept: deque[tuple[LaserScanMsg, str]] = deque()
        while self.waiting:
            msg, _ = self.waiting.popleft()
            reason = self._process(msg)
            if reason is None:  # the held scans before it can no longer be used
                while kept:
                    self._drop(*kept.popleft())
            else:
                kept.append((msg, reason))
        self.waiting = kept

    def _process(self, msg: LaserScanMsg) -> str | None:
        """Localise with one scan; the reason when its transforms are not (yet) known."""
        assert self.params is not None
        p = self.params
        stamp = m.seconds(msg.header.stamp)
        frame = msg.header.frame_id.lstrip("/")
        try:
            mount = self.tf.lookup(p["base_frame_id"], frame, stamp)
            odom = self.tf.lookup(p["odom_frame_id"], p["base_frame_id"], stamp)
        except TransformError as exc:
            return str(exc)
        scan = m.scan_from_msg(
            msg,
            mount,
            upside_down=frame in self.upside_down,
            range_min=p["laser_min_range"],
            range_max=p["laser_max_range"],
        )
        assert self.localiser is not None
        estimate = self.localiser.scan(odom, scan)
        if estimate is not None:  # the filter updated
            notice = cap_notice(self.localiser.filter)
            if notice is not None:
                self.get_logger().warning(notice, throttle_duration_sec=THROTTLE_S)
            self._publish_estimate(estimate, odom, stamp)
        if self.map_T_odom is not None and p["tf_broadcast"]:
            self.tf_pub.publish(
                TFMessage(
                    transforms=[
                        m.transform_msg(
                            p["global_frame_id"],
                            p["odom_frame_id"],
                            self.map_T_odom,
                            stamp + p["transform_tolerance"],
                        )
                    ]
                )
            )
        return None

    def _publish_estimate(self, estimate: PoseEstimate, odom: Pose2, stamp: float) -> None:
        assert self.localiser is not None and self.localiser.filter is not None
        assert self.params is not None and self.localiser.last_estimate is not None
        f = self.localiser.filter
        frame = self.params["global_frame_id"]
        self.map_T_odom = compose(self.localiser.last_estimate, inverse(odom))
        self.pose_pub.publish(m.pose_with_covariance(estimate, frame, stamp))
        if self.cloud_pub.get_subscription_count() > 0:
            self.cloud_pub.publish(m.pose_array(f.particles().poses, frame, stamp))
        hypotheses = f.hypotheses()
        self.hyp_pub.publish(
            m.pose_array(np.array([h.pose for h in hypotheses]).reshape(-1, 3), frame, stamp)
        )
        # Markers and status cost about 0.1 ms a hypothesis to build, and a KLD-AMCL in global
        # localisation has hundreds of clusters (461 on the hall's first scan, 34 ms): built
        # only for a subscriber, and for the MAX_DESCRIBED heaviest hypotheses.
        described = sorted(hypotheses, key=lambda h: -h.weight)[:MAX_DESCRIBED]
        if self.marker_pub.get_subscription_count() > 0:
            self.marker_pub.publish(m.hypothesis_markers(described, frame, stamp))
        if self.status_pub.get_subscription_count() > 0:
            self.status_pub.publish(
                m.hypotheses_status(described, self.params.algorithm, self.get_name(), stamp)
            )
        self.state_pub.publish(
            m.state_status(f.state(hypotheses), self.params.algorithm, self.get_name(), stamp)
        )


def main(args: list[str] | None = None, *, autostart: bool = False) -> int:
    """Run the node until it is interrupted (``ros2 run``-style ``args``)."""
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rclpy raises its own RCLError for bad --ros-args
        raise CeamclError(f"ROS 2 could not start: {exc}") from None
    node = LocalisationNode()
    try:
        if autostart:
            # a failed configure leaves the node unconfigured (logged), as Nav2's would be
            if node.trigger_configure() == TransitionCallbackReturn.SUCCESS:
                node.trigger_activate()
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    except RuntimeError:
        # SIGINT shuts the context down while the executor may be taking a message; rclpy then
        # raises from take_message ("Unable to convert call argument '0'"; seen once in four
        # CI runs of tests/ros/test_node_contract.py). After a shutdown that is the end of the
        # run, not an error; while the context is up it is one.
        if rclpy.ok():
            raise
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
