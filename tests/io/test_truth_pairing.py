"""Truth from a second log: raw scans paired with their corrected twins by identical ranges."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import ceamcl.io.truth as truth_module
from ceamcl.errors import InputWarning, LogFormatError
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.truth import pair_truth, printed_decimals, suggest_mount
from ceamcl.replay import prepare_log
from ceamcl.sensors.scan import laser_poses

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"


def make_log(
    ranges: list[list[float]],
    times: list[float],
    name: str,
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
    headings: list[float] | None = None,
) -> RecordedLog:
    n = len(ranges)
    flat = np.concatenate([np.asarray(r, dtype=np.float64) for r in ranges])
    offsets = np.concatenate([[0], np.cumsum([len(r) for r in ranges])]).astype(np.intp)
    th = np.zeros(n) if headings is None else np.asarray(headings, dtype=np.float64)
    poses = np.column_stack([np.arange(n, dtype=np.float64), np.zeros(n), th])
    return RecordedLog(
        path=name,
        times=np.asarray(times, dtype=np.float64),
        poses=poses,
        ranges_flat=flat,
        offsets=offsets,
        angle_min=np.full(n, -1.0),
        angle_increment=np.full(n, 0.1),
        range_min=np.zeros(n),
        range_max=np.full(n, 30.0),
        laser_mount=np.tile(np.asarray(mount, dtype=np.float64), (n, 1)),
    )


def test_pairs_by_ranges_across_a_clock_offset_and_printing_differences() -> None:
    rng = np.random.default_rng(0)
    scans = [list(np.round(rng.uniform(0.5, 10, 8), 2)) for _ in range(6)]
    raw = make_log(scans, [1000.0 + 0.2 * k for k in range(6)], "raw")
    # the corrected log keeps scans 1, 3, 4, printed with more digits (tiny float noise)
    kept = [1, 3, 4]
    corrected = make_log(
        [[v + 1e-9 for v in scans[k]] for k in kept], [0.2 * k for k in kept], "corrected"
    )
    p = pair_truth(raw, corrected)
    assert p.raw_index.tolist() == kept
    assert p.truth_index.tolist() == [0, 1, 2]
    assert p.clock_offset_s == pytest.approx(1000.0)
    truth = p.truth_at_raw_scans()
    assert np.isnan(truth[[0, 2, 5]]).all()
    assert truth[3].tolist() == corrected.poses[1].tolist()


def test_a_log_of_millimetres_pairs_with_its_corrected_log_of_centimetres(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A corrected log written with fewer digits than its raw log (the raw laser's
    millimetres, the SLAM tool's centimetres) still pairs: ranges compare at the coarser."""
    rng = np.random.default_rng(1)
    mm = [list(np.round(rng.uniform(0.5, 10, 40), 3)) for _ in range(8)]
    raw = make_log(mm, [50.0 + 0.1 * k for k in range(8)], "raw")
    kept = [0, 2, 5, 7]
    cm = [[float(f"{v:.2f}") for v in mm[k]] for k in kept]
    corrected = make_log(cm, [0.1 * k for k in kept], "corrected")
    assert (printed_decimals(raw), printed_decimals(corrected)) == (3, 2)
    assert pair_truth(raw, corrected).raw_index.tolist() == kept
    # compared at millimetres whatever the logs print (as before), nothing paired
    monkeypatch.setattr(truth_module, "printed_decimals", lambda log, limit=3: limit)
    with pytest.raises(LogFormatError, match="none of its 4 scans has the ranges"):
        pair_truth(raw, corrected)


def test_printed_decimals_reads_float32_readings_by_their_digits() -> None:
    cm = np.round(np.random.default_rng(2).uniform(0.5, 10, 50), 2)
    as_float32 = make_log([list(cm.astype(np.float32).astype(np.float64))], [0.0], "bag")
    assert printed_decimals(as_float32) == 2
    noisy = make_log([list(np.random.default_rng(3).uniform(0.5, 10, 50))], [0.0], "bag")
    assert printed_decimals(noisy) == 3  # the limit: no fewer digits describe them


