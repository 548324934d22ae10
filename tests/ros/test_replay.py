"""Real logs through ROS (../shared/data; skipped, saying why, where it is absent).

1. The first 120 scans of intel-corrected, sent at the node's pace (odometry TF, laser mount,
   scans): every ``amcl_pose`` equals, bit for bit, what the same filter gives offline with the
   same seed and the same messages, so the node adds transport and nothing else.
2. ``ceamcl play`` publishes fhw-corrected at 200 times its pace: the node takes it from there
   (map, TF, scans, initial pose at the first scan), and ``ground_truth`` arrives for every
   scan. (How well the filters track fhw is docs/real-data.md's subject, not this test's.)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.needs_ros

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "carmen"
TOLERANCE_S = 0.2


def real_log(name: str) -> Path:
    path = DATA / name
    if not path.is_file():
        pytest.skip(f"real log {path} is absent (the shared data folder is not mounted)")
    return path


def test_real_log_through_the_node_equals_offline(driver, tmp_path: Path) -> None:
    from rclpy.serialization import deserialize_message, serialize_message

    from ceamcl.io.logs import open_log
    from ceamcl.mapping import map_from_log
    from ceamcl.motion.odometry import OdometryNoise
    from ceamcl.ros import messages as m
    from ceamcl.ros.localiser import Localiser
    from ceamcl.ros.params import parse
    from ceamcl.ros.play import grid_msg, scan_msg
    from ceamcl.ros.transforms import TransformBuffer
    from tests.ros.harness import BASE, LASER, ODOM, NodeProcess

    log = open_log(real_log("intel-corrected.log.gz"))
    log = log.with_synthetic_odometry(OdometryNoise(), np.random.default_rng(0)).window(0, 120)
    grid, _ = map_from_log(log)
    values = {"seed": 4, "z_hit": 0.95, "z_rand": 0.05, "transform_tolerance": TOLERANCE_S}
    args = ["--ros-args", *[a for k, v in values.items() for a in ("-p", f"{k}:={v}")]]
    t0 = 5_000.0

    def sent(msg):  # what a subscriber receives: float32 fields rounded, as on the wire
        return deserialize_message(serialize_message(msg), type(msg))

    # offline: the messages the node receives, converted as the node converts them
    params = parse(values)
    localiser = Localiser(params)
    localiser.set_map(m.grid_from_msg(sent(grid_msg(grid, "map", t0))))
    tf = TransformBuffer()
    mount_msg = sent(m.transform_msg(BASE, LASER, tuple(log.laser_mount[0]), 0.0))
    tf.set_transform(BASE, LASER, m.transform_pose2(mount_msg)[0], 0.0, static=True)
    offline: dict[float, tuple[float, float, float]] = {}
    for k in range(len(log)):
        stamp = m.seconds(m.time_msg(t0 + float(log.times[k] - log.times[0])))
        odom_msg = sent(m.transform_msg(ODOM, BASE, tuple(log.odometry[k]), stamp))
        tf.set_transform(ODOM, BASE, m.transform_pose2(odom_msg)[0], stamp, static=False)
        scan = m.scan_from_msg(
            sent(scan_msg(log, k, LASER, stamp)),
            tf.lookup(BASE, LASER, stamp),
            range_min=params["laser_min_range"],
            range_max=params["laser_max_range"],
        )
        estimate = localiser.scan(tf.lookup(ODOM, BASE, stamp), scan)
        if estimate is not None:
            offline[stamp] = (
                float(estimate.pose[0]),
                float(estimate.pose[1]),
                float(estimate.pose[2]),
            )

    with NodeProcess(tmp_path, args) as node:
        driver.configure_and_activate()
        seen = node.log().count("map received")
        driver.publish_mount(tuple(log.laser_mount[0]))
        driver.map_pub.publish(grid_msg(grid, "map", t0))
        assert node.wait_for("map received", 20.0, count=seen + 1)
        for k in range(len(log)):
            stamp = t0 + float(log.times[k] - log.times[0])
            driver.publish_odom(log.odometry[k], stamp)
            driver.scan_pub.publish(scan_msg(log, k, LASER, stamp))
            key = m.seconds(m.time_msg(stamp)) + TOLERANCE_S
            assert driver.spin_until(
                lambda key=key: any(abs(s - key) < 1e-6 for s in driver.map_to_odom), 30.0
            ), f"scan {k}: no map -> odom\n{node.log()[-2000:]}"
        assert driver.spin_until(lambda: len(driver.poses) >= len(offline), 10.0)
        assert "Traceback" not in node.log()

    online = {m.seconds(p.header.stamp): m.pose2_from_msg(p.pose.pose) for p in driver.poses}
    assert sorted(online) == pytest.approx(sorted(offline), abs=1e-6)
    for (_, a), (_, b) in zip(sorted(online.items()), sorted(offline.items()), strict=True):
        assert a[0] == b[0] and a[1] == b[1]  # bit for bit
        assert abs(math.remainder(a[2] - b[2], 2 * math.pi)) < 1e-12  # through a quaternion
    assert len(online) > 60  # most scans moved the robot past update_min_d / update_min_a


def test_play_feeds_the_node(driver, tmp_path: Path) -> None:
    from ceamcl.io.logs import open_log
    from ceamcl.ros.messages import pose2_from_msg, seconds
    from tests.ros.harness import NodeProcess, pose_error

    path = real_log("fhw-corrected.log.gz")
    n_scans = len(open_log(path))
    first = open_log(path).poses[0]
    # The textbook product: this test is about play feeding the node at 200x. With amcl's flat
    # scoring (kld-amcl's default) KLD-sampling keeps a wider cloud and more particles, and on a
    # busy 2-core machine the node published poses for only 38 of 488 scans at that pace.
    params = {
        "algorithm": "kld-amcl",
        "set_initial_pose": "true",
        "initial_pose.x": first[0],
        "initial_pose.y": first[1],
        "initial_pose.yaw": first[2],
        "transform_tolerance": TOLERANCE_S,
        "kld_amcl.scoring": "product",
    }
    args = ["--ros-args", *[a for k, v in params.items() for a in ("-p", f"{k}:={v}")]]
    play_args = [
        str(path),
        "--rate",
        "200",
        "--synthetic-odometry",
        "--quiet",
        "--wait",
        "10",
        "--delay",
        "3",
    ]
    with NodeProcess(tmp_path, args) as node:
        driver.configure_and_activate()
        with NodeProcess(
            tmp_path, play_args, command=("-m", "ceamcl", "play"), name="play"
        ) as player:
            assert driver.spin_until(lambda: not player.alive, 120.0), player.log()[-2000:]
            assert player.wait(1.0) == 0, player.log()[-2000:]
        driver.spin_until(lambda: False, 1.0)  # the last messages
        assert node.alive and "Traceback" not in node.log(), node.log()[-3000:]
        assert "map received: 1006 x 1762 cells" in node.log()

    stamps = sorted(driver.truth)
    assert len(stamps) == n_scans, (
        f"{n_scans - len(stamps)} ground_truth lost; received {stamps[:2]} .. {stamps[-2:]}"
    )
    assert len(driver.poses) > n_scans // 4, node.log()[-2000:]
    # the map was in before the first scan (--delay), so the initial pose applies at scan 0:
    # the first amcl_pose is for the first scan, near the true start (Nav2's initial spread
    # is 0.5 m and 15 degrees)
    first_pose = driver.poses[0]
    assert seconds(first_pose.header.stamp) == min(driver.truth)
    truth = driver.truth[seconds(first_pose.header.stamp)]
    d, a = pose_error(pose2_from_msg(first_pose.pose.pose), truth)
    assert d < 1.0 and a < 0.5, (d, a)
