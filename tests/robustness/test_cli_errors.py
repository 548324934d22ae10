"""Bad command-line input: one line on stderr, exit code 2, no traceback, nothing written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ceamcl.cli import main


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "ceamcl", *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["demo", "--algorithm", "nope"], "invalid choice: 'nope'"),
        (["demo", "--world", "atlantis"], "invalid choice: 'atlantis'"),
        (["demo", "--particles", "-5"], "expected a positive whole number, got -5"),
        (["demo", "--particles", "0"], "expected a positive whole number, got 0"),
        (["demo", "--seed", "x"], "expected a whole number, got 'x'"),
        (["soak", "--steps", "-1"], "expected a positive whole number, got -1"),
        (["experiment", "marked", "--trials", "-1"], "expected a positive whole number, got -1"),
        (["evaluate-log", "x.log", "--starts", "-2"], "expected a positive whole number, got -2"),
        (["demo", "--seed", "-1"], "expected a non-negative number, got -1"),
        (["soak", "--algorithm", "pf"], "invalid choice: 'pf'"),
        (["soak", "--max-growth-pct", "nan"], "expected a positive finite number"),
        (["world", "atlantis", "-o", "x.yaml"], "invalid choice: 'atlantis'"),
    ],
)
def test_bad_arguments_exit_2_without_traceback(args: list[str], expected: str) -> None:
    done = run_cli(*args)
    assert done.returncode == 2
    assert expected in done.stderr
    assert "Traceback" not in done.stderr + done.stdout


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_output_folder_is_refused(tmp_path: Path) -> None:  # pragma: no cover
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    done = run_cli("soak", "--steps", "10", "--out", str(locked / "out"))
    assert done.returncode == 2 and "cannot create output folder" in done.stderr


def test_output_path_that_is_a_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    for argv in (
        ["demo", "--quiet", "--out", str(blocker / "out")],
        ["soak", "--quiet", "--steps", "10", "--out", str(blocker / "out")],
        ["world", "small-office", "-o", str(blocker / "map.yaml")],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("ceamcl: error: ") and str(blocker) in err
        assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # nothing half-written


def test_a_file_error_no_command_caught_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """An OSError about a file (a permission, a folder where a file goes) that reaches the
    command line is one line naming the file, exit 2; one about no file keeps its traceback."""
    import ceamcl.cli.soak as soak_cli

    def denied(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", "/results/soak.json")

    monkeypatch.setattr(soak_cli, "run_soak", denied)
    assert main(["soak", "--steps", "10", "--quiet", "--out", str(tmp_path / "s")]) == 2
    assert capsys.readouterr().err == "ceamcl: error: '/results/soak.json': Permission denied\n"

    def fault(*args: object, **kwargs: object) -> None:
        raise OSError("no file in this one")

    monkeypatch.setattr(soak_cli, "run_soak", fault)
    with pytest.raises(OSError, match="no file in this one"):
        main(["soak", "--steps", "10", "--quiet", "--out", str(tmp_path / "s")])
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize(("mode", "blocked"), [([], "evaluate.csv"), (["--tracking"], "ape.png")])
def test_evaluate_log_refuses_a_folder_where_a_result_goes_before_the_runs(
    mode: list[str], blocked: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The write failed after every run, with a traceback."""
    from tests.robustness.hostile_cases import box_log_lines, write_lines

    write_lines("box.log", box_log_lines(30, neff=True))(tmp_path)
    out = tmp_path / "ev"
    (out / blocked).mkdir(parents=True)
    args = ["evaluate-log", str(tmp_path / "box.log"), *mode, "--algorithms", "mcl"]
    assert main([*args, "--executor", "serial", "--quiet", "--out", str(out)]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"ceamcl: error: out: {str(out / blocked)!r} is a folder; evaluate-log writes a file "
        "of that name there"
    ]
    assert [p.name for p in out.iterdir()] == [blocked]