def test_the_truth_is_the_raw_robots_pose_where_the_lasers_sit_apart() -> None:
    """The corrected log's scans were taken at its laser pose (its pose plus its mount); the
    raw log's robot carries its laser at its own mount (fr079: 4 cm behind the centre). The
    truth at a raw scan is the robot pose that puts the raw laser where the corrected laser
    was, so a filter that fits the scan to the map is scored without the mount as a bias."""
    scans = [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]
    headings = [0.0, np.pi / 2, 3.0]
    raw = make_log(scans, [10.0, 11.0, 12.0], "raw", mount=(-0.04, 0.01, 0.05))
    corrected = make_log(scans, [0.0, 1.0, 2.0], "corrected", headings=headings)
    p = pair_truth(raw, corrected)
    assert p.mount_moved == 3
    assert "truth moved to the raw log's robot at 3 pairs" in p.summary()
    assert p.mount_shift_m == pytest.approx(np.hypot(0.04, 0.01))
    # the raw laser at the truth is where the corrected log's laser was
    at = laser_poses(p.truth_poses, raw.laser_mount[p.raw_index])
    np.testing.assert_allclose(at[:, :2], corrected.poses[:, :2], atol=1e-12)
    np.testing.assert_allclose(np.cos(at[:, 2] - corrected.poses[:, 2]), 1.0)
    # fr079's mount, the robot heading along +y: it stood 4 cm ahead of the laser pose
    fr079 = make_log(scans, [10.0, 11.0, 12.0], "raw", mount=(-0.04, 0.0, 0.0))
    q = pair_truth(fr079, corrected)
    np.testing.assert_allclose(q.truth_poses[1], corrected.poses[1] + [0.0, 0.04, 0.0])


def test_a_corrected_log_whose_robot_pose_is_its_odometry_gives_its_laser_pose() -> None:
    # Some GMapping logs keep the raw odometry as the FLASER line's robot pose: the "mount" is
    # metres long, the truth is the corrected laser pose all the same, and the summary says
    # what the second pose is.
    scans = [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]
    raw = make_log(scans, [0.0, 1.0, 2.0], "raw")
    corrected = make_log(scans, [0.0, 1.0, 2.0], "corrected", mount=(4.0, -3.0, 0.0))
    p = pair_truth(raw, corrected)
    np.testing.assert_allclose(p.truth_poses, laser_poses(corrected.poses, corrected.laser_mount))
    assert p.mount_shift_m == pytest.approx(5.0)
    assert "odometry, not a laser mount" in p.summary()


def test_equal_mounts_keep_the_corrected_pose_bit_for_bit() -> None:
    scans = [[1.0, 2.0], [3.0, 4.0]]
    raw = make_log(scans, [10.0, 11.0], "raw", mount=(0.2, 0.0, 0.0))
    corrected = make_log(scans, [0.0, 1.0], "corrected", mount=(0.2, 0.0, 0.0), headings=[1, 2])
    p = pair_truth(raw, corrected)
    assert p.mount_moved == 0 and "moved" not in p.summary()
    assert p.truth_poses.tobytes() == corrected.poses.tobytes()


def test_a_repeated_scan_is_told_apart_by_its_time() -> None:
    # The robot stands still: raw scans 1, 2 and 3 are identical; the corrected log kept the
    # third of them (and scan 0, unique, which fixes the clock offset).
    a, still = [1.0, 2.0, 3.0], [4.0, 5.0, 6.0]
    raw = make_log([a, still, still, still, [7.0, 8.0, 9.0]], [50, 51, 52, 53, 54], "raw")
    corrected = make_log([a, still], [0.0, 3.0], "corrected")
    p = pair_truth(raw, corrected)
    assert p.raw_index.tolist() == [0, 3]


def test_pairs_never_go_back_in_time() -> None:
    # Scan a's twin nearest in time (raw 1) comes before the last pair (raw 2): the pairing
    # takes the next twin instead of stepping back.
    a, b, c = [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]
    raw = make_log([c, a, b, a], [10.0, 11.0, 12.0, 12.3], "raw")
    corrected = make_log([c, b, a], [0.0, 2.0, 1.1], "corrected")
    p = pair_truth(raw, corrected, time_tol_s=2.0)
    assert p.raw_index.tolist() == [0, 2, 3]


