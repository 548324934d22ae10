"""The ROS bag reader on small ROS 1 and ROS 2 bags written with ``rosbags``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ceamcl.errors import LogFormatError
from ceamcl.io.logs import log_format, open_log
from ceamcl.io.rosbag import read_bag

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

N_SCANS = 5
N_BEAMS = 9


def _msgs(ts: Any) -> dict[str, Any]:
    T = ts.types
    return {
        "Time": T["builtin_interfaces/msg/Time"],
        "Header": T["std_msgs/msg/Header"],
        "LaserScan": T["sensor_msgs/msg/LaserScan"],
        "Odometry": T["nav_msgs/msg/Odometry"],
        "Pose": T["geometry_msgs/msg/Pose"],
        "PoseWC": T["geometry_msgs/msg/PoseWithCovariance"],
        "Twist": T["geometry_msgs/msg/Twist"],
        "TwistWC": T["geometry_msgs/msg/TwistWithCovariance"],
        "Point": T["geometry_msgs/msg/Point"],
        "Quat": T["geometry_msgs/msg/Quaternion"],
        "Vec": T["geometry_msgs/msg/Vector3"],
        "TF": T["tf2_msgs/msg/TFMessage"],
        "TS": T["geometry_msgs/msg/TransformStamped"],
        "Transform": T["geometry_msgs/msg/Transform"],
    }


def _header(m: dict[str, Any], t: float, frame: str, ros1: bool) -> Any:
    stamp = m["Time"](sec=int(t), nanosec=round((t % 1) * 1e9))
    if ros1:
        return m["Header"](seq=0, stamp=stamp, frame_id=frame)
    return m["Header"](stamp=stamp, frame_id=frame)


def _quat(m: dict[str, Any], yaw: float) -> Any:
    return m["Quat"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _true_pose(t: float) -> tuple[float, float, float]:
    return 0.5 * t, 0.1 * t, 0.2 * t


def write_bag(
    path: Path,
    ros1: bool,
    *,
    odom: str = "topic",
    scan_topic: str = "/scan",
    bad_x: float | None = None,
    scan_delay: float = 0.0,
    range_max: float = 10.0,
    mcap: bool = False,
) -> Path:
    """A small bag; ``bad_x``: the x of the sixth odometry message (a broken pose);
    ``scan_delay``: seconds added to the scans' stamps (another clock)."""
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:  # the Noetic store lacks it
        ts.register(
            get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
            )
        )
    m = _msgs(ts)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    if ros1:
        writer = Writer1(path)
    elif mcap:
        writer = Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
    else:
        writer = Writer2(path, version=9)
    with writer:
        c_scan = writer.add_connection(scan_topic, m["LaserScan"].__msgtype__, typestore=ts)
        c_odom = (
            writer.add_connection("/odom", m["Odometry"].__msgtype__, typestore=ts)
            if odom == "topic"
            else None
        )
        c_tf = writer.add_connection("/tf", m["TF"].__msgtype__, typestore=ts)
        # laser 0.2 m ahead of the base, on /tf (once)
        link = m["TS"](
            header=_header(m, 0.05, "base_link", ros1),
            child_frame_id="laser",
            transform=m["Transform"](
                translation=m["Vec"](x=0.2, y=0.0, z=0.0), rotation=_quat(m, 0.0)
            ),
        )
        writer.write(c_tf, 50_000_000, ser(m["TF"](transforms=[link]), m["TF"].__msgtype__))
        for i in range(11):  # odometry at 10 Hz over 1 s
            t = 0.1 * i
            x, y, yaw = _true_pose(t)
            if bad_x is not None and i == 5:
                x = bad_x
            if c_odom is not None:
                msg = m["Odometry"](
                    header=_header(m, t, "odom", ros1),
                    child_frame_id="base_link",
                    pose=m["PoseWC"](
                        pose=m["Pose"](
                            position=m["Point"](x=x, y=y, z=0.0), orientation=_quat(m, yaw)
                        ),
                        covariance=np.zeros(36),
                    ),
                    twist=m["TwistWC"](
                        twist=m["Twist"](
                            linear=m["Vec"](x=0.0, y=0.0, z=0.0),
                            angular=m["Vec"](x=0.0, y=0.0, z=0.0),
                        ),
                        covariance=np.zeros(36),
                    ),
                )
                writer.write(c_odom, int(t * 1e9) + 1, ser(msg, m["Odometry"].__msgtype__))
            else:
                tfm = m["TS"](
                    header=_header(m, t, "odom", ros1),
                    child_frame_id="base_link",
                    transform=m["Transform"](
                        translation=m["Vec"](x=x, y=y, z=0.0), rotation=_quat(m, yaw)
                    ),
                )
                writer.write(
                    c_tf, int(t * 1e9) + 1, ser(m["TF"](transforms=[tfm]), m["TF"].__msgtype__)
                )
        for k in range(N_SCANS):
            t = 0.15 + 0.2 * k + scan_delay
            ranges = np.full(N_BEAMS, 1.0 + k, dtype=np.float32)
            ranges[0] = np.inf
            scan = m["LaserScan"](
                header=_header(m, t, "laser", ros1),
                angle_min=-1.0,
                angle_max=1.0,
                angle_increment=0.25,
                time_increment=0.0,
                scan_time=0.1,
                range_min=0.1,
                range_max=range_max,
                ranges=ranges,
                intensities=np.zeros(0, dtype=np.float32),
            )
            writer.write(c_scan, int(t * 1e9) + 2, ser(scan, m["LaserScan"].__msgtype__))
    return path


