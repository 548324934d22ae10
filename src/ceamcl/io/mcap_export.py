"""Export a run as MCAP for Foxglove: map, particles, estimate, ground truth, scans, transforms.

Every message is JSON in one of Foxglove's own schemas (``foxglove.*``, JSON Schema encoding),
which Foxglove's 3D panel shows without any configuration:

========================  =========================  =============================================
topic                     schema                     when
========================  =========================  =============================================
``/map``                  ``foxglove.Grid``          once, at the first step; frame ``map``
``/particles``            ``foxglove.PosesInFrame``  every step with particles kept (snapshots)
``/estimate``             ``foxglove.PoseInFrame``   every step; frame ``map``
``/ground_truth``         ``foxglove.PoseInFrame``   every step, when the log knows the truth
``/scan``                 ``foxglove.LaserScan``     every step, when the log is given; frame
                                                     ``laser``
``/tf``                   ``foxglove.FrameTransforms``  every step: ``map -> base_link`` and
                                                     ``base_link -> laser``
``/state``                ``ceamcl.LocalisationState``  every step the runner recorded it: the
                                                     state (LOCALISED, AMBIGUOUS, LOST,
                                                     INITIALISING), confidence, hypotheses,
                                                     their weights, the reason (issue 14)
                                                     and the map's share of the scan
========================  =========================  =============================================

``map -> base_link`` is the ground truth where the log has it (so the scan lands where the robot
really was and one sees how well the particles agree), else the filter's estimate. Timestamps
are the log's times (seconds from its start for simulated logs). The map grid carries RGBA
fields (free white, occupied black, unknown grey) and the ROS occupancy value (``occupancy``,
INT8: 0 free, 100 occupied, -1 unknown).
"""

from __future__ import annotations

import base64
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from mcap.writer import Writer
from numpy.typing import NDArray

from ceamcl.filters.base import ParticleSnapshot
from ceamcl.io.quaternion import yaw_to_quaternion
from ceamcl.io.results import atomic_write
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult
from ceamcl.sensors.scan import LaserScan

MAP_FRAME = "map"
BASE_FRAME = "base_link"
LASER_FRAME = "laser"

# ---------------------------------------------------------------- Foxglove JSON schemas
_TIME: dict[str, Any] = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
    },
}
_VECTOR3: dict[str, Any] = {
    "title": "foxglove.Vector3",
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z")},
}
_VECTOR2: dict[str, Any] = {
    "title": "foxglove.Vector2",
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y")},
}
_QUATERNION: dict[str, Any] = {
    "title": "foxglove.Quaternion",
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z", "w")},
}
_POSE: dict[str, Any] = {
    "title": "foxglove.Pose",
    "type": "object",
    "properties": {"position": _VECTOR3, "orientation": _QUATERNION},
}
_NUMERIC_TYPES = (
    "UNKNOWN",
    "UINT8",
    "INT8",
    "UINT16",
    "INT16",
    "UINT32",
    "INT32",
    "FLOAT32",
    "FLOAT64",
)
_PACKED_FIELD: dict[str, Any] = {
    "title": "foxglove.PackedElementField",
    "type": "object",
    "properties": {
        "name": {"type": "string"},
        "offset": {"type": "integer", "minimum": 0},
        "type": {
            "title": "foxglove.NumericType",
            "oneOf": [{"title": t, "const": i} for i, t in enumerate(_NUMERIC_TYPES)],
        },
    },
}
_FRAME_TRANSFORM: dict[str, Any] = {
    "title": "foxglove.FrameTransform",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VECTOR3,
        "rotation": _QUATERNION,
    },
}


def _schema(title: str, description: str, properties: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "title": title,
        "description": description,
        "type": "object",
        "properties": dict(properties),
    }


SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.Grid": _schema(
        "foxglove.Grid",
        "A 2D grid of data",
        {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "pose": _POSE,
            "column_count": {"type": "integer", "minimum": 0},
            "cell_size": _VECTOR2,
            "row_stride": {"type": "integer", "minimum": 0},
            "cell_stride": {"type": "integer", "minimum": 0},
            "fields": {"type": "array", "items": _PACKED_FIELD},
            "data": {"type": "string", "contentEncoding": "base64"},
        },
    ),
    "foxglove.PosesInFrame": _schema(
        "foxglove.PosesInFrame",
        "An array of timestamped poses for an object or reference frame in 3D space",
        {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "poses": {"type": "array", "items": _POSE},
        },
    ),
    "foxglove.PoseInFrame": _schema(
        "foxglove.PoseInFrame",
        "A timestamped pose for an object or reference frame in 3D space",
        {"timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE},
    ),
    "foxglove.LaserScan": _schema(
        "foxglove.LaserScan",
        "A single scan from a planar laser range-finder",
        {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "pose": _POSE,
            "start_angle": {"type": "number"},
            "end_angle": {"type": "number"},
            "ranges": {"type": "array", "items": {"type": "number"}},
            "intensities": {"type": "array", "items": {"type": "number"}},
        },
    ),
    "foxglove.FrameTransforms": _schema(
        "foxglove.FrameTransforms",
        "An array of FrameTransform messages",
        {"transforms": {"type": "array", "items": _FRAME_TRANSFORM}},
    ),
}