def test_logs_of_different_runs_are_refused_naming_both_files() -> None:
    raw = make_log([[1.0, 2.0], [3.0, 4.0]], [0, 1], "raw.clf")
    other = make_log([[5.0, 6.0]], [0], "other.log")
    with pytest.raises(LogFormatError, match=r"other\.log.*raw\.clf"):
        pair_truth(raw, other)


def test_timestamps_too_coarse_to_check_leave_ranges_and_order() -> None:
    # The corrected log prints its times to ten thousand seconds (every scan "1.01893e+09"):
    # no twin lies within 0.5 s of any clock offset, yet the ranges name each twin. A robot
    # standing still repeats a scan: its first repeat after the last pair is where it stood.
    rng = np.random.default_rng(3)
    scans = [list(np.round(rng.uniform(0.5, 10, 6), 2)) for _ in range(12)]
    scans[5] = scans[6] = scans[4]  # standing still at scans 4-6
    raw = make_log(scans, [1018931783.43 + 0.37 * k for k in range(12)], "raw")
    kept = [0, 2, 4, 7, 8, 11]
    corrected = make_log([scans[k] for k in kept], [1.01893e09] * len(kept), "corrected")
    p = pair_truth(raw, corrected)
    assert not p.times_used
    assert p.raw_index.tolist() == kept
    assert "paired by ranges and order alone" in p.summary()
    assert "more than 0.5 s from the clock offset" in p.summary()
    # a wider tolerance let half of these twins agree with an offset fitted to nothing, and
    # two of the six pairs were lost: a clock that repeats itself checks nothing either way
    wide = pair_truth(raw, corrected, time_tol_s=2.0)
    assert "more than 2 s from" in wide.summary()
    assert not wide.times_used and wide.raw_index.tolist() == kept
    # with usable times the same log is checked by them
    timed = make_log([scans[k] for k in kept], [0.37 * k for k in kept], "corrected")
    q = pair_truth(raw, timed)
    assert q.times_used and q.raw_index.tolist() == kept
    assert "clock offset" in q.summary()


def test_twins_at_the_wrong_time_are_not_paired() -> None:
    a, b = [1.0, 2.0], [3.0, 4.0]
    raw = make_log([a, b, b], [0.0, 1.0, 2.0], "raw")
    corrected = make_log([a, b], [0.0, 30.0], "corrected")  # b's twin would be 28 s late
    p = pair_truth(raw, corrected)
    assert p.raw_index.tolist() == [0]