@pytest.mark.parametrize("ros1", [True, False], ids=["ros1", "ros2"])
@pytest.mark.parametrize("odom", ["topic", "tf"])
def test_bag_round_trip(tmp_path: Path, ros1: bool, odom: str) -> None:
    bag = write_bag(tmp_path / ("run.bag" if ros1 else "run"), ros1, odom=odom)
    assert log_format(bag) == ("ros1" if ros1 else "ros2")
    log = open_log(bag)
    assert len(log) == N_SCANS
    assert log.info["format"] == ("ros1" if ros1 else "ros2")
    expected_t = 0.15 + 0.2 * np.arange(N_SCANS)
    np.testing.assert_allclose(log.times, expected_t, atol=1e-6)
    # odometry interpolated at the scan stamps (the path is linear in t, yaw too)
    truth = np.array([_true_pose(t) for t in expected_t])
    np.testing.assert_allclose(log.poses, truth, atol=1e-6)
    scan = log.scan(2)
    assert scan.n_beams == N_BEAMS
    assert scan.angle_min == pytest.approx(-1.0)
    assert scan.angle_increment == pytest.approx(0.25)
    assert scan.range_max == pytest.approx(10.0)
    assert scan.ranges[1] == pytest.approx(3.0)
    assert np.isinf(scan.ranges[0])
    assert scan.pose == pytest.approx((0.2, 0.0, 0.0))  # from the base_link -> laser TF


def test_missing_scan_topic_lists_topics(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "run.bag", True)
    with pytest.raises(LogFormatError, match=r"'/front_scan'.*/scan \(sensor_msgs/msg/LaserScan\)"):
        read_bag(bag, scan_topic="/front_scan")


def test_missing_odom_topic_lists_topics(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "run", False)
    with pytest.raises(LogFormatError, match=r"/wheel_odom.*/odom \(nav_msgs/msg/Odometry\)"):
        read_bag(bag, odom_topic="/wheel_odom")


def test_missing_tf_pair_lists_transforms(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "run.bag", True, odom="tf")
    with pytest.raises(LogFormatError, match=r"odom -> base_footprint.*odom -> base_link"):
        read_bag(bag, base_frame="base_footprint")


@pytest.mark.parametrize(
    ("odom", "bad_x", "says"),
    [
        ("topic", math.nan, r"/odom: odometry message 5 .*: expected a finite position"),
        ("tf", math.inf, r"/tf odom -> base_link: odometry message 5 .*: expected a finite"),
        ("topic", 1e200, r"/odom: odometry message 5 .*: expected \|x\|, \|y\| <= 1e\+07 m"),
    ],
)
def test_a_broken_odometry_pose_is_named(
    tmp_path: Path, odom: str, bad_x: float, says: str
) -> None:
    """A NaN or absurd pose in the odometry is an error naming the bag, the source and the
    message (it ended in a traceback when the map was built from it)."""
    bag = write_bag(tmp_path / "b", False, odom=odom, bad_x=bad_x)
    with pytest.raises(LogFormatError, match=says):
        open_log(bag)


