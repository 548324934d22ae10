"""ROS 1 and ROS 2 bags through the ``rosbags`` library (no ROS installation needed).

:func:`read_bag` reads ``sensor_msgs/LaserScan`` messages of one topic and the robot's
odometry pose at each scan, from

* a ``nav_msgs/Odometry`` topic (``--odom-topic``, or the bag's only Odometry topic), or
* the ``odom_frame -> base_frame`` transform on ``/tf`` when the bag has no Odometry topic.

Poses are interpolated at each scan's header stamp (linear in x, y; shorter arc in yaw); a
scan stamped 0 takes the bag's receive time. Scans whose stamps do not overlap the odometry's
time span at all (another clock) are refused (:func:`ceamcl.io.recorded.poses_at_scans`).
The laser's mounting pose comes from the ``base_frame -> <scan frame>`` transform on
``/tf_static`` or ``/tf`` when the bag has one, else the laser is taken to sit at the base.
Readings outside ``[range_min, range_max]``, NaN and infinities are no-return, as in
``sensor_msgs/LaserScan``.

A missing topic or frame raises :class:`~ceamcl.errors.LogFormatError` listing what the bag
holds. Bags are read as a stream; only the scans and poses are kept.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ceamcl import budget
from ceamcl.errors import CeamclError, LogFormatError
from ceamcl.io import streams
from ceamcl.io.quaternion import quaternion_yaw
from ceamcl.io.recorded import (
    POSE_LIMIT_M,
    RecordedLog,
    check_pose_values,
    poses_at_scans,
)

__all__ = ["LASER_SCAN", "ODOMETRY", "TF", "read_bag"]

#: Memory kept per bag record read (times, poses, lists) and per range reading (the ranges
#: and the arrays built from them), for the budget checks (ceamcl.budget).
RECORD_BYTES = 256
RANGE_BYTES = 24

LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"


def _stamp(header: Any, fallback_ns: int) -> float:
    s = header.stamp.sec + header.stamp.nanosec * 1e-9
    return s if s > 0 else fallback_ns * 1e-9


def _strip(frame: str) -> str:
    return frame.lstrip("/")


def _topics(connections: list[Any]) -> str:
    seen = sorted({(c.topic, c.msgtype) for c in connections})
    return ", ".join(f"{t} ({m})" for t, m in seen) or "none"


def _bag_paths(path: Path) -> list[Path]:
    if path.is_dir():
        return [path]
    if path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").is_file():
        return [path.parent]
    return [path]


def read_bag(
    path: str | os.PathLike[str],
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    odom_frame: str = "odom",
    base_frame: str = "base_link",
) -> RecordedLog:
    """Scans of one LaserScan topic with the robot's odometry pose at each (module doc)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    p = Path(path)
    if streams.is_stream(p):
        raise LogFormatError(
            f"{p}: a ROS bag cannot be read from a pipe or device (it is read by seeking); "
            "save it to a file first"
        )
    paths = _bag_paths(p)
    # a ROS 2 storage file out of its folder: rosbags reads it alone (its own topic list)
    lone = paths[0].is_file() and paths[0].suffix in (".db3", ".mcap")
    try:
        reader = AnyReader(paths, default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except CeamclError:
        raise
    except Exception as exc:  # rosbags raises many types on a damaged container
        if lone:
            raise LogFormatError(
                f"{p}: cannot open the {p.suffix} file of a ROS 2 bag on its own: "
                f"{_one_line(exc)}; read the bag from its folder (the one holding metadata.yaml)"
            ) from None
        raise LogFormatError(f"{p}: cannot open the bag: {_one_line(exc)}") from None
    try:
        return _read(reader, p, scan_topic, odom_topic, _strip(odom_frame), _strip(base_frame))
    except CeamclError:
        raise
    except MemoryError:
        raise LogFormatError(
            f"{p}: a record of the bag claims more memory than there is (a damaged bag?)"
        ) from None
    except Exception as exc:  # damaged records, bad message definitions
        raise LogFormatError(f"{p}: cannot read the bag's records: {_one_line(exc)}") from None
    finally:
        try:
            reader.close()
        except Exception:  # closing a damaged bag must not hide the error
            pass


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def _pick(
    conns: list[Any], msgtype: str, topic: str | None, what: str, p: Path, all_conns: list[Any]
) -> list[Any]:
    of_type = [c for c in conns if c.msgtype == msgtype]
    if topic is not None:
        chosen = [c for c in of_type if c.topic == topic]
        if not chosen:
            raise LogFormatError(
                f"{p}: no {msgtype} messages on topic {topic!r}; the bag has: {_topics(all_conns)}"
            )
        return chosen
    topics = sorted({c.topic for c in of_type})
    if len(topics) > 1:
        raise LogFormatError(
            f"{p}: several {what} topics ({', '.join(topics)}); choose one with --{what}-topic"
        )
    return of_type


def _read(
    reader: Any,
    p: Path,
    scan_topic: str | None,
    odom_topic: str | None,
    odom_frame: str,
    base_frame: str,
) -> RecordedLog:
    conns = list(reader.connections)
    scan_conns = _pick(conns, LASER_SCAN, scan_topic, "scan", p, conns)
    if not scan_conns:
        raise LogFormatError(f"{p}: no {LASER_SCAN} topic; the bag has: {_topics(conns)}")
    odom_conns = _pick(conns, ODOMETRY, odom_topic, "odom", p, conns)
    tf_conns = [c for c in conns if c.msgtype == TF]
    use_tf = not odom_conns
    if use_tf and not tf_conns:
        raise LogFormatError(
            f"{p}: no {ODOMETRY} topic and no /tf to take the {odom_frame} -> {base_frame} "
            f"transform from; the bag has: {_topics(conns)}"
        )

    times: list[float] = []
    ranges: list[NDArray[np.float64]] = []
    meta: list[tuple[float, float, float, float]] = []
    frames: list[str] = []
    odo: list[tuple[float, float, float, float, float, float, float]] = []  # t x y quaternion
    links: dict[tuple[str, str], tuple[float, float, float]] = {}
    tf_pairs: set[tuple[str, str]] = set()
    wanted = scan_conns + odom_conns + tf_conns
    records = sum(int(getattr(c, "msgcount", 0) or 0) for c in wanted)
    budget.require(f"{p}: scan, odometry and /tf records", records, RECORD_BYTES, "records")
    beams = 0
    for conn, t_ns, raw in reader.messages(connections=wanted):
        msg = reader.deserialize(raw, conn.msgtype)
        if conn.msgtype == LASER_SCAN:
            times.append(_stamp(msg.header, t_ns))
            ranges.append(np.asarray(msg.ranges, dtype=np.float64))
            beams += ranges[-1].size
            if beams * RANGE_BYTES > budget.current().memory_bytes:
                budget.require(f"{p}: {conn.topic}", beams, RANGE_BYTES, "range readings")
            meta.append(
                (
                    float(msg.angle_min),
                    float(msg.angle_increment),
                    float(msg.range_min),
                    float(msg.range_max),
                )
            )
            frames.append(_strip(msg.header.frame_id))
        elif conn.msgtype == ODOMETRY:
            pos, q = msg.pose.pose.position, msg.pose.pose.orientation
            odo.append((_stamp(msg.header, t_ns), pos.x, pos.y, q.x, q.y, q.z, q.w))
        else:
            for tf in msg.transforms:
                parent, child = _strip(tf.header.frame_id), _strip(tf.child_frame_id)
                tf_pairs.add((parent, child))
                tr, q = tf.transform.translation, tf.transform.rotation
                if use_tf and parent == odom_frame and child == base_frame:
                    odo.append((_stamp(tf.header, t_ns), tr.x, tr.y, q.x, q.y, q.z, q.w))
                elif parent == base_frame:
                    links[(parent, child)] = (tr.x, tr.y, float(quaternion_yaw(q.x, q.y, q.z, q.w)))
    if not times:
        raise LogFormatError(f"{p}: the scan topic holds no message")
    if not odo:
        if use_tf:
            pairs = ", ".join(f"{a} -> {b}" for a, b in sorted(tf_pairs)) or "none"
            raise LogFormatError(
                f"{p}: /tf has no {odom_frame} -> {base_frame} transform (--odom-frame, "
                f"--base-frame); transforms present: {pairs}"
            )
        raise LogFormatError(f"{p}: the odometry topic holds no message")
    n = len(times)
    t = np.asarray(times, dtype=np.float64)
    o = np.asarray(odo, dtype=np.float64)
    yaw = quaternion_yaw(o[:, 3], o[:, 4], o[:, 5], o[:, 6])
    source = odom_conns[0].topic if odom_conns else f"/tf {odom_frame} -> {base_frame}"
    bad = np.flatnonzero(~np.isfinite(o).all(axis=1) | ~np.isfinite(yaw))
    if bad.size:
        k = int(bad[0])
        raise LogFormatError(
            f"{p}: {source}: odometry message {k} (t={o[k, 0]:.3f} s): expected a finite "
            f"position and orientation, got x={o[k, 1]}, y={o[k, 2]}, quaternion {o[k, 3:7]}"
        )
    far = np.flatnonzero(np.abs(o[:, 1:3]).max(axis=1) > POSE_LIMIT_M)
    if far.size:
        k = int(far[0])
        check_pose_values(
            np.array([o[k, 1], o[k, 2], yaw[k]]),
            f"odometry message {k} (t={o[k, 0]:.3f} s)",
            lambda what: LogFormatError(f"{p}: {source}: {what}"),
        )
    for (parent, child), link in links.items():
        if not np.all(np.isfinite(link)):
            raise LogFormatError(
                f"{p}: /tf {parent} -> {child}: expected a finite laser mount, got {link}"
            )
    poses = poses_at_scans(
        o[:, 0],
        np.column_stack([o[:, 1], o[:, 2], yaw]),
        t,
        scans=f"the scans on {scan_conns[0].topic}",
        odometry=f"the odometry on {source}",
        error=lambda what: LogFormatError(f"{p}: {what}"),
    )
    m = np.asarray(meta, dtype=np.float64)
    for k in range(n):
        if not (np.isfinite(m[k, 0]) and np.isfinite(m[k, 1])):
            raise LogFormatError(
                f"{p}: scan {k}: expected finite angle_min and angle_increment, got "
                f"angle_min={m[k, 0]}, angle_increment={m[k, 1]}"
            )
        # an infinite range_max passes here: --max-range may set it (io.logs.open_log
        # refuses what is left non-finite)
        if not (m[k, 3] > 0 and 0 <= m[k, 2] < m[k, 3]):
            raise LogFormatError(
                f"{p}: {scan_conns[0].topic}: scan {k} (t={t[k]:.3f} s): expected "
                f"0 <= range_min < range_max, got range_min={m[k, 2]}, range_max={m[k, 3]}"
            )
    mount = np.array([links.get((base_frame, f), (0.0, 0.0, 0.0)) for f in frames])
    offsets = np.concatenate([[0], np.cumsum([r.size for r in ranges])]).astype(np.intp)
    fmt = "ros1" if not reader.is2 else "ros2"
    info = {
        "format": fmt,
        "scan_topic": scan_conns[0].topic,
        "odometry_from": odom_conns[0].topic if odom_conns else f"/tf {odom_frame}->{base_frame}",
        "laser_mount_from_tf": any((base_frame, f) in links for f in set(frames)),
        "topics": {c.topic: c.msgtype for c in conns},
    }
    return RecordedLog(
        path=str(p),
        times=t,
        poses=poses,
        ranges_flat=np.concatenate(ranges),
        offsets=offsets,
        angle_min=m[:, 0],
        angle_increment=m[:, 1],
        range_min=m[:, 2],
        range_max=m[:, 3],
        laser_mount=mount.reshape(n, 3),
        info=info,
    )
