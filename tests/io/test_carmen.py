"""The CARMEN reader on small handwritten logs: every message type, geometry, errors."""

from __future__ import annotations

import bz2
import gzip
import lzma
import math
import os
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ceamcl.errors import LogFormatError
from ceamcl.io.carmen import (
    CarmenComment,
    CarmenLaser,
    CarmenOdometry,
    CarmenParam,
    CarmenSkipped,
    guess_angle_increment,
    guess_fov,
    iter_carmen,
    read_carmen,
)
from ceamcl.io.logs import open_log


def flaser(
    n: int,
    r: float,
    pose: tuple[float, float, float],
    t: float,
    kind: str = "FLASER",
    host: bool = True,
) -> str:
    ranges = " ".join([f"{r:g}"] * n)
    p = " ".join(f"{v:g}" for v in pose)
    tail = f"{t} nohost {t}" if host else f"{t}"
    return f"{kind} {n} {ranges} {p} {p} {tail}"


def write(tmp_path: Path, lines: list[str], name: str = "run.log", gz: bool = False) -> Path:
    text = "\n".join(lines) + "\n"
    path = tmp_path / name
    if gz:
        with gzip.open(path, "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)
    return path


def test_every_message_type(tmp_path: Path) -> None:
    lines = [
        "# message formats defined: PARAM SYNC ODOM FLASER RLASER TRUEPOS",
        "PARAM robot_front_laser_max 50.0 nohost 0",
        "ODOM 0 0 0 0.1 0.0 0 0.5 nohost 0.5",
        flaser(180, 2.0, (1.0, 2.0, 0.5), 1.0),
        flaser(181, 3.0, (0.0, 0.0, 0.0), 1.5, kind="RLASER"),
        "NEFF 15",
        "SYNC 1 nohost 1",
        "",
        "ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 7 1 2 3 4 5 6 20 0 "
        "1.1 2.0 0.1 1.0 2.0 0.1 0 0 0.5 0.3 0 2.0 host 2.0",
        "RAWLASER2 0 -1.0 2.0 1.0 8.0 0.01 0 3 1 2 8 2 5 5 2.5 host 2.5",
    ]
    msgs = list(iter_carmen(write(tmp_path, lines)))
    kinds = [type(m) for m in msgs]
    assert kinds == [
        CarmenComment,
        CarmenParam,
        CarmenOdometry,
        CarmenLaser,
        CarmenLaser,
        CarmenSkipped,
        CarmenSkipped,
        CarmenLaser,
        CarmenLaser,
    ]
    f, r, robot, raw = (m for m in msgs if isinstance(m, CarmenLaser))
    assert (f.kind, f.laser_id, f.ranges.size, f.line) == ("FLASER", 1, 180, 4)
    assert f.laser_pose == (1.0, 2.0, 0.5) and f.timestamp == 1.0
    assert (r.kind, r.laser_id, r.ranges.size) == ("RLASER", 2, 181)
    assert (robot.kind, robot.laser_id, robot.max_range) == ("ROBOTLASER1", 1, 20.0)
    assert robot.start_angle == -1.5 and robot.angle_increment == 0.5 and robot.fov == 3.0
    assert robot.laser_pose == (1.1, 2.0, 0.1) and robot.robot_pose == (1.0, 2.0, 0.1)
    assert robot.timestamp == 2.0
    assert (raw.kind, raw.laser_id, raw.laser_pose, raw.timestamp) == ("RAWLASER2", 2, None, 2.5)
    odom = next(m for m in msgs if isinstance(m, CarmenOdometry))
    assert (odom.tv, odom.timestamp) == (0.1, 0.5)


@pytest.mark.parametrize(
    ("n", "fov_deg", "inc_deg"),
    [(180, 179.0, 1.0), (181, 180.0, 1.0), (360, 179.5, 0.5), (361, 180.0, 0.5)],
)
def test_flaser_geometry_as_carmen_defines_it(
    tmp_path: Path, n: int, fov_deg: float, inc_deg: float
) -> None:
    assert guess_fov(n) == pytest.approx(math.radians(fov_deg))
    assert guess_angle_increment(n) == pytest.approx(math.radians(inc_deg))
    log = read_carmen(write(tmp_path, [flaser(n, 1.0, (0, 0, 0), 0.0)]))
    scan = log.scan(0)
    assert scan.n_beams == n
    assert scan.angles[0] == pytest.approx(-math.pi / 2)
    # the last beam: -90 deg + the field of view
    assert scan.angles[-1] == pytest.approx(-math.pi / 2 + math.radians(fov_deg))


def test_read_carmen_counts_and_poses(tmp_path: Path) -> None:
    lines = ["# comment"] + [
        flaser(180, 81.91 if k == 1 else 2.0, (k * 0.5, 0.0, 0.1 * k), float(k)) for k in range(4)
    ]
    lines += ["NEFF 3", "ODOM 0 0 0 0 0 0 0 h 0", "RLASER 1 1.0 0 0 0 0 0 0 0.2 h 0.2"]
    log = read_carmen(write(tmp_path, lines))
    assert len(log) == 4
    assert log.info["message_counts"]["FLASER"] == 4
    assert log.info["message_counts"]["RLASER"] == 1
    assert log.info["skipped_messages"] == {"NEFF": 1}
    np.testing.assert_allclose(log.times, [0, 1, 2, 3])
    np.testing.assert_allclose(log.poses[:, 0], [0, 0.5, 1.0, 1.5])
    np.testing.assert_allclose(log.laser_mount, 0.0)
    # 81.91 m is at or beyond CARMEN's 80 m maximum: a no-return reading
    scan = log.scan(1)
    assert scan.range_max == 80.0
    assert np.all(scan.ranges >= scan.range_max)
    assert np.all(log.scan(0).ranges < log.scan(0).range_max)


def test_param_sets_max_range_and_rear_laser_is_selectable(tmp_path: Path) -> None:
    lines = [
        "PARAM robot_front_laser_max 40.0",
        flaser(180, 1.0, (0, 0, 0), 0.0),
        flaser(361, 1.0, (0, 0, 0), 0.1, kind="RLASER"),
    ]
    path = write(tmp_path, lines)
    assert read_carmen(path).range_max[0] == 40.0
    rear = read_carmen(path, laser=2)
    assert len(rear) == 1 and rear.scan(0).n_beams == 361 and rear.range_max[0] == 80.0
    assert read_carmen(path, max_range_m=8.0).range_max[0] == 8.0


def _aces_like(rng: np.random.Generator, no_return: float, scans: int = 20) -> list[str]:
    """FLASER lines of 180 readings: measured distances up to 45 m, a fifth of them the
    laser's no-return value (ACES writes 50.00 m and states no maximum)."""
    lines = []
    for k in range(scans):
        r = np.round(rng.uniform(0.2, 45.0, 180), 2)
        r[rng.random(180) < 0.2] = no_return
        ranges = " ".join(f"{v:.2f}" for v in r)
        lines.append(f"FLASER 180 {ranges} {k} 0 0 {k} 0 0 {k}.0 nohost {k}.0")
    return lines


def test_a_no_return_value_below_80_m_is_read_from_the_readings(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    path = write(tmp_path, _aces_like(rng, 50.0))
    log = read_carmen(path)
    assert log.range_max[0] == 50.0  # not CARMEN's 80 m: 50.00 is "no return", not a wall
    assert "taken as the laser's no-return value" in log.info["max_range_from"]
    scan = log.scan(0)
    assert np.count_nonzero(scan.ranges >= scan.range_max) > 20
    # what the log or the user states wins
    stated = write(tmp_path, ["PARAM robot_front_laser_max 60", *_aces_like(rng, 50.0)], "p.log")
    assert read_carmen(stated).range_max[0] == 60.0
    assert read_carmen(path, max_range_m=70.0).range_max[0] == 70.0
    # a largest reading that is a measured distance (few, as its neighbours) changes nothing
    far = _aces_like(rng, 0.5)  # 0.5 m readings pile up below the top, not at it
    plain = read_carmen(write(tmp_path, far, name="plain.log"))
    assert plain.range_max[0] == 80.0 and "max_range_from" not in plain.info
    # Radish's no-return values above 80 m are no-return under the default already
    radish = read_carmen(write(tmp_path, _aces_like(rng, 81.91), name="radish.log"))
    assert radish.range_max[0] == 80.0 and "max_range_from" not in radish.info


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf", "-inf", "far"])
def test_param_max_range_that_is_not_a_positive_finite_number_names_its_line(
    tmp_path: Path, value: str
) -> None:
    """-1, 0 and nan fell back to CARMEN's 80 m silently; inf failed later as 'scan:
    range_max: expected a positive finite number, got inf', naming no file or line."""
    lines = ["# a log", f"PARAM robot_front_laser_max {value} nohost 0"]
    lines += [flaser(180, 1.0, (0, 0, 0), float(k)) for k in range(2)]
    with pytest.raises(
        LogFormatError,
        match=rf"run\.log:2: PARAM robot_front_laser_max: expected a positive finite number of "
        rf"metres, got '{value}' \(--max-range sets the maximum instead\)",
    ):
        read_carmen(write(tmp_path, lines))
    # --max-range replaces the parameter, as docs/real-data.md says
    assert read_carmen(write(tmp_path, lines), max_range_m=8.0).range_max[0] == 8.0
    # the rear laser's parameter is the rear laser's business
    lines[1] = f"PARAM robot_rear_laser_max {value}"
    assert read_carmen(write(tmp_path, lines)).range_max[0] == 80.0


def test_flaser_without_hostname_or_timestamp_tail(tmp_path: Path) -> None:
    lines = [flaser(180, 1.0, (1, 2, 0), 7.5, host=False), flaser(180, 1.0, (1, 2, 0), 8.5)]
    log = read_carmen(write(tmp_path, lines))
    np.testing.assert_allclose(log.times, [7.5, 8.5])


def test_scans_with_and_without_timestamps_are_refused_naming_the_first_without(
    tmp_path: Path,
) -> None:
    """A log numbers its scans when none has a timestamp; numbering only some would mix
    indices with seconds (the untimed scan 1 came 99 s before the timed scan 0)."""
    timed = [flaser(180, 1.0, (1, 2, 0), 100.5), flaser(180, 1.0, (1, 2, 0), 0.0)]
    untimed = [line.rsplit(" ", 3)[0] for line in timed]  # timestamp, host, logger time cut
    with pytest.raises(LogFormatError, match=r"run\.log:2: 1 scans .* a timestamp and 1 none"):
        read_carmen(write(tmp_path, [timed[0], untimed[1]]))
    np.testing.assert_array_equal(read_carmen(write(tmp_path, untimed)).times, [0.0, 1.0])


def test_robotlaser_gives_mount_and_max_range(tmp_path: Path) -> None:
    line = (
        "ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 7 1 2 3 4 5 6 25 0 "
        "1.0 2.0 1.5707963 1.0 1.8 1.5707963 0 0 0.5 0.3 0 2.0 host 2.0"
    )
    log = read_carmen(write(tmp_path, [line]))
    scan = log.scan(0)
    assert scan.angle_min == -1.5 and scan.angle_increment == 0.5 and scan.range_max == 20.0
    # laser 0.2 m to the robot's left in the world = 0.2 m ahead of a robot facing +y
    assert scan.pose == pytest.approx((0.2, 0.0, 0.0), abs=1e-6)
    assert scan.ranges[-1] >= scan.range_max  # 25 m > 20 m: no return


def test_rawlaser_only_takes_pose_from_odom(tmp_path: Path) -> None:
    lines = [
        "ODOM 0 0 0 0 0 0 0.0 h 0",
        "RAWLASER1 0 -1.57 3.14 0.0174 80.0 0.01 0 3 1 2 3 0 0.5 h 0.5",
        "ODOM 1 0 0.2 0 0 0 1.0 h 1",
    ]
    log = read_carmen(write(tmp_path, lines))
    assert log.info["poses_from"] == "ODOM (interpolated)"
    np.testing.assert_allclose(log.poses[0], [0.5, 0.0, 0.1], atol=1e-12)


RAW = "RAWLASER1 0 -1.57 3.14 0.0174 80.0 0.01 0 3 1 2 3 0"


def _raw_log(scan_t: list[str], odom_t: list[str]) -> list[str]:
    """ODOM and RAWLASER1 lines in turn, the robot driving 0.5 m a line along x; an empty
    time leaves the line without timestamp, host and logger timestamp."""
    lines = []
    for k, (ts, to) in enumerate(zip(scan_t, odom_t, strict=True)):
        lines.append(f"ODOM {0.5 * k} 0 0 0.5 0 0" + (f" {to} h {to}" if to else ""))
        lines.append(RAW + (f" {ts} h {ts}" if ts else ""))
    return lines


def test_rawlaser_needs_timestamps_on_its_scans_and_on_odom(tmp_path: Path) -> None:
    """RAWLASER scans take their pose from ODOM at their time. With untimed ODOM lines the
    poses came out NaN (a NaN trajectory with exit 0, or a traceback in the mapper); with
    untimed scans the scan indices 0, 1, 2 were read as seconds against ODOM's clock (every
    scan the first pose). Both are refused naming the first line without a timestamp."""
    timed = [f"{100 + 0.2 * k:.1f}" for k in range(4)]
    with pytest.raises(
        LogFormatError,
        match=r"run\.log:3: ODOM line without a timestamp: the RAWLASER1 scans take the "
        r"robot's pose from ODOM at their time",
    ):
        read_carmen(write(tmp_path, _raw_log(timed, [timed[0], "", "", ""])))
    with pytest.raises(LogFormatError, match=r"run\.log:1: ODOM line without a timestamp"):
        read_carmen(write(tmp_path, _raw_log(timed, [""] * 4)))
    with pytest.raises(
        LogFormatError, match=r"run\.log:2: RAWLASER1 scan without a timestamp: RAWLASER scans"
    ):
        read_carmen(write(tmp_path, _raw_log([""] * 4, timed)))
    log = read_carmen(write(tmp_path, _raw_log(timed, timed)))
    np.testing.assert_allclose(log.poses[:, 0], [0.0, 0.5, 1.0, 1.5])
    # FLASER scans carry their pose: ODOM lines without a timestamp are fine beside them
    lines = ["ODOM 0 0 0 0 0 0", flaser(180, 1.0, (1, 2, 0), 7.5), "ODOM 0 0 0 0 0 0"]
    assert np.all(np.isfinite(read_carmen(write(tmp_path, lines)).poses))


def test_rawlaser_scans_outside_the_odometry_time_span_are_refused(tmp_path: Path) -> None:
    """Scans that do not overlap the odometry's time span at all would each take its first
    or last pose; a scan a little before the first ODOM line takes the first pose."""
    odom_t = [f"{100 + 0.2 * k:.1f}" for k in range(4)]
    scan_t = [f"{200 + 0.2 * k:.1f}" for k in range(4)]
    with pytest.raises(
        LogFormatError,
        match=r"run\.log: the RAWLASER1 scans \(lines 2-8\) span 200\.000 \.\. 200\.600 s "
        r"and the 4 ODOM lines 100\.000 \.\. 100\.600 s: the times do not overlap",
    ):
        read_carmen(write(tmp_path, _raw_log(scan_t, odom_t)))
    early = [f"{99.9 + 0.2 * k:.1f}" for k in range(4)]  # 0.1 s before each ODOM line
    log = read_carmen(write(tmp_path, _raw_log(early, odom_t)))
    np.testing.assert_allclose(log.poses[:, 0], [0.0, 0.25, 0.75, 1.25])


def test_poses_at_scans_never_gives_a_nan_pose() -> None:
    """The guard of every reader that interpolates odometry: NaN times are refused, so are
    scans with no time in the odometry's span; the poses otherwise are interpolated."""
    from ceamcl.io.recorded import poses_at_scans

    def fail(what: str) -> LogFormatError:
        return LogFormatError(f"x: {what}")

    t, poses = np.array([0.0, 1.0]), np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    kw = {"scans": "the scans", "odometry": "the odometry", "error": fail}
    with pytest.raises(LogFormatError, match=r"x: the odometry: time nan of entry 1"):
        poses_at_scans([0.0, math.nan], poses, [0.5], **kw)
    with pytest.raises(LogFormatError, match=r"x: the scans: time nan of entry 0"):
        poses_at_scans(t, poses, [math.nan, 0.5], **kw)
    with pytest.raises(LogFormatError, match=r"the times do not overlap"):
        poses_at_scans(t, poses, [1.5, 2.0], **kw)
    out = poses_at_scans(t, poses, [-0.5, 0.5, 1.0], **kw)
    np.testing.assert_allclose(out[:, 0], [0.0, 0.5, 1.0])
    with pytest.raises(LogFormatError, match=r"scan 0 \(t=0\.500 s\): the pose interpolated"):
        poses_at_scans(t, [[0.0, 0.0, 0.0], [math.inf, 0.0, 0.0]], [0.5], **kw)


def test_gzip_is_read_transparently(tmp_path: Path) -> None:
    lines = [flaser(180, 1.0, (0, 0, 0), float(k)) for k in range(3)]
    plain = read_carmen(write(tmp_path, lines))
    packed = open_log(write(tmp_path, lines, name="run.log.gz", gz=True))
    assert len(packed) == 3
    np.testing.assert_array_equal(packed.ranges_flat, plain.ranges_flat)


@pytest.mark.parametrize("packer", [bz2.compress, lzma.compress], ids=["bzip2", "xz"])
def test_bzip2_and_xz_are_read_transparently_from_a_file_or_a_pipe(
    tmp_path: Path, packer: Callable[[bytes], bytes]
) -> None:
    """Logs are published as ``.bz2`` too: one was refused as binary data ("NUL bytes"),
    and the README had users pipe it through ``bzcat``."""
    lines = [flaser(180, 1.0 + 0.1 * k, (0, 0, 0), float(k)) for k in range(40)]
    plain = read_carmen(write(tmp_path, lines))
    packed = packer(write(tmp_path, lines).read_bytes())
    path = tmp_path / "run.log.packed"
    path.write_bytes(packed)
    np.testing.assert_array_equal(open_log(path).ranges_flat, plain.ranges_flat)
    r, w = os.pipe()

    def feed() -> None:
        with os.fdopen(w, "wb") as fh:
            fh.write(packed)

    threading.Thread(target=feed).start()
    try:
        piped = read_carmen(f"/dev/fd/{r}")
    finally:
        os.close(r)
    np.testing.assert_array_equal(piped.ranges_flat, plain.ranges_flat)
    path.write_bytes(packed[: len(packed) // 2])
    with pytest.raises(LogFormatError, match=r"run\.log\.packed:\d+: the compressed file is"):
        read_carmen(path)
    damaged = bytearray(packed)  # whole, with bytes changed inside: bzip2 raised OSError
    damaged[len(packed) // 2 : len(packed) // 2 + 64] = bytes(64)
    path.write_bytes(bytes(damaged))
    with pytest.raises(LogFormatError, match=r"run\.log\.packed:\d+: the compressed file is"):
        read_carmen(path)


def test_a_text_log_that_starts_like_bzip2_is_text(tmp_path: Path) -> None:
    """Only bzip2's block or end-of-stream magic after ``BZh`` and a digit opens a
    decompressor: a text line starting ``BZh9`` is an unknown message of a text log."""
    lines = ["BZh9 something", flaser(180, 1.0, (0, 0, 0), 0.0)]
    log = read_carmen(write(tmp_path, lines))
    assert len(log) == 1 and log.info["skipped_messages"] == {"BZh9": 1}


def test_beam_count_that_does_not_agree_with_the_fields_is_refused(tmp_path: Path) -> None:
    """``FLASER 179`` followed by 180 ranges was read shifted and accepted: the 180th range
    became the laser's x, the robot pose took the laser's theta, the timestamp the robot's
    theta (a scan at -0.35 s, a laser mounted 1.6 m off). Only the timestamp, host and logger
    timestamp may follow the fields; more, or a logger timestamp that is not a number, is an
    error naming the line."""
    good = [flaser(180, 1.5, (0.1 * k, 0.2, 0.3), 10.0 + k) for k in range(3)]
    refusals = {
        179: r"run\.log:2: FLASER: the beam count 179 and the fields do not agree: 4 fields "
        r"follow where at most 3 may \(expected 179 ranges, 6 pose values, then \[timestamp",
        # one beam too many: the host name lands where the timestamp goes
        181: r"run\.log:2: FLASER: timestamp: expected a number, got 'nohost' \(does the "
        r"beam count 181 agree with the fields\?",
    }
    for count, message in refusals.items():
        bad = good[1].replace("FLASER 180 ", f"FLASER {count} ", 1)
        with pytest.raises(LogFormatError, match=message):
            read_carmen(write(tmp_path, [good[0], bad, good[2]]))
    # without host and logger timestamp, more than two beams too few are caught by the count
    short = [line.rsplit(" ", 2)[0] for line in good]  # ... timestamp
    bad = short[1].replace("FLASER 180 ", "FLASER 177 ", 1)
    with pytest.raises(LogFormatError, match=r"run\.log:2: FLASER: the beam count 177 and"):
        read_carmen(write(tmp_path, [short[0], bad, short[2]]))
    assert len(read_carmen(write(tmp_path, short))) == 3


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (
            "FLASER 3 1 1 1 0 0 0 0 0 0 1 h 1 extra",
            r"FLASER: the beam count 3 and the fields do not agree: 4 fields follow",
        ),
        (
            "FLASER 3 1 1 1 0 0 0 0 0 0 1 h x",
            r"FLASER: the beam count 3 and the fields do not agree: the logger timestamp is "
            r"'x', not a number",
        ),
        (
            "RAWLASER1 0 -1.57 3.14 0.0174 80.0 0.01 0 3 1 2 3 0 0.5 h 0.5 9",
            r"RAWLASER1: the beam count 3 and the fields do not agree: 4 fields follow where "
            r"at most 3 may \(expected 3 ranges, remission count 0, 0 remissions, then",
        ),
        (
            "ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 2 1 2 0 0 0 0 0 0 0 0 0 0 0 0 1 h 1 2",
            r"ROBOTLASER1: the beam count 2 and the fields do not agree: 4 fields follow",
        ),
    ],
)
def test_fields_after_a_laser_message_name_the_beam_count(
    tmp_path: Path, line: str, message: str
) -> None:
    with pytest.raises(LogFormatError, match=r"run\.log:2: " + message):
        read_carmen(write(tmp_path, ["# ok", line]))


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("FLASER 180 1 2 3", r"run\.log:2: FLASER: expected 180 ranges"),
        ("FLASER abc 1 2", r"run\.log:2: FLASER: beam count: expected a whole number, got 'abc'"),
        (
            "FLASER 3 1 2 x 0 0 0 0 0 0 1 h 1",
            r"run\.log:2: FLASER: 3 ranges: expected numbers, got 'x'",
        ),
        ("FLASER 3 1 2 3 0 0", r"run\.log:2: FLASER: expected laser pose"),
        ("ODOM 1 2", r"run\.log:2: ODOM: expected x y theta tv rv accel"),
        ("ODOM 1 2 3 4 5 6 when h 0", r"run\.log:2: ODOM: timestamp: expected a number"),
        ("PARAM lonely", r"run\.log:2: PARAM: expected a parameter name and a value"),
        (
            "ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 2 1 2 0 1 1",
            r"run\.log:2: ROBOTLASER1: expected laser pose",
        ),
        ("FLASER -2 1 2", r"run\.log:2: FLASER: beam count: expected a non-negative count"),
        (
            "FLASER 2 1 1 nan nan 0 0 0 0 1 h 1",
            r"run\.log:2: FLASER: laser pose x y theta: expected three finite numbers",
        ),
        (
            "FLASER 2 1 1 0 0 0 1e200 0 0 1 h 1",
            r"run\.log:2: FLASER: robot pose .*: expected \|x\|, \|y\| <= 1e\+07 m",
        ),
        ("ODOM 1 inf 0 0 0 0 1 h 1", r"run\.log:2: ODOM: x y theta: expected three finite"),
        (
            "ROBOTLASER1 0 -1.5 nan 0.5 20.0 0.01 0 2 1 2 0 0 0 0 0 0 0 0 0 0 0 0 1 h 1",
            r"run\.log:2: ROBOTLASER1: fov: expected a finite number, got nan",
        ),
    ],
)
def test_malformed_line_names_file_and_line(tmp_path: Path, line: str, message: str) -> None:
    path = write(tmp_path, ["# ok", line])
    with pytest.raises(LogFormatError, match=message):
        read_carmen(path)


def test_no_scans_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match=r"no scan of laser 1.*ODOM x1"):
        read_carmen(write(tmp_path, ["ODOM 0 0 0 0 0 0 0 h 0"]))
    # a file of something else says what its lines are, not "nothing"
    with pytest.raises(LogFormatError, match=r"holds: 2 lines of other kinds \(such as 'step,t'"):
        read_carmen(write(tmp_path, ["step,t", "1,2"], name="diagnostics.csv"))
    with pytest.raises(LogFormatError, match="not found"):
        read_carmen(tmp_path / "absent.log")


