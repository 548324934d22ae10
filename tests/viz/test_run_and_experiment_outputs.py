"""The visual outputs of ``ceamcl run`` (from the replay of a log) and ``ceamcl experiment``
(from a re-run of the first trial of each algorithm), on tiny logs and short trials."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from PIL import Image

from ceamcl.cli import main
from ceamcl.experiments.common import (
    ExperimentSettings,
    first_records,
    make_trials,
    write_trial_outputs,
)
from ceamcl.experiments.routes import resolve_course
from ceamcl.experiments.trials import run_trial
from ceamcl.outputs import OutputOptions
from ceamcl.replay import obtain_map, prepare_log, replay_log
from tests.box_room import box_ranges

SCANS = 24
BEAMS = 180
BOX = (-1.0, 3.0, -1.5, 1.5)  # x_min, x_max, y_min, y_max of the room [m]


def box_log(tmp_path: Path) -> Path:
    """A CARMEN log of a robot driving 2.3 m along a 4 m x 3 m box, one FLASER a step (the
    poses are exact, so with ``--truth yes`` they are the ground truth)."""
    lines = ["PARAM robot_front_laser_max 8.0 nohost 0"]
    for k in range(SCANS):
        x, t = 0.1 * k, 0.1 * k
        ranges = box_ranges(x, 0.0, BEAMS, BOX)
        pose = f"{x:g} 0 0"
        lines.append(
            f"FLASER {BEAMS} "
            + " ".join(f"{r:.3f}" for r in ranges)
            + f" {pose} {pose} {t:g} nohost {t:g}"
        )
    path = tmp_path / "box.log"
    path.write_text("\n".join(lines) + "\n")
    return path


def expected_frames(steps: int, stride: int) -> list[int]:
    """A frame every ``stride`` steps and the last step (docs/outputs.md)."""
    return sorted({*range(0, steps, stride), steps - 1})


def mcap_counts(path: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    with path.open("rb") as fh:
        for _, channel, _ in make_reader(fh).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def gif_frames(path: Path) -> int:
    with Image.open(path) as im:
        return int(getattr(im, "n_frames", 1))  # a GIF has n_frames; a still image has 1


# ---------------------------------------------------------------------------- ceamcl run
def test_run_writes_gif_report_and_mcap_from_the_replay(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    log = box_log(tmp_path)
    monkeypatch.chdir(tmp_path)  # --mcap is relative to the current folder
    out = tmp_path / "out"
    argv = ["run", str(log), "--truth", "yes", "--gif", "--report", "--mcap", "x.mcap"]
    assert main([*argv, "--stride", "4", "--out", str(out), "--quiet"]) == 0
    frames = expected_frames(SCANS, 4)
    assert gif_frames(out / "run.gif") == len(frames)
    report = (out / "report.html").read_text()
    assert "box" in report and json.loads((out / "summary.json").read_text())["scans"] == SCANS
    counts = mcap_counts(tmp_path / "x.mcap")
    assert not (out / "x.mcap").exists()
    # every scan and the truth of every step (the log has truth), particles at the frames
    assert counts["/scan"] == SCANS
    assert counts["/ground_truth"] == SCANS
    assert counts["/estimate"] == SCANS
    assert counts["/particles"] == len(frames)


def test_mcap_into_the_new_output_folder(tmp_path: Path) -> None:
    """README: ``--mcap o/run.mcap --out o`` works when ``o`` does not exist yet."""
    log = box_log(tmp_path)
    out = tmp_path / "new" / "o"
    argv = ["run", str(log), "--truth", "yes", "--mcap", str(out / "run.mcap")]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    assert mcap_counts(out / "run.mcap")["/scan"] == SCANS
    assert (out / "summary.json").is_file()


def test_run_console_says_what_happened(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The table and the verdict of ``ceamcl run``: odometry source, restarts, units, no
    ``nan``, within 100 columns, and a verdict that agrees with summary.json."""
    log = box_log(tmp_path)
    out = tmp_path / "out"
    assert main(["run", str(log), "--truth", "yes", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert max(len(line) for line in text.splitlines()) <= 100
    assert "nan" not in text
    for row in (
        "odometry",
        "synthetic, from the corrected poses",
        "restarts of global",
        "duration [s]",
        "final error [m, rad]",
        "largest estimate jump [m]",
    ):
        assert row in text, row
    assert summary["odometry_source"] == "synthetic, from the corrected poses"
    assert summary["restarts"] == len(summary["restart_scans"])
    verdict = " ".join(text.split("verdict: ", 1)[1].split())
    assert verdict.startswith(" ".join(summary["verdict"].split())[:60])
    assert (summary["convergence"] == "converged") == summary["converged"]
    if summary["converged"]:
        assert verdict.startswith(f"converged at scan {summary['scans_to_converge']}")


def test_run_writes_no_visual_output_unless_asked(tmp_path: Path) -> None:
    log = box_log(tmp_path)
    out = tmp_path / "out"
    assert main(["run", str(log), "--truth", "yes", "--out", str(out), "--quiet"]) == 0
    assert (out / "summary.json").is_file()
    for name in ("run.gif", "run.mp4", "report.html"):
        assert not (out / name).exists(), name


def test_replay_keeps_particles_only_for_outputs_and_at_the_stride(tmp_path: Path) -> None:
    prepared = prepare_log(box_log(tmp_path), truth="yes")
    grid, source = obtain_map(prepared.log, None)
    kept = {}
    for label, options in {
        "no outputs": None,
        "outputs off": OutputOptions.none(),
        "report, stride 4": OutputOptions(gif=False, report=True, stride=4),
    }.items():
        out = tmp_path / label.replace(" ", "-").replace(",", "")
        outcome = replay_log(prepared, grid, "ceamcl", map_source=source, out=out, outputs=options)
        kept[label] = sorted(outcome.result.snapshots)
        wanted = ["report.html"] if label == "report, stride 4" else []
        assert [p.name for p in outcome.files] == wanted
    assert kept["no outputs"] == [] and kept["outputs off"] == []
    assert kept["report, stride 4"] == list(range(0, SCANS, 4))


# ---------------------------------------------------------------------------- experiments
def test_experiment_writes_the_first_trial_of_each_algorithm(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "exp"
    argv = [
        "experiment",
        "table1",
        "--trials",
        "1",
        "--start-routes",
        "0",
        "--algorithms",
        "ceamcl",
    ]
    # one worker process: the trial runs in another process, the re-run in this one
    argv += ["--max-time", "5", "--gif", "--mcap", "r.mcap", "--workers", "1"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    run_dir = out / "runs" / "ceamcl"
    summary: dict[str, Any] = json.loads((run_dir / "summary.json").read_text())
    assert summary["same_as_recorded_trial"] is True
    assert summary["route"] == "room0" and summary["repetition"] == 0
    with (out / "trials.csv").open() as fh:
        (row,) = list(csv.DictReader(fh))
    assert int(row["steps"]) == summary["steps"]
    assert float(row["final_position_error_m"]) == pytest.approx(
        summary["final_position_error_m"], rel=1e-5
    )
    assert gif_frames(run_dir / "run.gif") == len(expected_frames(summary["steps"], 5))
    assert not (run_dir / "report.html").exists()
    # --mcap FILE names a file in the algorithm's folder, not in the current one
    assert not (tmp_path / "r.mcap").exists()
    assert mcap_counts(run_dir / "r.mcap")["/ground_truth"] == summary["steps"]


def test_rerun_is_checked_against_the_record(tmp_path: Path) -> None:
    course = resolve_course("table1", None, None).select([0])
    settings = ExperimentSettings(
        course=course, algorithms=("ceamcl", "mcl"), trials=2, max_time_s=1.0
    )
    trials = make_trials("table1", settings)
    records = [run_trial(t) for t in trials if t.repetition == 0]
    firsts = first_records(records)
    assert [(r.algorithm, r.repetition) for r in firsts] == [("ceamcl", 0), ("mcl", 0)]
    record = firsts[0]
    same = write_trial_outputs(record, settings, tmp_path / "a", OutputOptions.none())
    doctored = dataclasses.replace(record, estimates=record.estimates + 1e-12)
    differs = write_trial_outputs(doctored, settings, tmp_path / "b", OutputOptions.none())
    flagged = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert same.same_as_record and [p.name for p in same.files] == ["summary.json"]
    assert not differs.same_as_record and flagged["same_as_recorded_trial"] is False


def test_run_without_truth_says_it_is_not_scored(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = box_log(tmp_path)
    out = tmp_path / "out"
    assert main(["run", str(log), "--truth", "no", "--out", str(out)]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "verdict: not scored: the log has no ground truth" in text
    assert "recorded in the log" in text and "nan" not in text
    summary = json.loads((out / "summary.json").read_text())
    # the console's verdict in the file too (it was the console's only)
    assert summary["verdict"].startswith("not scored") and summary["convergence"] == "not scored"
    assert summary["odometry_source"] == "recorded in the log"
    assert summary["jumps_from_scan"] == 0 and summary["restarts"] == 0
