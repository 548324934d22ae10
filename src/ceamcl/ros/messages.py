"""ROS 2 messages to and from ceamcl's types: maps, scans, poses, hypotheses.

Each ``*_from_msg`` checks what it reads and raises :class:`ceamcl.errors.CeamclError` naming
the field (sizes are checked against a budget before anything is allocated).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (
    Point,
    Pose,
    PoseArray,
    PoseWithCovarianceStamped,
    Quaternion,
    TransformStamped,
)
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from sensor_msgs.msg import LaserScan as LaserScanMsg
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from ceamcl.errors import CeamclError, LogFormatError, MapFormatError
from ceamcl.filters.base import Hypothesis, PoseEstimate
from ceamcl.filters.state import LocalisationState, State
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.ros.transforms import Pose2, is_upside_down, quaternion_of, yaw_of
from ceamcl.sensors.scan import LaserScan

#: Largest map accepted (cells): 100 million, a 1 km x 1 km map at 10 cm.
MAX_MAP_CELLS = 100_000_000
#: Most beams accepted in one scan.
MAX_BEAMS = 100_000


def seconds(stamp: Time) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def time_msg(t: float) -> Time:
    sec = math.floor(t)
    return Time(sec=int(sec), nanosec=min(round((t - sec) * 1e9), 999_999_999))


def pose2_from_msg(pose: Pose) -> Pose2:
    """``(x, y, yaw)`` of a message pose; a non-finite value is an error."""
    q = pose.orientation
    values = (pose.position.x, pose.position.y, q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        raise CeamclError(f"pose: expected finite numbers, got {values}")
    if abs(q.x) + abs(q.y) + abs(q.z) + abs(q.w) == 0.0:
        raise CeamclError("pose: orientation: a zero quaternion")
    return (pose.position.x, pose.position.y, yaw_of(q.x, q.y, q.z, q.w))


def pose_msg(pose: Sequence[float] | np.ndarray[Any, np.dtype[np.float64]]) -> Pose:
    x, y, z, w = quaternion_of(float(pose[2]))
    return Pose(
        position=Point(x=float(pose[0]), y=float(pose[1]), z=0.0),
        orientation=Quaternion(x=x, y=y, z=z, w=w),
    )


def transform_msg(parent: str, child: str, pose: Pose2, stamp: float) -> TransformStamped:
    t = TransformStamped()
    t.header = Header(stamp=time_msg(stamp), frame_id=parent)
    t.child_frame_id = child
    t.transform.translation.x = float(pose[0])
    t.transform.translation.y = float(pose[1])
    x, y, z, w = quaternion_of(pose[2])
    t.transform.rotation = Quaternion(x=x, y=y, z=z, w=w)
    return t


def transform_pose2(t: TransformStamped) -> tuple[Pose2, bool]:
    """``(x, y, yaw)`` of a transform and whether it turns z downwards (upside down)."""
    q = t.transform.rotation
    v = t.transform.translation
    return (v.x, v.y, yaw_of(q.x, q.y, q.z, q.w)), is_upside_down(q.x, q.y, q.z, q.w)


def grid_from_msg(msg: OccupancyGridMsg) -> OccupancyGrid:
    """A ``nav_msgs/OccupancyGrid`` as ceamcl's grid (rows are y, as in ROS)."""
    w, h = int(msg.info.width), int(msg.info.height)
    if w == 0 or h == 0:
        raise MapFormatError(f"map: empty map ({w} x {h} cells)")
    if w * h > MAX_MAP_CELLS:
        raise MapFormatError(f"map: {w} x {h} cells is more than the {MAX_MAP_CELLS} accepted")
    if len(msg.data) != w * h:
        raise MapFormatError(f"map: data has {len(msg.data)} cells, expected {w} x {h} = {w * h}")
    origin = pose2_from_msg(msg.info.origin)
    data = np.asarray(msg.data, dtype=np.int8).reshape(h, w)
    # Nav2's amcl reads 0 as free, 100 as occupied and any other value as unknown; values
    # outside the message's -1..100 are unknown here too (the grid refuses them)
    data = np.where((data < -1) | (data > 100), np.int8(-1), data).astype(np.int8)
    return OccupancyGrid(data, float(msg.info.resolution), origin, name=msg.header.frame_id)


