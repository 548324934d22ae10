"""Tests of the ``ceamcl`` command line (``ceamcl.cli``), in-process and as a subprocess."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ceamcl.cli import main
from ceamcl.maps.worlds import get_world

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SUMMARY_KEYS = {
    "algorithm",
    "world",
    "seed",
    "steps",
    "final_position_error_m",
    "final_heading_error_rad",
    "mean_step_ms",
    "particles_final",
}


def run_demo_cli(out: Path) -> int:
    return main(["demo", "--algorithm", "mcl", "--seed", "3", "--out", str(out), "--quiet"])


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "D"
    assert run_demo_cli(out) == 0
    return out


def test_demo_writes_summary(demo_dir: Path) -> None:
    summary = json.loads((demo_dir / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["algorithm"] == "mcl"
    assert summary["world"] == "symmetric-hall"
    assert summary["seed"] == 3
    assert isinstance(summary["steps"], int) and summary["steps"] > 100
    assert summary["final_position_error_m"] >= 0.0
    assert 0.0 <= summary["final_heading_error_rad"] <= np.pi
    assert summary["mean_step_ms"] > 0.0
    assert summary["particles_final"] >= 1
    # the localisation state at the end (docs/state.md), as ceamcl run reports it
    assert summary["final_state"] in {"LOCALISED", "AMBIGUOUS", "LOST", "INITIALISING"}
    assert 0.0 <= summary["final_state_confidence"] <= 1.0 and summary["final_state_reason"]


def test_a_run_into_a_used_folder_leaves_no_file_of_the_earlier_run(tmp_path: Path) -> None:
    """A CEAMCL run's species.csv/png and run.gif stayed beside a later MCL run's summary."""
    out = tmp_path / "D"
    out.mkdir()
    for name in ("species.csv", "species.png", "run.gif", "report.html"):
        (out / name).write_text("an earlier run's")
    (out / "notes.txt").write_text("the user's")
    argv = ["demo", "--algorithm", "mcl", "--seed", "3", "--out", str(out), "--quiet"]
    assert main([*argv, "--no-animation"]) == 0
    names = {p.name for p in out.iterdir()}
    assert "summary.json" in names and "notes.txt" in names
    assert not names & {"species.csv", "species.png", "run.gif", "report.html"}


def test_demo_writes_tum_trajectories(demo_dir: Path) -> None:
    steps = json.loads((demo_dir / "summary.json").read_text())["steps"]
    for name in ("trajectory.tum", "groundtruth.tum"):
        rows = np.loadtxt(demo_dir / name, comments="#", ndmin=2)
        assert rows.shape == (steps, 8), name
        np.testing.assert_allclose(np.diff(rows[:, 0]), 0.1, atol=1e-6)
        np.testing.assert_allclose(np.hypot(rows[:, 6], rows[:, 7]), 1.0, atol=1e-6)
        assert np.all(rows[:, 3:6] == 0.0)
    # The last row of the truth is where the summary's final error is measured from.
    summary = json.loads((demo_dir / "summary.json").read_text())
    est = np.loadtxt(demo_dir / "trajectory.tum", ndmin=2)[-1]
    truth = np.loadtxt(demo_dir / "groundtruth.tum", ndmin=2)[-1]
    assert np.hypot(est[1] - truth[1], est[2] - truth[2]) == pytest.approx(
        summary["final_position_error_m"], abs=1e-6
    )


def test_demo_writes_png_and_diagnostics(demo_dir: Path) -> None:
    png = demo_dir / "run.png"
    assert png.read_bytes()[:8] == PNG_SIGNATURE
    with Image.open(png) as img:
        img.verify()
    with Image.open(png) as img:
        assert img.format == "PNG" and min(img.size) > 100
    steps = json.loads((demo_dir / "summary.json").read_text())["steps"]
    with (demo_dir / "diagnostics.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == steps
    assert {"step", "n_particles", "ess", "step_ms"} <= set(rows[0])
    assert [int(r["step"]) for r in rows] == list(range(steps))
    assert not (demo_dir / "species.csv").exists()  # MCL has no species


def test_demo_is_reproducible(demo_dir: Path, tmp_path: Path) -> None:
    again = tmp_path / "again"
    assert run_demo_cli(again) == 0
    for name in ("trajectory.tum", "groundtruth.tum"):
        assert (again / name).read_bytes() == (demo_dir / name).read_bytes(), name


@pytest.mark.parametrize("fmt", ["pgm", "png"])
def test_world_export_loads_back_equal(tmp_path: Path, fmt: str) -> None:
    from ceamcl.maps.ros_io import load_map

    target = tmp_path / "maps" / "m.yaml"
    assert main(["world", "symmetric-hall", "-o", str(target), "--format", fmt]) == 0
    assert target.is_file()
    assert (tmp_path / "maps" / f"m.{fmt}").is_file()
    assert load_map(target) == get_world("symmetric-hall")


def test_printed_paths_and_reasons_keep_their_brackets(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Rich reads "[peers]" as markup and drops it: the install hint lost its extra and paths
    # their folder names.
    from ceamcl.filters import registry

    target = tmp_path / "br[peers]" / "m.yaml"
    assert main(["world", "small-office", "-o", str(target)]) == 0
    assert str(target) in capsys.readouterr().out.replace("\n", "")
    monkeypatch.setattr(
        registry,
        "unavailable_reason",
        lambda name: "not installed (pip install 'ceamcl[peers]')" if name == "nav2-amcl" else None,
    )
    argv = ["experiment", "table1", "--trials", "1", "--algorithms", "nav2-amcl"]
    assert main([*argv, "--out", str(tmp_path / "x")]) == 2
    assert "pip install 'ceamcl[peers]'" in capsys.readouterr().out


def test_world_list(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["world", "--list"]) == 0
    out = capsys.readouterr().out
    for name in ("symmetric-hall", "marked-hall", "small-office"):
        assert name in out


@pytest.mark.parametrize(
    "argv",
    [
        ["demo", "--algorithm", "mcl", "--world", "no-such-world"],
        ["demo", "--algorithm", "no-such-algorithm"],
        ["demo", "--algorithm", "mcl", "--particles", "-3"],
        ["demo", "--algorithm", "mcl", "--particles", "0"],
        ["demo", "--algorithm", "mcl", "--particles", "many"],
        ["demo", "--algorithm", "mcl", "--seed", "-1"],
        ["world", "no-such-world", "-o", "m.yaml"],
        [],
    ],
)
def test_bad_arguments_exit_2_without_traceback(
    argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    with pytest.raises(SystemExit) as info:
        main([*argv, "--out", str(tmp_path / "x")] if argv[:1] == ["demo"] else argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 2 and ": error: " in lines[0]  # the error, then where help is
    assert lines[1].startswith("(see 'ceamcl") and lines[1].endswith("--help')")
    assert "Traceback" not in err
    assert not (tmp_path / "x").exists()  # nothing ran


def test_particles_message_names_the_problem(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["demo", "--algorithm", "mcl", "--particles", "-3"])
    err = capsys.readouterr().err
    assert "--particles" in err and "-3" in err


@pytest.mark.parametrize(
    ("mount", "says"),
    [
        ("0.1,0", "three numbers"),
        ("a,b,c", "three numbers"),
        ("nan,0,0", "finite"),
        ("3,0,0", "within 2 m"),
        ("0,0,4", "[-pi, pi]"),
    ],
)
def test_a_bad_laser_mount_is_refused_naming_the_option(
    mount: str, says: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["run", str(tmp_path / "log.clf"), "--laser-mount", mount])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--laser-mount" in err and says in err and "Traceback" not in err


def test_world_without_output_is_a_clean_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["world", "symmetric-hall"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ceamcl: error:")
    assert "Traceback" not in err


def test_subprocess_unknown_world_exits_2_without_traceback(tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ceamcl.cli",
            "demo",
            "--algorithm",
            "mcl",
            "--world",
            "atlantis",
            "--out",
            str(tmp_path / "x"),
            "--quiet",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "atlantis" in proc.stderr and "symmetric-hall" in proc.stderr
    assert not (tmp_path / "x").exists()


def test_subprocess_world_export(tmp_path: Path) -> None:
    from ceamcl.maps.ros_io import load_map

    target = tmp_path / "office.yaml"
    proc = subprocess.run(
        [sys.executable, "-m", "ceamcl.cli", "world", "small-office", "-o", str(target)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert load_map(target) == get_world("small-office")


@pytest.mark.parametrize("command", ["demo", "soak"])
def test_an_algorithm_that_cannot_run_here_is_refused_with_the_reason(
    command: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Every registered algorithm is offered; one whose optional extra is missing (the Nav2
    peer without ``[peers]``) is refused before any work, saying why."""
    from ceamcl.filters import registry

    monkeypatch.setattr(
        registry,
        "unavailable_reason",
        lambda name: "Nav2's AMCL is not installed" if name == "nav2-amcl" else None,
    )
    out = tmp_path / "out"
    code = main([command, "--algorithm", "nav2-amcl", "--out", str(out), "--quiet"])
    assert code == 2
    err = capsys.readouterr().err
    assert "nav2-amcl cannot run here: Nav2's AMCL is not installed" in err
    assert not out.exists()