def test_truncated_gzip_names_file(tmp_path: Path) -> None:
    lines = [flaser(180, 1.0, (0, 0, 0), float(k)) for k in range(200)]
    path = write(tmp_path, lines, name="cut.log.gz", gz=True)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(LogFormatError, match=r"cut\.log\.gz:\d+: the compressed file is damaged"):
        read_carmen(path)


def test_streaming_reads_lazily(tmp_path: Path) -> None:
    # A malformed line far down is not reached when only the first messages are taken.
    lines = [flaser(180, 1.0, (0, 0, 0), 0.0), "FLASER broken"]
    it = iter_carmen(write(tmp_path, lines))
    assert isinstance(next(it), CarmenLaser)
    with pytest.raises(LogFormatError):
        next(it)


def _mixed_log() -> list[str]:
    return [
        "# a comment",
        "PARAM robot_front_laser_max 40.0",
        "ODOM 0 0 0 0.1 0 0 0.5 nohost 0.5",
        *(flaser(180, 1.0 + k, (0.1 * k, 0.0, 0.0), float(k)) for k in range(5)),
    ]


@pytest.mark.parametrize("eol", ["\r\n", "\r", "mixed"])
@pytest.mark.parametrize("chunk", [1 << 16, 7])
def test_line_ends_cr_lf_and_lone_cr_read_as_lf(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, eol: str, chunk: int
) -> None:
    """A log saved with classic Mac line ends (CR alone) was one line: read as 1 scan of 5,
    the rest dropped silently. CR LF, LF and CR all end a line, also when a CR LF straddles
    two of the chunks the file is read in."""
    import ceamcl.io.carmen as carmen

    monkeypatch.setattr(carmen, "_CHUNK_BYTES", chunk, raising=False)
    lines = _mixed_log()
    ends = ["\r", "\r\n", "\n"] * len(lines) if eol == "mixed" else [eol] * len(lines)
    text = "".join(line + end for line, end in zip(lines, ends, strict=False))
    plain = read_carmen(write(tmp_path, lines))
    for name, data in (("cr.log", text.encode()), ("cr.log.gz", gzip.compress(text.encode()))):
        (tmp_path / name).write_bytes(data)
        log = read_carmen(tmp_path / name)
        assert len(log) == 5
        np.testing.assert_array_equal(log.ranges_flat, plain.ranges_flat)
        np.testing.assert_array_equal(log.times, plain.times)
        np.testing.assert_array_equal(log.info["scan_lines"], [4, 5, 6, 7, 8])
        assert log.info["message_counts"] == plain.info["message_counts"]
        assert log.range_max[0] == 40.0