def scan_from_msg(
    msg: LaserScanMsg,
    mount: Pose2,
    *,
    upside_down: bool = False,
    range_min: float = -1.0,
    range_max: float = -1.0,
) -> LaserScan:
    """A ``sensor_msgs/LaserScan`` as ceamcl's scan, the laser at ``mount`` in the base frame.

    ``range_min`` / ``range_max`` > 0 narrow the scan's own limits, never widen them, as Nav2's
    ``laser_min_range`` and ``laser_max_range`` do (``max`` of the minima, ``min`` of the
    maxima): with the default ``laser_max_range`` of 100 m, a reading at the scan's own
    ``range_max`` stays a max-range reading. NaN and out-of-range readings are kept: the sensor
    models discard them. An upside-down laser sees the world mirrored: its bearings are
    negated.
    """
    n = len(msg.ranges)
    if n > MAX_BEAMS:
        raise LogFormatError(f"scan: {n} ranges is more than the {MAX_BEAMS} accepted")
    if n == 0:
        raise LogFormatError("scan: ranges: empty")
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    own_min, own_max = max(float(msg.range_min), 0.0), float(msg.range_max)
    angle_min, increment = float(msg.angle_min), float(msg.angle_increment)
    if upside_down:
        angle_min, increment = -angle_min, -increment
    return LaserScan(
        ranges=ranges,
        angle_min=angle_min,
        angle_increment=increment,
        range_min=max(own_min, range_min) if range_min > 0 else own_min,
        range_max=min(own_max, range_max) if range_max > 0 else own_max,
        pose=mount,
        stamp=seconds(msg.header.stamp),
    )


def covariance_from_msg(cov: Sequence[float]) -> np.ndarray[Any, np.dtype[np.float64]]:
    """The ``(x, y, yaw)`` block of a 6 x 6 row-major covariance."""
    c = np.asarray(cov, dtype=np.float64).reshape(6, 6)
    out = c[np.ix_([0, 1, 5], [0, 1, 5])]
    if not np.all(np.isfinite(out)):
        raise CeamclError("covariance: expected finite numbers")
    return 0.5 * (out + out.T)


def pose_with_covariance(
    estimate: PoseEstimate, frame: str, stamp: float
) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header = Header(stamp=time_msg(stamp), frame_id=frame)
    msg.pose.pose = pose_msg(estimate.pose)
    cov = np.zeros((6, 6))
    idx = [0, 1, 5]
    cov[np.ix_(idx, idx)] = estimate.covariance
    msg.pose.covariance = [float(v) for v in cov.reshape(-1)]
    return msg


def pose_array(poses: np.ndarray[Any, np.dtype[np.float64]], frame: str, stamp: float) -> PoseArray:
    msg = PoseArray()
    msg.header = Header(stamp=time_msg(stamp), frame_id=frame)
    msg.poses = [pose_msg(p) for p in poses]
    return msg


_COLOURS = [
    (0.12, 0.47, 0.71),
    (1.0, 0.5, 0.05),
    (0.17, 0.63, 0.17),
    (0.84, 0.15, 0.16),
    (0.58, 0.4, 0.74),
    (0.55, 0.34, 0.29),
    (0.89, 0.47, 0.76),
    (0.5, 0.5, 0.5),
]


def ellipse(cov_xy: np.ndarray[Any, np.dtype[np.float64]]) -> tuple[float, float, float]:
    """Diameters (m) of the 2-sigma ellipse of a 2 x 2 covariance and its major axis's angle."""
    vals, vecs = np.linalg.eigh(0.5 * (cov_xy + cov_xy.T))
    vals = np.clip(vals, 0.0, None)
    major = vecs[:, 1]
    return (
        max(4.0 * math.sqrt(vals[1]), 0.05),
        max(4.0 * math.sqrt(vals[0]), 0.05),
        math.atan2(major[1], major[0]),
    )


