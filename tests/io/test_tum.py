"""Tests of TUM trajectory files (``ceamcl.io.tum``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ceamcl.angles import diff
from ceamcl.io.tum import read_tum, write_tum


def random_trajectory(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.05, 0.2, n))
    poses = np.column_stack(
        [rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-np.pi, np.pi, n)]
    )
    poses[:4, 2] = [np.pi, -np.pi + 1e-7, 0.0, np.pi - 1e-7]  # the seam and zero
    return times, poses


def test_round_trip(tmp_path: Path) -> None:
    times, poses = random_trajectory(500, 60)
    path = write_tum(tmp_path / "t.tum", times, poses)
    assert path == tmp_path / "t.tum"
    t, p = read_tum(path)
    # Written with 9 decimals: values agree to 5e-10, a heading to ~1e-9 rad.
    np.testing.assert_allclose(t, times, atol=1e-9)
    np.testing.assert_allclose(p[:, :2], poses[:, :2], atol=1e-9)
    np.testing.assert_allclose(diff(p[:, 2], poses[:, 2]), 0.0, atol=1e-8)
    assert np.all((p[:, 2] > -np.pi - 1e-12) & (p[:, 2] <= np.pi))


def test_rows_hold_a_unit_quaternion_about_z(tmp_path: Path) -> None:
    times, poses = random_trajectory(300, 61)
    path = write_tum(tmp_path / "t.tum", times, poses)
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    assert len(lines) == 300
    rows = np.array([[float(v) for v in ln.split()] for ln in lines])
    assert rows.shape == (300, 8)  # t x y z qx qy qz qw
    assert np.all(rows[:, 3] == 0.0)  # planar: z = 0
    assert np.all(rows[:, 4:6] == 0.0)  # rotation axis is z: qx = qy = 0
    np.testing.assert_allclose(np.hypot(rows[:, 6], rows[:, 7]), 1.0, atol=2e-9)
    # qz = sin(yaw / 2), qw = cos(yaw / 2).
    np.testing.assert_allclose(rows[:, 6], np.sin(poses[:, 2] / 2), atol=1e-9)
    np.testing.assert_allclose(rows[:, 7], np.cos(poses[:, 2] / 2), atol=1e-9)
    assert path.read_text().startswith("# timestamp x y z qx qy qz qw")
    assert not list(tmp_path.glob("*.tmp"))  # written atomically, no leftovers


def test_single_row_and_length_mismatch(tmp_path: Path) -> None:
    path = write_tum(tmp_path / "one.tum", [1.5], [[1.0, 2.0, -0.5]])
    t, p = read_tum(path)
    assert t.shape == (1,) and p.shape == (1, 3)
    np.testing.assert_allclose(p[0], [1.0, 2.0, -0.5], atol=1e-9)
    with pytest.raises(ValueError):
        write_tum(tmp_path / "bad.tum", [0.0, 1.0], [[0.0, 0.0, 0.0]])


def test_read_accepts_any_unit_quaternion_sign(tmp_path: Path) -> None:
    # q and -q are the same rotation; files from other tools may use either.
    path = tmp_path / "neg.tum"
    yaw = 2.5
    path.write_text(f"0.0 1 2 0 0 0 {-np.sin(yaw / 2):.12f} {-np.cos(yaw / 2):.12f}\n")
    _, p = read_tum(path)
    assert float(diff(p[0, 2], yaw)) == pytest.approx(0.0, abs=1e-9)