def test_delta_refuses_another_algorithm_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "delta"
    argv = ["experiment", "delta", "--algorithms", "mcl", "--trials", "1", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["ceamcl: error: algorithms: the delta experiment runs ceamcl only, got mcl"]
    assert not out.exists()
    with pytest.raises(SystemExit):
        main(["experiment", "delta", "--help"])
    assert "only ceamcl" in " ".join(capsys.readouterr().out.split())


def test_experiment_console_one_run_units_and_width(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One run is "1 run"; the table shows its units and fits 100 columns, with no nan."""
    argv = ["experiment", "table1", "--trials", "1", "--algorithms", "mcl", "--start-routes", "0"]
    argv += ["--max-time", "1", "--executor", "serial", "--out", str(tmp_path / "t")]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "1 run " in text and "1 runs" not in text and "nan" not in text
    assert "conv. [s]" in text and "err [m]" in text and "step [ms]" in text
    assert max(len(line) for line in text.splitlines()) <= 100


# ---------------------------------------------------------------- the demo's console tables
def test_demo_summary_places_every_hypothesis_and_counts_the_initialisation(
    demo_dir: Path,
) -> None:
    s = json.loads((demo_dir / "summary.json").read_text())
    hyps = s["hypotheses_final"]
    assert s["hypotheses_count"] == len(hyps)  # MCL seed 3 ends with few clusters: all listed
    at_images = sum(h["weight"] for h in hyps if h["image"] is not None)
    assert at_images == pytest.approx(s["true_image_weight"])
    assert s["true_image_weight"] + s["spurious_weight"] == pytest.approx(1.0)
    at_truth = sum(h["weight"] for h in hyps if h["image"] == 0)
    assert at_truth == pytest.approx(s["truth_weight"])
    assert min(h["position_error_m"] for h in hyps) == pytest.approx(
        s["closest_hypothesis_error_m"]
    )
    # Likelihood evaluations: the run's total is the sum of diagnostics.csv's column, whose
    # step 0 (the global initialisation: every one of MCL's particles weighted) counts.
    with (demo_dir / "diagnostics.csv").open(newline="") as fh:
        per_step = [int(r["likelihood_evaluations"]) for r in csv.DictReader(fh)]
    assert s["likelihood_evaluations"] == sum(per_step)
    assert s["initialisation_likelihood_evaluations"] == per_step[0] == s["samples_initial"]


def _demo_summary(weights: list[float], images: list[int | None], estimate: int) -> dict:
    """A summary.json of a run ending with one hypothesis per weight, at those images."""
    hyps = [
        {
            "x": 1.0 + i,
            "y": 2.0,
            "theta": 0.5,
            "weight": w,
            "fitness": 0.9,
            "image": k,
            "position_error_m": 0.05 if k == 0 else 9.4,
            "heading_error_rad": 0.01 if k == 0 else 1.57,
        }
        for i, (w, k) in enumerate(zip(weights, images, strict=True))
    ]
    est = hyps[estimate]
    return {
        "algorithm": "ceamcl",
        "hypotheses_final": hyps,
        "hypotheses_count": len(hyps),
        "species_final": len(hyps),
        "symmetric_images": 4,
        "estimate_hypothesis": estimate,
        "estimate_image": est["image"],
        "final_position_error_m": est["position_error_m"],
        "final_heading_error_rad": est["heading_error_rad"],
        "closest_hypothesis_error_m": 0.05,
        "closest_hypothesis_heading_error_rad": 0.01,
        "images_kept": len({k for k in images if k is not None}),
        "truth_weight": sum(w for w, k in zip(weights, images, strict=True) if k == 0),
        "true_image_weight": sum(w for w, k in zip(weights, images, strict=True) if k is not None),
        "spurious_weight": sum(w for w, k in zip(weights, images, strict=True) if k is None),
        "confidently_wrong": est["image"] != 0 and max(weights) >= 0.9,
        "samples_initial": 900,
        "samples_final": 300,
        "likelihood_evaluations": 1_234_567,
        "initialisation_likelihood_evaluations": 1_000_000,
        "restarts": 0,
        "steps": 425,
        "mean_step_ms": 2.0,
        "median_step_ms": 1.5,
    }


def _render(*tables: object) -> str:
    from rich.console import Console

    console = Console(record=True, width=100)
    for t in tables:
        console.print(t)
    return console.export_text()


def test_demo_table_reads_an_equal_symmetric_image_as_an_image_not_a_failure() -> None:
    from ceamcl.cli.demo import hypotheses_table, state_table

    s = _demo_summary([0.25, 0.25, 0.25, 0.24, 0.01], [3, 0, 1, 2, None], estimate=0)
    text = _render(hypotheses_table("demo", s), state_table("demo", s))
    lines = text.splitlines()
    # The hypotheses lead: the first table lists them, the estimate marked, weights shown.
    assert "5 species at the end" in lines[0]
    first_row = next(line for line in lines if line.startswith("│ 1 "))
    assert "image 3 of 4, estimate" in first_row and "25%" in first_row
    assert text.index("the truth") < text.index("the filter at the end")
    assert "image 3 of 4 alike (off truth 9.40 m, 1.57 rad)" in text
    assert "wrong" not in text.split("the filter at the end")[1].split("confidently")[0]
    assert "0.050, 0.010" in text  # the nearest hypothesis
    assert "25% / 99% / 1%" in text
    assert "1,234,567 (1,000,000)" in text
    assert max(len(line) for line in lines) <= 100


def test_demo_table_says_wrong_and_confidently_wrong_when_it_is() -> None:
    from ceamcl.cli.demo import state_table

    spurious = _demo_summary([0.95, 0.05], [None, 0], estimate=0)
    text = _render(state_table("demo", spurious))
    assert "wrong: at no image of the truth" in text
    assert "confidently wrong (>= 90 % on one pose) │ yes" in text
    right = _demo_summary([0.95, 0.05], [0, 2], estimate=0)
    text = _render(state_table("demo", right))
    assert "at the truth (off 0.05 m, 0.01 rad)" in text and "│ no" in text


def test_demo_prints_the_hypotheses_before_the_filter_state(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["demo", "--algorithm", "mcl", "--seed", "3", "--no-animation"]
    assert main([*argv, "--out", str(tmp_path / "d")]) == 0
    out = capsys.readouterr().out
    assert "at the end" in out and "off truth [m, rad]" in out
    assert out.index("pose [m, m, rad]") < out.index("the filter at the end")
    assert "likelihood evaluations (initialisation)" in out


def test_ceamcl_with_the_beam_model_is_told_what_its_state_reads() -> None:
    """``run``/``evaluate-log --sensor beam`` with CEAMCL: a note says the state's thresholds
    were chosen with the field (docs/sensor-models.md); no note otherwise."""
    import io

    from rich.console import Console

    from ceamcl.cli.run import print_sensor_note

    def said(sensor: str, algorithms: list[str]) -> str:
        buf = io.StringIO()
        print_sensor_note(Console(file=buf, width=200), sensor, algorithms)
        return buf.getvalue()

    assert "reads LOST at most scans" in said("beam", ["mcl", "ceamcl"])
    assert said("beam", ["mcl", "nav2-amcl"]) == ""
    assert said("likelihood-field", ["ceamcl"]) == ""


def test_every_option_with_a_default_shows_it_in_its_help() -> None:
    """README: `--help` shows every default. An option without help text showed nothing, and
    a default of 0 (equal to False) was hidden as if it were a flag's absence."""
    import argparse

    from ceamcl.cli import DefaultsFormatter, _leaf_parsers, build_parser

    missing = []
    for leaf in _leaf_parsers(build_parser()):
        formatter = DefaultsFormatter(leaf.prog)
        for action in leaf._actions:
            default = action.default
            if (
                not action.option_strings
                or action.nargs == 0
                or default is None
                or default is False
                or default is argparse.SUPPRESS
            ):
                continue
            text = formatter._expand_help(action) if action.help else ""
            if "default" not in text:
                missing.append(f"{leaf.prog} {action.option_strings[-1]}")
    assert not missing, missing


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["evaluate-log", "LOG", "--particles", "500"], "particles: only with --tracking"),
        (["evaluate-log", "LOG", "--executor", "bogus"], "executor: unknown executor"),
        (["evaluate-log", "LOG", "--executor", "dask://h:1", "--workers", "2"], "workers:"),
        (["evaluate-log", "LOG", "--every-scan", "--update-min-d", "0.2"], "update-min-d/-a"),
        (["run", "LOG", "--every-scan", "--update-min-a", "0.1"], "update-min-d/-a"),
        (["run", "LOG", "--truth-from", "C", "--truth", "no"], "truth: --truth no"),
        (["evaluate-log", "LOG", "--tracking", "--starts", "5"], "starts: --starts"),
        (["evaluate-log", "LOG", "--tracking", "--hold-m", "3"], "hold-m: --hold-m"),
        (["evaluate-log", "LOG", "--tracking", "--particles", "10**11"], "over the memory budget"),
        (["experiment", "state", "--executor", "bogus"], "executor: unknown executor"),
        (["experiment", "state", "--start-routes", "0"], "start-routes: the state"),
        (["experiment", "table1", "--starts", "5"], "--start-routes I,J"),
        # no route: empty tables with exit 0 (marked, tune, state), a traceback (kidnapped, delta)
        (["experiment", "marked", "--start-routes", ""], "--start-routes: expected comma"),
        (["experiment", "tune", "--start-routes", " , "], "route numbers (one or more)"),
        (["experiment", "kidnapped", "--start-routes", ""], "route numbers (one or more)"),
        (["experiment", "delta", "--start-routes", ","], "route numbers (one or more)"),
        (["experiment", "state", "--world", "marked-hall", "--start-routes", ""], "one or more"),
        (["experiment", "tune", "--max-beams", "inf"], "argument --max-beams"),
        (["experiment", "tune", "--particle-counts", "1.7"], "argument --particle-counts"),
        # an empty list ran the defaults; a value given twice ran once and was counted twice
        (["experiment", "delta", "--deltas", ","], "--deltas: expected one or more values"),
        # refused before the trials, not after them as "the run has no kidnap"
        (["experiment", "kidnapped", "--max-time", "10"], "max-time: expected more than the"),
        (["experiment", "delta", "--deltas", "20,80,80"], "80 given twice"),
        (["experiment", "tune", "--max-beams", "30,30"], "30 given twice"),
        (["experiment", "tune", "--tempers", ","], "--tempers: expected one or more values"),
        # headings from the scan without test poses: no configuration, an empty sweep ran
        (
            ["experiment", "tune", "--init-headings", "scan", "--init-test-poses", "0"],
            "init-headings: headings from the scan apply only with test poses",
        ),
        (["play", "LOG", "--delay", "inf"], "argument --delay"),
        # only node and play hand what follows --ros-args to ROS; run dropped it without a word
        (["run", "LOG", "--ros-args", "--seed", "7"], "unrecognized arguments: --ros-args"),
        # --resolution shapes a map built from the log; with --map it was ignored
        (["run", "LOG", "--map", "m.yaml", "--resolution", "0.1"], "resolution: --resolution"),
        (["evaluate-log", "LOG", "--map", "m.yaml", "--resolution", "0.1"], "its own"),
        (["demo", "--particles", "7"], "particles: ceamcl sizes its own sample"),
        (["experiment", "table1", "--mcap", "d/r.mcap"], "mcap: expected a file name"),
        (["soak", "--particles", "7", "--steps", "5"], "particles: ceamcl sizes its own sample"),
    ],
)
def test_option_conflicts_and_bad_values_are_refused_before_any_work(
    args: list[str], named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each of these was accepted and ignored, refused only after the log was read and the map
    built, or ended in a traceback. The log does not exist: an error about the option, not
    about the log, shows that the option was judged first."""
    args = [str(tmp_path / "missing.log") if a == "LOG" else a for a in args]
    args = [str(10**11) if a == "10**11" else a for a in args]
    try:  # argparse's own refusals end in SystemExit(2), the others return 2
        code = main([*args, "--out", str(tmp_path / "out")] if args[0] != "play" else args)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert named in err and "Traceback" not in err
    assert "missing.log" not in err


def test_world_output_without_a_world_to_write_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # it listed the worlds and exited 0 without writing the file it was asked for
    target = tmp_path / "map.yaml"
    assert main(["world", "-o", str(target)]) == 2
    assert main(["world", "--list", "-o", str(target)]) == 2
    assert capsys.readouterr().err.count("expected a NAME") == 2 and not target.exists()


def test_bench_data_without_real_maps_is_refused_for_the_latency_run_too(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # --ros-latency returned before the check and ignored --data
    assert main(["bench", "--ros-latency", "--data", "/nonexistent"]) == 2
    assert "--data is read with --real-maps only" in capsys.readouterr().err


def test_evaluate_log_takes_comma_separated_algorithms_as_experiment_does(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    # an unknown name is still refused before the log is read, by the registry's message
    args = ["evaluate-log", str(tmp_path / "missing.log"), "--algorithms", "mcl,ekf"]
    assert main([*args, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "unknown algorithm 'ekf'" in err and "missing.log" not in err


def test_a_missing_tf2_msgs_says_how_to_build_it(monkeypatch: pytest.MonkeyPatch) -> None:
    # 'ceamcl[ros]' from PyPI has rclpy but no tf2_msgs (no wheel ships it): the error must not
    # tell the user to install what is installed (docs/ros.md).
    from ceamcl.cli import node
    from ceamcl.errors import CeamclError

    def missing(name: str) -> None:
        raise ModuleNotFoundError("No module named 'tf2_msgs'", name="tf2_msgs")

    monkeypatch.setattr(node, "import_module", missing)
    with pytest.raises(CeamclError, match=r"tf2_msgs, which has no wheel on PyPI.*build-tf2-msgs"):
        node.import_ros("node", "node")

    def no_rclpy(name: str) -> None:
        raise ModuleNotFoundError("No module named 'rclpy'", name="rclpy")

    monkeypatch.setattr(node, "import_module", no_rclpy)
    with pytest.raises(CeamclError, match=r"install 'ceamcl\[ros\]'"):
        node.import_ros("play", "play")


def test_a_runs_progress_bars_say_which_is_the_steps_and_which_the_frames() -> None:
    """A re-run with --gif (and ``demo``/``run`` with an animation) showed two bars with the
    same label: the steps' and the animation frames' (the tasks' descriptions were dropped)."""
    import io

    from rich.console import Console

    from ceamcl.cli.common import RunProgress, make_progress

    sink = io.StringIO()
    console = Console(file=sink, width=200, force_terminal=False)
    with make_progress("[bold]mcl[/] on room{0}, again", console) as progress:
        bar = RunProgress(progress)
        bar.start(10)
        bar.step(9)
        bar.frame(3, 3)
    lines = [line for line in sink.getvalue().splitlines() if line.strip()]
    assert any(line.startswith("mcl on room{0}, again: steps") for line in lines), lines
    assert any(line.startswith("mcl on room{0}, again: animation frames") for line in lines)


def test_quiet_hides_dasks_large_graph_warning(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``evaluate-log --executor dask --quiet`` printed Dask's six-line "Sending large graph"
    warning for every batch (each trial carries its map and log window); other warnings stay."""
    import warnings

    import ceamcl.cli.evaluate_log as evaluate_cli
    from tests.robustness.hostile_cases import box_log_lines, write_lines

    def submitting(*args: object, **kwargs: object) -> None:
        warnings.warn("Sending large graph of size 13.85 MiB.", UserWarning, stacklevel=2)
        warnings.warn("something else", UserWarning, stacklevel=2)

    monkeypatch.setattr(evaluate_cli, "evaluate_log", submitting)
    write_lines("box.log", box_log_lines(30, neff=True))(tmp_path)
    argv = ["evaluate-log", str(tmp_path / "box.log"), "--algorithms", "mcl", "--quiet"]
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        assert main([*argv, "--out", str(tmp_path / "ev")]) == 0
    messages = [str(w.message) for w in shown]
    assert "something else" in messages
    assert not any("Sending large graph" in m for m in messages)
    with warnings.catch_warnings(record=True) as caught:  # scoped to the command
        warnings.simplefilter("default")
        warnings.warn("Sending large graph of size 1 MiB.", UserWarning, stacklevel=1)
    assert len(caught) == 1


def test_run_demo_defaults_to_the_algorithm_of_ceamcl_demo() -> None:
    """``run_demo()`` ran MCL where ``ceamcl demo`` runs CEAMCL, though the docs present it as
    the command in Python."""
    import inspect

    from ceamcl.cli import build_parser
    from ceamcl.demo import DEFAULT_ALGORITHM, run_demo

    args = build_parser().parse_args(["demo"])
    assert args.algorithm == DEFAULT_ALGORITHM == "ceamcl"
    assert inspect.signature(run_demo).parameters["algorithm"].default == args.algorithm


def test_a_narrow_console_folds_the_names_of_a_table_instead_of_cutting_them() -> None:
    """On a 100-column console evaluate-log's table cut "mcl-tuned" to "mcl-tu…": the row's
    name is what a reader needs most, so the name column folds and keeps every letter."""
    from rich.console import Console

    from ceamcl.cli.common import plain_table

    header = ("algorithm", *(f"figure {i} [unit]" for i in range(9)))
    names = ("ceamcl", "mcl-tuned", "kld-amcl-tuned")
    table = plain_table("t", header, [(n, *("123.456" for _ in range(9))) for n in names])
    console = Console(width=100, record=True)
    console.print(table)
    lines = console.export_text().splitlines()
    assert max(len(line) for line in lines) <= 100
    # the first column of every line, joined row by row, spells the names whole
    cells = [line.split("│")[1].strip() for line in lines if line.startswith("│")]
    assert "".join(cells) == "".join(names)
