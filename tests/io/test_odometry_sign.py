"""Wheel odometry that lost its sign, found from the ODOM lines' velocity and repaired."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ceamcl.errors import ConfigError
from ceamcl.io.carmen import read_carmen
from ceamcl.io.odometry_sign import check_sign, signed_poses


def _drive(velocities: list[float], dt: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Straight along x: the true positions, and the poses an odometry that integrates the
    speed would record (always forward), at times 0, dt, 2 dt, ..."""
    v = np.asarray(velocities, dtype=np.float64)
    t = dt * np.arange(v.size + 1)
    true_x = np.concatenate([[0.0], np.cumsum(v * dt)])
    unsigned_x = np.concatenate([[0.0], np.cumsum(np.abs(v) * dt)])
    poses = np.column_stack([unsigned_x, np.zeros_like(t), np.zeros_like(t)])
    return t, poses, true_x


def test_an_odometry_moving_forward_while_backing_up_is_unsigned_and_repaired() -> None:
    v = [0.5] * 20 + [-0.3] * 15 + [0.4] * 20
    t, poses, true_x = _drive(v)
    tv = np.concatenate([[0.0], v])  # the velocity each ODOM line records
    sign = check_sign(t, poses, tv)
    assert sign.unsigned and sign.reversing == 15 and sign.forward == 15
    fixed, changed = signed_poses(t, poses, t, tv)
    assert changed == 15
    assert np.allclose(fixed[:, 0], true_x) and np.array_equal(fixed[:, 2], poses[:, 2])
    # scans every third ODOM line: an increment spanning a change of direction takes the
    # velocity's share, sum(tv) / sum(|tv|), of its translation
    k = np.arange(0, t.size, 3)
    coarse, _ = signed_poses(t[k], poses[k], t, tv)
    assert np.allclose(coarse[:, 0], true_x[k])


def test_a_signed_odometry_and_one_without_velocity_are_left_alone() -> None:
    v = [0.5] * 20 + [-0.3] * 15
    t, poses, true_x = _drive(v)
    signed = poses.copy()
    signed[:, 0] = true_x  # an odometry that goes backwards
    tv = np.concatenate([[0.0], v])
    assert not check_sign(t, signed, tv).unsigned
    assert not check_sign(t, poses, np.zeros_like(tv)).unsigned  # tv = 0: nothing to tell
    assert not check_sign(t[:8], poses[:8], tv[:8]).unsigned  # too few moves to judge


def test_nan_poses_and_velocities_never_spread() -> None:
    v = [0.5] * 10 + [-0.3] * 12
    t, poses, _ = _drive(v)
    tv = np.concatenate([[np.nan], v])
    assert check_sign(t, poses, tv).unsigned
    fixed, _ = signed_poses(t, poses, t, tv)
    assert np.isfinite(fixed).all()
    holed = poses.copy()
    holed[3, 0] = np.nan
    same, changed = signed_poses(t, holed, t, tv)
    assert changed == 0 and np.array_equal(same, holed, equal_nan=True)


def _write_log(path: Path, velocities: list[float]) -> Path:
    """A CARMEN log whose ODOM and FLASER poses integrate the speed, with the signed tv."""
    t, poses, _ = _drive(velocities)
    tv = np.concatenate([[0.0], velocities])
    ranges = " ".join(["2.0"] * 181)
    lines = []
    for k in range(t.size):
        x = poses[k, 0]
        lines.append(f"ODOM {x:.4f} 0 0 {tv[k]:.3f} 0 0 {t[k]:.3f} host {t[k]:.3f}")
        if k % 2 == 0:
            lines.append(
                f"FLASER 181 {ranges} {x:.4f} 0 0 {x:.4f} 0 0 {t[k] + 0.01:.3f} host {t[k]:.3f}"
            )
    path.write_text("\n".join(lines) + "\n")
    return path


def test_the_reader_repairs_a_log_by_default_and_says_so(tmp_path: Path) -> None:
    v = [0.5] * 20 + [-0.3] * 20 + [0.5] * 10
    log_path = _write_log(tmp_path / "unsigned.clf", v)
    auto = read_carmen(log_path)
    recorded = read_carmen(log_path, odometry_sign="recorded")
    assert "no sign" in auto.info["odometry_sign"] and "odometry_sign" not in recorded.info
    assert np.all(np.diff(recorded.poses[:, 0]) >= 0)
    x = auto.poses[:, 0]
    assert x[10] == pytest.approx(1.0, abs=0.06) and x[20] == pytest.approx(0.4, abs=0.06)
    with pytest.raises(ConfigError, match="odometry-sign"):
        read_carmen(log_path, odometry_sign="flip")
