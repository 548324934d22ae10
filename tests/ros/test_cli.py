"""``ceamcl node`` / ``ceamcl play`` refuse bad start-up input with one line and exit code 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.needs_ros


def ceamcl(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "ceamcl", *args], capture_output=True, text=True, timeout=60
    )


def test_broken_parameter_file_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "nav2_params.yaml"
    bad.write_text("amcl:\n  ros__parameters:\n    alpha1: [1,\n")
    run = ceamcl("node", "--params", str(bad))
    assert run.returncode == 2
    assert f"ceamcl: error: {bad}: not a YAML file" in run.stderr
    assert "Traceback" not in run.stderr


def test_bad_ros_arguments_are_an_error_not_a_traceback() -> None:
    run = ceamcl("node", "--ros-args", "-p")
    assert run.returncode == 2
    assert "ceamcl: error: ROS 2 could not start" in run.stderr
    assert "Traceback" not in run.stderr


def test_play_refuses_a_missing_log(tmp_path: Path) -> None:
    run = ceamcl("play", str(tmp_path / "nothing.log"))
    assert run.returncode == 2 and "log file not found" in run.stderr


def test_play_takes_a_corrected_logs_poses_as_the_truth() -> None:
    """Without --synthetic-odometry, a SLAM-corrected CARMEN log's poses are its ground truth;
    `play` asked whether they look corrected with the log's path instead of the log and failed
    with a traceback on every such log."""
    path = (
        Path(__file__).resolve().parents[3] / "shared" / "data" / "carmen" / "fhw-corrected.log.gz"
    )
    if not path.is_file():
        pytest.skip(f"real log {path} is absent (the shared data folder is not mounted)")
    run = ceamcl("play", str(path), "--rate", "1000", "--wait", "0", "--delay", "0", "--quiet")
    assert run.returncode == 0, run.stderr[-2000:]
    assert "Traceback" not in run.stderr