def hypothesis_markers(hypotheses: Sequence[Hypothesis], frame: str, stamp: float) -> MarkerArray:
    """Each hypothesis's living domain (its 2-sigma ellipse), heading arrow and a label with
    weight, fitness and particle count; the previous step's markers are deleted first."""
    header = Header(stamp=time_msg(stamp), frame_id=frame)
    markers = [Marker(header=header, ns="hypotheses", action=Marker.DELETEALL)]
    for i, h in enumerate(hypotheses):
        r, g, b = _COLOURS[i % len(_COLOURS)]
        major, minor, angle = ellipse(h.covariance[:2, :2])
        domain = Marker(header=header, ns="hypotheses", id=3 * i, type=Marker.CYLINDER)
        domain.pose = pose_msg((h.pose[0], h.pose[1], angle))
        domain.scale.x, domain.scale.y, domain.scale.z = major, minor, 0.02
        domain.color = ColorRGBA(r=r, g=g, b=b, a=0.25 + 0.5 * float(h.weight))
        arrow = Marker(header=header, ns="hypotheses", id=3 * i + 1, type=Marker.ARROW)
        arrow.pose = pose_msg(h.pose)
        arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.6, 0.08, 0.08
        arrow.color = ColorRGBA(r=r, g=g, b=b, a=1.0)
        label = Marker(header=header, ns="hypotheses", id=3 * i + 2, type=Marker.TEXT_VIEW_FACING)
        label.pose = pose_msg((h.pose[0], h.pose[1] + 0.5 * major + 0.3, 0.0))
        label.scale.z = 0.3
        label.color = ColorRGBA(r=r, g=g, b=b, a=1.0)
        label.text = f"w {h.weight:.2f}  fit {h.fitness:.2f}  n {h.n_particles}"
        markers += [domain, arrow, label]
    return MarkerArray(markers=markers)


def hypotheses_status(
    hypotheses: Sequence[Hypothesis], algorithm: str, node_name: str, stamp: float
) -> DiagnosticArray:
    """What is measured about the hypotheses: how many, each one's weight, fitness, particle
    count and pose (the localisation state read from them is ``~/state``, :func:`state_status`)."""
    values = [
        KeyValue(key="algorithm", value=algorithm),
        KeyValue(key="n_hypotheses", value=str(len(hypotheses))),
    ]
    for i, h in enumerate(hypotheses):
        values += [
            KeyValue(key=f"hypothesis_{i}.weight", value=f"{h.weight:.6g}"),
            KeyValue(key=f"hypothesis_{i}.fitness", value=f"{h.fitness:.6g}"),
            KeyValue(key=f"hypothesis_{i}.n_particles", value=str(h.n_particles)),
            KeyValue(
                key=f"hypothesis_{i}.pose",
                value=f"{h.pose[0]:.3f} {h.pose[1]:.3f} {h.pose[2]:.4f}",
            ),
        ]
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK,
        name=f"{node_name}: hypotheses",
        message=f"{len(hypotheses)} hypotheses (measured weights and fitness; "
        "the state is on ~/state)",
        hardware_id="",
        values=values,
    )
    return DiagnosticArray(header=Header(stamp=time_msg(stamp)), status=[status])


#: Diagnostic level of each state: LOCALISED OK, AMBIGUOUS and INITIALISING WARN, LOST ERROR.
STATE_LEVELS = {
    State.LOCALISED: DiagnosticStatus.OK,
    State.AMBIGUOUS: DiagnosticStatus.WARN,
    State.INITIALISING: DiagnosticStatus.WARN,
    State.LOST: DiagnosticStatus.ERROR,
}


def state_status(
    state: LocalisationState, algorithm: str, node_name: str, stamp: float
) -> DiagnosticArray:
    """``~/state``: the localisation state (issue 14, :mod:`ceamcl.filters.state`) as one
    diagnostic status: level OK (LOCALISED), WARN (AMBIGUOUS, INITIALISING) or ERROR (LOST),
    message ``STATE: reason``, values ``state``, ``confidence``, ``n_hypotheses``, ``weights``,
    ``map_explained`` (``nan`` where not judged)."""
    values = [
        KeyValue(key="algorithm", value=algorithm),
        KeyValue(key="state", value=state.state.name),
        KeyValue(key="confidence", value=f"{state.confidence:.4f}"),
        KeyValue(key="n_hypotheses", value=str(state.n_hypotheses)),
        KeyValue(key="weights", value=" ".join(f"{w:.4f}" for w in state.weights)),
        KeyValue(key="map_explained", value=f"{state.map_explained:.4f}"),
    ]
    status = DiagnosticStatus(
        level=STATE_LEVELS[state.state],
        name=f"{node_name}: localisation state",
        message=f"{state.state.name}: {state.reason}",
        hardware_id="",
        values=values,
    )
    return DiagnosticArray(header=Header(stamp=time_msg(stamp)), status=[status])