SCHEMAS["ceamcl.LocalisationState"] = _schema(
    "ceamcl.LocalisationState",
    "Whether to trust the pose: LOCALISED, AMBIGUOUS, LOST or INITIALISING (ceamcl.filters.state)",
    {
        "timestamp": _TIME,
        "state": {"type": "string"},
        "confidence": {"type": "number"},
        "n_hypotheses": {"type": "integer"},
        "weights": {"type": "array", "items": {"type": "number"}},
        "reason": {"type": "string"},
        "map_explained": {"type": ["number", "null"]},
    },
)

TOPICS: dict[str, str] = {
    "/map": "foxglove.Grid",
    "/particles": "foxglove.PosesInFrame",
    "/estimate": "foxglove.PoseInFrame",
    "/ground_truth": "foxglove.PoseInFrame",
    "/scan": "foxglove.LaserScan",
    "/tf": "foxglove.FrameTransforms",
    "/state": "ceamcl.LocalisationState",
}


class ScanLog(Protocol):
    """What the exporter needs of a log: its length and its scans."""

    def __len__(self) -> int: ...

    def scan(self, k: int) -> LaserScan: ...


# ---------------------------------------------------------------- message builders
def time_ns(t: float) -> int:
    """Seconds to integer nanoseconds (MCAP log time); negative times are clamped to 0."""
    return max(round(float(t) * 1e9), 0)


def stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def yaw_quaternion(yaw: float) -> dict[str, float]:
    qz, qw = yaw_to_quaternion(yaw)
    return {"x": 0.0, "y": 0.0, "z": float(qz), "w": float(qw)}


def pose_2d(x: float, y: float, yaw: float) -> dict[str, Any]:
    return {
        "position": {"x": float(x), "y": float(y), "z": 0.0},
        "orientation": yaw_quaternion(float(yaw)),
    }


def grid_message(grid: OccupancyGrid, ns: int) -> dict[str, Any]:
    """``foxglove.Grid``: RGBA (UINT8 x 4) and the ROS occupancy (INT8) per cell, row 0 at the
    origin (lowest y), as ``nav_msgs/OccupancyGrid``."""
    h, w = grid.data.shape
    cells = np.empty((h, w, 5), dtype=np.uint8)
    grey = np.full((h, w), 255, dtype=np.uint8)
    grey[grid.unknown_mask] = 190
    grey[grid.occupied_mask] = 0
    cells[..., 0] = cells[..., 1] = cells[..., 2] = grey
    cells[..., 3] = 255
    cells[..., 4] = grid.data.view(np.uint8)
    ox, oy, oyaw = grid.origin
    return {
        "timestamp": stamp(ns),
        "frame_id": MAP_FRAME,
        "pose": pose_2d(ox, oy, oyaw),
        "column_count": int(w),
        "cell_size": {"x": grid.resolution, "y": grid.resolution},
        "row_stride": int(w * 5),
        "cell_stride": 5,
        "fields": [
            {"name": "red", "offset": 0, "type": 1},
            {"name": "green", "offset": 1, "type": 1},
            {"name": "blue", "offset": 2, "type": 1},
            {"name": "alpha", "offset": 3, "type": 1},
            {"name": "occupancy", "offset": 4, "type": 2},
        ],
        "data": base64.b64encode(cells.tobytes()).decode("ascii"),
    }


_PARTICLE_JSON = (
    '{"position":{"x":%.4f,"y":%.4f,"z":0.0},"orientation":{"x":0.0,"y":0.0,"z":%.6f,"w":%.6f}}'
)


def poses_json(poses: NDArray[np.float64], ns: int) -> bytes:
    """``foxglove.PosesInFrame`` of particles as JSON bytes. Positions are rounded to 0.1 mm and
    quaternions to 1e-6 (about 2e-6 rad): thousands of particles per step stay small and fast
    (one C-level format call per message instead of a dict per particle)."""
    p = np.asarray(poses, dtype=np.float64)[:, :3]
    if not np.all(np.isfinite(p)):
        raise ValueError("poses_json: particle poses must be finite")
    qz, qw = yaw_to_quaternion(p[:, 2])
    flat = np.column_stack([p[:, 0], p[:, 1], qz, qw]).ravel().tolist()
    body = ",".join([_PARTICLE_JSON] * p.shape[0]) % tuple(flat) if p.shape[0] else ""
    head = json.dumps({"timestamp": stamp(ns), "frame_id": MAP_FRAME}, separators=(",", ":"))
    return (head[:-1] + ',"poses":[' + body + "]}").encode()


def pose_message(pose: NDArray[np.float64], ns: int) -> dict[str, Any]:
    return {"timestamp": stamp(ns), "frame_id": MAP_FRAME, "pose": pose_2d(*pose[:3])}


