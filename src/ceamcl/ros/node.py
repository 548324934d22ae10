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

import math
import traceback
from collections.abc import Callable
from typing import Any, Literal

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
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
from ceamcl.filters.base import LocalisationFilter
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryNoise, increment_between
from ceamcl.ros import messages as m
from ceamcl.ros.params import NAV2_DEFAULTS, OWN_DEFAULTS, NodeParams, parse
from ceamcl.ros.transforms import (
    Pose2,
    TransformBuffer,
    TransformError,
    compose,
    inverse,
    wrap,
)
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.beam_model import BeamModel, BeamModelConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel

#: Nav2's covariance for an initial pose set without one (its init_cov defaults).
DEFAULT_INIT_COV = np.diag([0.5**2, 0.5**2, (math.pi / 12.0) ** 2])
#: Seconds between repeats of the same warning.
THROTTLE_S = 5.0


class MotionGate:
    """Nav2's update trigger: update when the odometry moved more than ``update_min_d``
    along x or y, or turned more than ``update_min_a``, since the last update, or when forced.

    Kept in the node until the particle core offers this policy (``update_min_d/a`` there);
    then the node hands the thresholds to the filter instead.
    """

    def __init__(self, min_d: float, min_a: float) -> None:
        self.min_d, self.min_a = min_d, min_a
        self.reference: Pose2 | None = None
        self.force = False

    def due(self, odom: Pose2) -> bool:
        if self.reference is None or self.force:
            return True
        r = self.reference
        return (
            abs(odom[0] - r[0]) > self.min_d
            or abs(odom[1] - r[1]) > self.min_d
            or abs(wrap(odom[2] - r[2])) > self.min_a
        )

    def updated(self, odom: Pose2) -> None:
        self.reference = odom
        self.force = False


