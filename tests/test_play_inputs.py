"""``ceamcl play`` reads a log as ``ceamcl run`` does: the same odometry for a seed, the same
truth (``--truth-from`` included), the same reading options. ROS itself is replaced by a
recorder, so these tests run without the [ros] extra."""

from __future__ import annotations

import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.cli import play as play_cli
from ceamcl.replay import prepare_log

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def shared_log(*parts: str) -> Path:
    path = DATA.joinpath(*parts)
    if not path.is_file():
        pytest.skip(f"real log {path} is absent (the shared data folder is not mounted)")
    return path


@pytest.fixture
def played(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """What ``play`` would have published: the log, the map, the truth and the frames."""
    seen: dict[str, Any] = {}

    def play(log: Any, grid: Any, truth: Any, **kwargs: Any) -> int:
        seen.update(log=log, grid=grid, truth=truth, **kwargs)
        return len(log)

    def frames(*names: str) -> tuple[str, ...]:
        return names

    fake = types.SimpleNamespace(play=play, Frames=frames)
    monkeypatch.setattr(play_cli, "import_ros", lambda *_: fake)
    return seen


def test_play_sends_the_odometry_run_reads_for_the_same_seed(played: dict[str, Any]) -> None:
    path = shared_log("carmen", "fhw-corrected.log.gz")
    assert main(["play", str(path), "--seed", "3", "--quiet"]) == 0
    want = prepare_log(path, seed=3).log  # what `ceamcl run --seed 3` replays
    np.testing.assert_array_equal(played["log"].odometry, want.odometry)
    np.testing.assert_array_equal(played["truth"], want.true_poses)
    assert not np.array_equal(played["log"].odometry, want.poses)  # drawn, not the truth
    # --truth no: the log as recorded and no ground truth
    assert main(["play", str(path), "--truth", "no", "--quiet"]) == 0
    assert played["truth"] is None
    np.testing.assert_array_equal(played["log"].odometry, want.poses)


def test_play_takes_its_truth_from_a_corrected_log(played: dict[str, Any]) -> None:
    raw = shared_log("carmen-raw", "fr079.clf.gz")
    corrected = shared_log("carmen", "freiburg-079-corrected.log.gz")
    assert main(["play", str(raw), "--truth-from", str(corrected), "--quiet"]) == 0
    want = prepare_log(raw, truth_from=corrected)
    assert want.pairing is not None
    truth = played["truth"]
    assert truth.shape == (len(want.log), 3)
    paired = np.isfinite(truth).all(axis=1)
    assert paired.sum() == want.pairing.n_matched  # NaN rows are not published
    assert 0 < paired.sum() < len(truth)
    np.testing.assert_array_equal(played["log"].odometry, want.log.odometry)  # the robot's own


def test_play_publishes_the_frames_it_reads(played: dict[str, Any]) -> None:
    path = shared_log("carmen", "fhw-corrected.log.gz")
    argv = ["play", str(path), "--base-frame", "base_link", "--odom-frame", "odom2", "--quiet"]
    assert main(argv) == 0
    assert played["frames"] == ("map", "odom2", "base_link", "laser")


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--truth", "no", "--synthetic-odometry"], "--truth no says they are not"),
        (["--truth-from", "X", "--synthetic-odometry"], "--synthetic-odometry has no effect"),
        (["--truth-from", "X", "--truth", "yes"], "--truth yes has no effect"),
    ],
)
def test_play_refuses_truth_options_that_contradict(
    played: dict[str, Any], extra: list[str], says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["play", "some.log", *extra]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not played  # refused before anything was read