def scan_message(scan: LaserScan, ns: int) -> dict[str, Any]:
    """``foxglove.LaserScan`` in the laser frame. Max-range readings (no return) stay at
    ``range_max``; NaN readings become ``range_max`` too (JSON has no NaN)."""
    ranges = np.where(np.isfinite(scan.ranges), scan.ranges, scan.range_max)
    return {
        "timestamp": stamp(ns),
        "frame_id": LASER_FRAME,
        "pose": pose_2d(0.0, 0.0, 0.0),
        "start_angle": float(scan.angle_min),
        "end_angle": float(scan.angle_min + scan.angle_increment * max(scan.n_beams - 1, 0)),
        "ranges": [float(r) for r in ranges],
        "intensities": [],
    }


def transform(parent: str, child: str, pose: Sequence[float], ns: int) -> dict[str, Any]:
    x, y, yaw = (float(v) for v in pose[:3])
    return {
        "timestamp": stamp(ns),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": {"x": x, "y": y, "z": 0.0},
        "rotation": yaw_quaternion(yaw),
    }


# ---------------------------------------------------------------- writer
def _particle_steps(result: RunResult) -> dict[int, ParticleSnapshot]:
    out = {0: result.initial_particles, **result.snapshots}
    out[result.steps - 1] = result.final_particles
    return dict(sorted(out.items()))


def write_mcap(
    path: str | os.PathLike[str],
    result: RunResult,
    grid: OccupancyGrid,
    log: ScanLog | None = None,
) -> Path:
    """Write ``result`` (and the scans of ``log``, if given) to the MCAP file ``path``.

    Particles are exported at every step the run kept them (``run_filter(...,
    snapshot_every=k)``), plus the first and the last step. The file is written to a temporary
    name and renamed, so a failure leaves no half-written file.
    """
    if log is not None and len(log) != result.steps:
        raise ValueError(
            f"write_mcap: the log has {len(log)} entries but the run has {result.steps} steps"
        )
    with atomic_write(path) as tmp:
        with tmp.open("wb") as fh:
            writer = Writer(fh)
            writer.start(profile="", library="ceamcl")
            schema_ids = {
                name: writer.register_schema(
                    name=name, encoding="jsonschema", data=json.dumps(schema).encode()
                )
                for name, schema in SCHEMAS.items()
            }
            topics = ["/map", "/particles", "/estimate", "/tf"]
            if result.truth is not None:
                topics.append("/ground_truth")
            if log is not None:
                topics.append("/scan")
            states = result.states
            if any(st is not None for st in states):
                topics.append("/state")
            channels = {
                t: writer.register_channel(
                    topic=t, message_encoding="json", schema_id=schema_ids[TOPICS[t]]
                )
                for t in topics
            }
            sequence: dict[str, int] = dict.fromkeys(topics, 0)

            def emit(topic: str, ns: int, message: Mapping[str, Any] | bytes) -> None:
                data = (
                    message
                    if isinstance(message, bytes)
                    else json.dumps(message, separators=(",", ":"), allow_nan=False).encode()
                )
                writer.add_message(channels[topic], ns, data, ns, sequence[topic])
                sequence[topic] += 1

            times = [time_ns(t) for t in result.times]
            emit("/map", times[0], grid_message(grid, times[0]))
            particles = _particle_steps(result)
            laser_pose = (0.0, 0.0, 0.0)
            known = result.truth_known
            for k, ns in enumerate(times):
                # map -> base_link is the truth where the log knows it (a raw log's paired
                # scans), else the estimate; NaN is no JSON
                base = (
                    result.truth[k]
                    if result.truth is not None and known[k]
                    else result.estimates[k]
                )
                scan = log.scan(k) if log is not None else None
                if scan is not None:
                    laser_pose = scan.pose
                emit(
                    "/tf",
                    ns,
                    {
                        "transforms": [
                            transform(MAP_FRAME, BASE_FRAME, base, ns),
                            transform(BASE_FRAME, LASER_FRAME, laser_pose, ns),
                        ]
                    },
                )
                emit("/estimate", ns, pose_message(result.estimates[k], ns))
                if result.truth is not None and known[k]:
                    emit("/ground_truth", ns, pose_message(result.truth[k], ns))
                if scan is not None:
                    emit("/scan", ns, scan_message(scan, ns))
                if k in particles:
                    emit("/particles", ns, poses_json(particles[k].poses, ns))
                st = states[k]
                if st is not None:
                    emit(
                        "/state",
                        ns,
                        {
                            "timestamp": stamp(ns),
                            "state": st.state.name,
                            "confidence": st.confidence,
                            "n_hypotheses": st.n_hypotheses,
                            "weights": list(st.weights),
                            "reason": st.reason,
                            # JSON has no NaN: null where the map was not judged
                            "map_explained": (
                                st.map_explained if math.isfinite(st.map_explained) else None
                            ),
                        },
                    )
            writer.finish()
    return Path(path)