def test_a_line_over_the_bound_is_refused_whatever_ends_the_lines(tmp_path: Path) -> None:
    from ceamcl import budget

    long = flaser(200_000, 1.2345, (0, 0, 0), 1.0)  # 1.4 MB, over the 1 MiB line bound
    for eol in ("\n", "\r"):
        path = tmp_path / "long.log"
        path.write_bytes(eol.join(["# ok", long, "# after"]).encode())
        with budget.use(budget.Budget(64 << 20)):
            with pytest.raises(budget.BudgetError, match=r"long\.log:2: line longer than 1\.0 MiB"):
                read_carmen(path)


def test_a_utf8_byte_order_mark_is_not_part_of_the_first_message(tmp_path: Path) -> None:
    """A log saved as "UTF-8 with BOM" lost its first line: '\\ufeffFLASER' was counted as an
    unknown message (199 scans of 200)."""
    lines = [flaser(180, 1.0, (0.1 * k, 0.0, 0.0), float(k)) for k in range(3)]
    path = tmp_path / "bom.log"
    path.write_bytes(b"\xef\xbb\xbf" + ("\n".join(lines) + "\n").encode())
    log = read_carmen(path)
    assert len(log) == 3 and log.info["skipped_messages"] == {}
    np.testing.assert_array_equal(log.info["scan_lines"], [1, 2, 3])
    gz = tmp_path / "bom.log.gz"
    gz.write_bytes(gzip.compress(path.read_bytes()))
    assert len(read_carmen(gz)) == 3
    # a BOM anywhere else is not text of a CARMEN log: the line is an unknown message
    path.write_bytes(("\n".join(lines) + "\n\ufeffNEFF 3\n").encode())
    assert read_carmen(path).info["skipped_messages"] == {"\ufeffNEFF": 1}