@pytest.mark.parametrize("ros1", [True, False], ids=["ros1", "ros2"])
def test_scans_stamped_outside_the_odometry_time_span_are_refused(
    tmp_path: Path, ros1: bool
) -> None:
    """Scans stamped by another clock than the odometry (5000 s against 0-1 s: simulated and
    wall time) each took the odometry's last pose: a robot that never moved, exit 0. No scan
    within the odometry's time span is now an error naming both spans."""
    bag = write_bag(tmp_path / ("run.bag" if ros1 else "run"), ros1, scan_delay=5000.0)
    with pytest.raises(
        LogFormatError,
        match=r"run(\.bag)?: the scans on /scan span 5000\.150 \.\. 5000\.950 s and the "
        r"odometry on /odom 0\.000 \.\. 1\.000 s: the times do not overlap",
    ):
        open_log(bag)


def test_scans_a_little_past_the_odometry_take_its_last_pose(tmp_path: Path) -> None:
    """Real logs start and end their streams at slightly different times: scans after the last
    odometry message (here the last two of five) are kept with the last pose."""
    log = open_log(write_bag(tmp_path / "run.bag", True, scan_delay=0.3))
    expected_t = 0.45 + 0.2 * np.arange(N_SCANS)
    np.testing.assert_allclose(log.times, expected_t, atol=1e-6)
    truth = np.array([_true_pose(min(t, 1.0)) for t in expected_t])
    np.testing.assert_allclose(log.poses, truth, atol=1e-6)


@pytest.mark.parametrize("range_max", [math.inf, math.nan, 0.0])
def test_a_scan_range_max_that_is_not_a_positive_finite_number_is_named(
    tmp_path: Path, range_max: float
) -> None:
    """range_max: inf passed the reader's check (only > 0) and failed later as 'scan:
    range_max: expected a positive finite number, got inf', naming no bag or topic."""
    bag = write_bag(tmp_path / "run.bag", True, range_max=range_max)
    expected = (
        r"range_max inf: expected a finite number of metres \(--max-range sets"
        if range_max == float("inf")
        else r"expected 0 <= range_min < range_max, got range_min=0\.1.*, range_max="
        + str(range_max)
    )
    with pytest.raises(
        LogFormatError, match=r"run\.bag: /scan: scan 0 \(t=0\.150 s\): " + expected
    ):
        open_log(bag)
    if range_max == float("inf"):  # what --max-range is for: the bag's own maximum is replaced
        assert np.all(open_log(bag, max_range_m=8.0).range_max == 8.0)


def test_a_log_that_starts_with_nul_bytes_is_a_carmen_log_with_binary_data(tmp_path: Path) -> None:
    """A log zero-filled after a crash was sent to the bag reader ('Unrecognized storage
    format .log'): only a .mcap or .db3 file is looked at as a ROS 2 bag's storage."""
    p = tmp_path / "run.log"
    p.write_bytes(b"\0\0\0\0" + b"FLASER 0 0 0 0 0 0 0 0 nohost 0\n")
    assert log_format(p) == "carmen"
    with pytest.raises(LogFormatError, match=r"run\.log:1: binary data \(NUL bytes\)"):
        open_log(p)


@pytest.mark.parametrize("mcap", [True, False], ids=["mcap", "db3"])
def test_a_ros2_storage_file_out_of_its_folder_is_read_as_a_bag(tmp_path: Path, mcap: bool) -> None:
    """A lone .mcap (or .db3) file, copied out of its bag folder, was read as a CARMEN log:
    'alone.mcap:1: not UTF-8/ASCII text (byte 0x89 at column 1); expected a CARMEN text log'.
    rosbags reads such a file on its own; a damaged one says to read the bag's folder."""
    import shutil

    folder = write_bag(tmp_path / "run", False, mcap=mcap)
    suffix = ".mcap" if mcap else ".db3"
    lone = tmp_path / f"alone{suffix}"
    shutil.copy(next(folder.glob(f"*{suffix}")), lone)
    assert log_format(lone) == "ros2"
    log, whole = open_log(lone), open_log(folder)
    assert len(log) == N_SCANS and log.info["format"] == "ros2"
    np.testing.assert_array_equal(log.times, whole.times)
    np.testing.assert_array_equal(log.poses, whole.poses)
    np.testing.assert_array_equal(log.ranges_flat, whole.ranges_flat)
    cut = tmp_path / f"cut{suffix}"
    cut.write_bytes(lone.read_bytes()[:300])
    with pytest.raises(
        LogFormatError,
        match=rf"cut\{suffix}: cannot open the \{suffix} file of a ROS 2 bag on its own: .*; "
        r"read the bag from its folder \(the one holding metadata\.yaml\)",
    ):
        open_log(cut)