@pytest.mark.parametrize(
    ("raw_name", "corrected_name", "n_corrected"),
    [
        ("intel.clf.gz", "intel-corrected.log.gz", 910),
        ("fr079.clf.gz", "freiburg-079-corrected.log.gz", 4791),
    ],
)
def test_every_corrected_scan_of_the_shared_logs_has_its_raw_twin(
    raw_name: str, corrected_name: str, n_corrected: int
) -> None:
    raw_path, cor_path = DATA / "carmen-raw" / raw_name, DATA / "carmen" / corrected_name
    if not (raw_path.is_file() and cor_path.is_file()):
        pytest.skip(
            f"{raw_path} or {cor_path} is absent (../shared/data is not beside the project)"
        )
    from ceamcl.io.carmen import read_carmen

    raw, corrected = read_carmen(raw_path), read_carmen(cor_path)
    p = pair_truth(raw, corrected)
    assert p.n_matched == n_corrected == len(corrected)
    # fr079's laser sits 4 cm behind its robot's centre (PARAM robot_frontlaser_offset -0.04,
    # and the raw FLASER lines' laser pose); the corrected log's laser pose is its pose
    assert p.mount_moved == (n_corrected if raw_name == "fr079.clf.gz" else 0)
    assert p.mount_shift_m == pytest.approx(0.04 if raw_name == "fr079.clf.gz" else 0.0, abs=1e-4)
    assert np.all(np.diff(p.raw_index) > 0)
    assert p.times_used
    # twins have the same ranges
    for k in (0, p.n_matched // 2, p.n_matched - 1):
        np.testing.assert_allclose(
            raw.ranges(int(p.raw_index[k])), corrected.ranges(int(p.truth_index[k])), atol=5e-4
        )
    # The same corrected log with GMapping's coarse absolute timestamps (Belgioioso's .gfs.log
    # prints 1.01893e+09: ten thousand seconds a step), and with no clock at all: the same pairs.
    epoch = 1.0e9 + float(raw.times[0])
    coarse = [float(f"{epoch + t:g}") for t in corrected.times]
    assert len(set(coarse)) <= 2
    for times in (coarse, [0.0] * len(corrected)):
        q = pair_truth(raw, replace(corrected, times=np.asarray(times)))
        assert not q.times_used and "ranges and order alone" in q.summary()
        assert q.raw_index.tolist() == p.raw_index.tolist()
        assert q.truth_index.tolist() == p.truth_index.tolist()


def _flaser_log(path: Path, scans: list[list[float]], times: list[float], neff: bool) -> Path:
    lines = []
    for k, (r, t) in enumerate(zip(scans, times, strict=True)):
        ranges = " ".join(f"{v:.3f}" for v in r)
        pose = f"{0.1 * k:.3f} 0.0 0.0"
        lines.append(f"FLASER {len(r)} {ranges} {pose} {pose} {t:.3f} host {t:.3f}")
        if neff:
            lines.append(f"NEFF 10.0 {t:.3f} host {t:.3f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_truth_log_that_does_not_look_corrected_is_used_with_a_warning(
    tmp_path: Path,
) -> None:
    """A corrected log written by another SLAM tool may have no NEFF messages: --truth-from
    takes its poses as asked and says that it does not look corrected."""
    rng = np.random.default_rng(1)
    scans = [list(np.round(rng.uniform(0.5, 10, 181), 2)) for _ in range(8)]
    times = [100.0 + 0.5 * k for k in range(8)]
    raw = _flaser_log(tmp_path / "raw.clf", scans, times, neff=False)
    kept = [0, 2, 5, 7]
    truth = _flaser_log(
        tmp_path / "other-slam.log", [scans[k] for k in kept], [times[k] for k in kept], False
    )
    with pytest.warns(InputWarning, match="does not look SLAM-corrected"):
        prepared = prepare_log(raw, truth_from=truth)
    assert prepared.has_truth and "warning" in prepared.truth_reason
    assert prepared.pairing is not None and prepared.pairing.raw_index.tolist() == kept
    # the same log with its NEFF messages is taken without a warning
    corrected = _flaser_log(
        tmp_path / "corrected.log", [scans[k] for k in kept], [times[k] for k in kept], True
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", InputWarning)
        quiet = prepare_log(raw, truth_from=corrected)
    assert "warning" not in quiet.truth_reason


def _course(n: int, rng: np.random.Generator, turning: bool = True) -> np.ndarray:
    """A robot's poses: drives of up to 0.3 m and turns of up to 0.6 rad (in place at times)."""
    poses = np.zeros((n, 3))
    for k in range(1, n):
        drive = 0.0 if rng.random() < 0.3 else rng.uniform(0.0, 0.3)
        turn = rng.uniform(-0.6, 0.6) if turning else 0.0
        th = poses[k - 1, 2]
        poses[k] = poses[k - 1] + [drive * np.cos(th), drive * np.sin(th), turn]
    return poses


def test_the_mount_the_poses_and_the_odometry_agree_on_is_found() -> None:
    """io/truth.py, "which mount the data suggest": corrected laser poses of a laser 9 cm ahead
    of the axis and 1 cm to the left, and odometry of the axis in a frame of its own (turned
    and moved, with noise and a few glitches), give back that mount within a few millimetres;
    a robot that never turns does not show it."""
    rng = np.random.default_rng(3)
    robot = _course(400, rng)
    mount = np.array([0.09, 0.01, 0.0])
    laser = laser_poses(robot, mount)
    # the odometry's frame: the robot's poses composed onto (5, -2, 0.7)
    odometry = laser_poses(np.tile([5.0, -2.0, 0.7], (400, 1)), robot)
    odometry[:, :2] += rng.normal(0.0, 0.002, (400, 2))
    odometry[100:, 0] += 0.5  # a glitch: the odometry jumps once
    odometry[250, 2] = np.nan  # and one reading is not a number
    found = suggest_mount(laser, odometry)
    assert found is not None
    np.testing.assert_allclose(found, mount[:2], atol=0.005)
    # the mount is the laser's, not the frame's: no mount, none found
    bare = suggest_mount(robot, odometry)
    assert bare is not None and np.hypot(*bare) < 0.005
    straight = _course(400, rng, turning=False)
    assert suggest_mount(laser_poses(straight, mount), straight) is None


def test_a_laser_mount_given_moves_the_truth_and_every_scan(tmp_path: Path) -> None:
    """``--laser-mount`` (``prepare_log(laser_mount=...)``): every scan of the raw log gets that
    mount, and the truth is the robot that puts its laser where the corrected log's was (the
    corrected log's laser pose is its pose): 0.1 m behind it along the heading 0."""
    rng = np.random.default_rng(2)
    scans = [list(np.round(rng.uniform(0.5, 10, 181), 2)) for _ in range(6)]
    times = [100.0 + 0.5 * k for k in range(6)]
    raw = _flaser_log(tmp_path / "raw.clf", scans, times, neff=False)
    corrected = _flaser_log(tmp_path / "corrected.log", scans, times, neff=True)
    plain = prepare_log(raw, truth_from=corrected)
    mounted = prepare_log(raw, truth_from=corrected, laser_mount=(0.1, 0.0, 0.0))
    assert np.all(mounted.log.laser_mount == [0.1, 0.0, 0.0])
    assert plain.log.true_poses is not None and mounted.log.true_poses is not None
    np.testing.assert_allclose(
        mounted.log.true_poses, plain.log.true_poses - [0.1, 0.0, 0.0], atol=1e-12
    )
    assert "--laser-mount sets it" not in mounted.truth_reason  # it never turned: no suggestion


@pytest.mark.parametrize(
    ("raw_name", "corrected_name", "x_range"),
    [
        ("intel.clf.gz", "intel-corrected.log.gz", (0.07, 0.11)),
        ("fr079.clf.gz", "freiburg-079-corrected.log.gz", (-0.03, 0.01)),
    ],
)
def test_the_shared_raw_logs_suggest_their_lasers_mount(
    raw_name: str, corrected_name: str, x_range: tuple[float, float]
) -> None:
    """intel raw gives no mount (0), yet its SLAM poses move as a laser about 9 cm ahead of the
    odometry's axis would; fr079's say about 1 cm behind, where its log says 4 cm
    (docs/real-data.md, "the laser's mount")."""
    raw_path, cor_path = DATA / "carmen-raw" / raw_name, DATA / "carmen" / corrected_name
    if not (raw_path.is_file() and cor_path.is_file()):
        pytest.skip(
            f"{raw_path} or {cor_path} is absent (../shared/data is not beside the project)"
        )
    from ceamcl.io.carmen import read_carmen

    p = pair_truth(read_carmen(raw_path), read_carmen(cor_path))
    assert p.suggested_mount is not None
    x, y = p.suggested_mount
    assert x_range[0] < x < x_range[1] and abs(y) < 0.02
    assert "--laser-mount sets it" in p.summary()


def test_a_mount_given_does_not_make_a_corrected_log_look_raw() -> None:
    """``--laser-mount`` on a SLAM-corrected log: its poses are still the truth and the filter
    reads odometry drawn from them. The mount was applied before the log was judged, so the
    laser pose apart from the robot's read as raw odometry and the truth became the odometry."""
    path = DATA / "carmen" / "fhw-corrected.log.gz"
    if not path.is_file():
        pytest.skip(f"real log {path} is absent (the shared data folder is not mounted)")
    prepared = prepare_log(path, laser_mount=(0.1, 0.0, 0.0))
    assert prepared.has_truth and prepared.odometry == "synthetic"
    assert not np.array_equal(prepared.log.odometry, prepared.log.true_poses)
    np.testing.assert_array_equal(prepared.log.laser_mount[0], [0.1, 0.0, 0.0])