def sensor_model(params: NodeParams, grid: OccupancyGrid) -> SensorModel:
    """The laser model Nav2's parameters ask for, built on ``grid``."""
    p = params.nav2
    if params.sensor == "beam":
        return BeamModel(
            grid,
            BeamModelConfig(
                z_hit=p["z_hit"], z_short=p["z_short"], z_max=p["z_max"], z_rand=p["z_rand"],
                sigma_hit_m=p["sigma_hit"], lambda_short=p["lambda_short"],
                max_beams=p["max_beams"],
            ),
        )
    return LikelihoodFieldModel(
        grid,
        LikelihoodFieldConfig(
            z_hit=p["z_hit"], z_rand=p["z_rand"], sigma_hit_m=p["sigma_hit"],
            max_occ_dist_m=p["laser_likelihood_max_dist"], max_beams=p["max_beams"],
        ),
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
        for pname, default in {**NAV2_DEFAULTS, **OWN_DEFAULTS}.items():
            if not self.has_parameter(pname):
                self.declare_parameter(pname, default)
        self.params: NodeParams | None = None
        self._entities: list[Any] = []
        self._reset_state()

    # ------------------------------------------------------------------ state
    def _reset_state(self) -> None:
        self.active = False
        self.grid: OccupancyGrid | None = None
        self.filter: LocalisationFilter | None = None
        self.pending: Literal["global"] | tuple[Pose2, np.ndarray] | None = None
        self.gate = MotionGate(0.0, 0.0)
        self.tf = TransformBuffer()
        self.upside_down: set[str] = set()
        self.map_T_odom: Pose2 | None = None
        self.last_estimate: Pose2 | None = None
        # a scan whose odometry has not arrived yet (tf2's message filter, queue of one)
        self.waiting_scan: tuple[LaserScanMsg, str] | None = None
        self.rng = np.random.default_rng(0)

    # ------------------------------------------------------------------ lifecycle
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        values = {name: p.value for name, p in self._parameters.items()}
        try:
            params = parse(values)
        except CeamclError as exc:
            self.get_logger().error(f"cannot configure: {exc}")
            return TransitionCallbackReturn.FAILURE
        for warning in params.warnings:
            self.get_logger().warning(warning)
        self.params = params
        self._reset_state()
        self.rng = np.random.default_rng(params.seed)
        self.gate = MotionGate(params["update_min_d"], params["update_min_a"])
        self._create_interfaces(params)
        self.get_logger().info(
            f"configured: {params.algorithm} ({params.sensor} model, seed {params.seed})"
        )
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        assert self.params is not None
        if self.params["set_initial_pose"]:
            p = self.params.nav2
            self.pending = (
                (p["initial_pose.x"], p["initial_pose.y"], p["initial_pose.yaw"]),
                DEFAULT_INIT_COV,
            )
            self.get_logger().info(f"initial pose from parameters: {self.pending[0]}")
        self.active = True
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
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
        self.marker_pub = self.create_lifecycle_publisher(
            MarkerArray, "~/hypotheses/markers", 10
        )
        self.status_pub = self.create_lifecycle_publisher(
            DiagnosticArray, "~/hypotheses/status", 10
        )
        self.tf_pub = self.create_lifecycle_publisher(TFMessage, "/tf", 100)
        self._entities = [
            self.create_subscription(
                LaserScanMsg, params["scan_topic"], self._guard("scan", self._on_scan),
                qos_profile_sensor_data,
            ),
            self.create_subscription(
                OccupancyGridMsg, params["map_topic"], self._guard("map", self._on_map), latched
            ),
            self.create_subscription(
                PoseWithCovarianceStamped, "initialpose",
                self._guard("initialpose", self._on_initial_pose), 10,
            ),
            self.create_subscription(TFMessage, "/tf", self._guard("tf", self._on_tf), 100),
            self.create_subscription(
                TFMessage, "/tf_static", self._guard("tf_static", self._on_tf_static), latched
            ),
            self.create_service(
                Empty, "reinitialize_global_localization", self._on_reinitialise
            ),
            self.create_service(Empty, "request_nomotion_update", self._on_nomotion),
        ]

    def _destroy_interfaces(self) -> None:
        for entity in self._entities:
            if hasattr(entity, "srv_type"):
                self.destroy_service(entity)
            else:
                self.destroy_subscription(entity)
        self._entities = []
        for name in ("pose_pub", "cloud_pub", "hyp_pub", "marker_pub", "status_pub", "tf_pub"):
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
        if self.waiting_scan is not None:
            self._on_scan(self.waiting_scan[0])

    def _on_tf_static(self, msg: TFMessage) -> None:
        self._on_tf(msg, static=True)

    def _on_map(self, msg: OccupancyGridMsg) -> None:
        assert self.params is not None
        if self.grid is not None and self.params["first_map_only"]:
            self.get_logger().info("map: a new map ignored (first_map_only)")
            return
        grid = m.grid_from_msg(msg)
        if self.grid is not None and grid == self.grid:
            return
        if msg.header.frame_id.lstrip("/") != self.params["global_frame_id"]:
            self.get_logger().warning(
                f"map: frame {msg.header.frame_id!r} is not global_frame_id "
                f"{self.params['global_frame_id']!r}; using it as that frame"
            )
        if grid.free_cells.size == 0:
            raise CeamclError("map: no free cell to localise in")
        new_filter = registry.make_filter(
            self.params.algorithm,
            grid,
            self.rng,
            sensor=sensor_model(self.params, grid),
            odometry_noise=OdometryNoise(*(self.params[f"alpha{i}"] for i in range(1, 5))),
            n_particles=self.params["max_particles"],
            config=self.params.config,
        )
        changed = self.grid is not None
        self.grid, self.filter = grid, new_filter
        if self.pending is None:
            if changed and self.last_estimate is not None:
                self.pending = (self.last_estimate, DEFAULT_INIT_COV)
            else:
                self.pending = "global"
        self.get_logger().info(
            f"map {'changed' if changed else 'received'}: {grid.width} x {grid.height} cells at "
            f"{grid.resolution} m; "
            + ("localising globally" if self.pending == "global" else "restarting at the last pose")
        )

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
        if np.any(np.diag(cov) <= 0) or np.any(np.linalg.eigvalsh(cov) < 0):
            self.get_logger().warning("initialpose: covariance not positive; Nav2's default used")
            cov = DEFAULT_INIT_COV
        self.pending = (pose, cov)
        self.get_logger().info(f"initial pose set: {pose[0]:.3f} {pose[1]:.3f} {pose[2]:.3f}")

    def _on_reinitialise(self, request: Any, response: Any) -> Any:
        self.pending = "global"
        self.get_logger().info("global localisation requested: from the next scan")
        return response

    def _on_nomotion(self, request: Any, response: Any) -> Any:
        self.gate.force = True
        self.get_logger().info("request for an update without motion")
        return response

    def _on_scan(self, msg: LaserScanMsg) -> None:
        if not self.active:
            return
        assert self.params is not None
        p = self.params
        if self.filter is None:
            self.get_logger().warning(
                "scan: no map yet; waiting for one on " + p["map_topic"],
                throttle_duration_sec=THROTTLE_S,
            )
            return
        stamp = m.seconds(msg.header.stamp)
        frame = msg.header.frame_id.lstrip("/")
        if self.waiting_scan is not None and self.waiting_scan[0] is not msg:
            dropped, reason = self.waiting_scan
            self.get_logger().warning(
                f"scan in frame {dropped.header.frame_id!r} dropped: {reason}",
                throttle_duration_sec=THROTTLE_S,
            )
        self.waiting_scan = None
        try:
            mount = self.tf.lookup(p["base_frame_id"], frame, stamp)
            odom = self.tf.lookup(p["odom_frame_id"], p["base_frame_id"], stamp)
        except TransformError as exc:
            # its transforms may be on the way: retried at the next TF message, dropped (and
            # logged) when the next scan comes first, as tf2's message filter does
            self.waiting_scan = (msg, str(exc))
            return
        scan = m.scan_from_msg(
            msg, mount, upside_down=frame in self.upside_down,
            range_min=p["laser_min_range"], range_max=p["laser_max_range"],
        )
        updated = self._update(odom, scan)
        if updated:
            self._publish_estimate(odom, stamp)
        if self.map_T_odom is not None and p["tf_broadcast"]:
            self.tf_pub.publish(
                TFMessage(
                    transforms=[
                        m.transform_msg(
                            p["global_frame_id"], p["odom_frame_id"], self.map_T_odom,
                            stamp + p["transform_tolerance"],
                        )
                    ]
                )
            )

    # ------------------------------------------------------------------ filtering
    def _update(self, odom: Pose2, scan: Any) -> bool:
        """Initialise or step the filter with this scan; whether it did anything."""
        f = self.filter
        assert f is not None
        if self.pending == "global":
            f.initialise_global(scan)
            self.pending = None
            self.gate.updated(odom)
            return True
        if self.pending is not None:
            pose, cov = self.pending
            f.initialise_pose(np.asarray(pose), cov)
            self.pending = None
            self.gate.reference = odom
            self.gate.force = True
        if not self.gate.due(odom):
            return False
        assert self.gate.reference is not None
        f.step(increment_between(self.gate.reference, odom), scan)
        self.gate.updated(odom)
        return True

    def _publish_estimate(self, odom: Pose2, stamp: float) -> None:
        assert self.filter is not None and self.params is not None
        frame = self.params["global_frame_id"]
        estimate = self.filter.estimate()
        if not (np.all(np.isfinite(estimate.pose)) and np.all(np.isfinite(estimate.covariance))):
            self.get_logger().error("the filter gave a non-finite pose; nothing published")
            return
        pose = (float(estimate.pose[0]), float(estimate.pose[1]), float(estimate.pose[2]))
        self.last_estimate = pose
        self.map_T_odom = compose(pose, inverse(odom))
        self.pose_pub.publish(m.pose_with_covariance(estimate, frame, stamp))
        if self.cloud_pub.get_subscription_count() > 0:
            self.cloud_pub.publish(m.pose_array(self.filter.particles().poses, frame, stamp))
        hypotheses = self.filter.hypotheses()
        self.hyp_pub.publish(
            m.pose_array(np.array([h.pose for h in hypotheses]).reshape(-1, 3), frame, stamp)
        )
        self.marker_pub.publish(m.hypothesis_markers(hypotheses, frame, stamp))
        self.status_pub.publish(
            m.hypotheses_status(hypotheses, self.params.algorithm, self.get_name(), stamp)
        )


def main(args: list[str] | None = None, *, autostart: bool = False) -> int:
    """Run the node until it is interrupted (``ros2 run``-style ``args``)."""
    rclpy.init(args=args)
    node = LocalisationNode()
    try:
        if autostart:
            # a failed configure leaves the node unconfigured (logged), as Nav2's would be
            if node.trigger_configure() == TransitionCallbackReturn.SUCCESS:
                node.trigger_activate()
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
