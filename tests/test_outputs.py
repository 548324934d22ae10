"""Tests of ``ceamcl.outputs`` (the shared output options) and of ``ceamcl demo`` writing
the animation, the report and the MCAP file."""

from __future__ import annotations

import argparse
import csv
import os
from pathlib import Path

import pytest
from mcap.reader import make_reader
from PIL import Image

from ceamcl.cli import build_parser, main
from ceamcl.cli.common import add_output_arguments
from ceamcl.errors import ConfigError
from ceamcl.outputs import OutputOptions, write_outputs
from tests.viz.runs import short_run


def _parse(*argv: str, animation_default: bool = True) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="x")
    add_output_arguments(parser, animation_default=animation_default)
    return parser.parse_args(list(argv))


def test_defaults_write_the_gif_only_and_keep_snapshots() -> None:
    options = OutputOptions.from_args(_parse())
    assert options == OutputOptions(gif=True, mp4=False, fps=10.0, stride=5, report=False)
    assert options.snapshot_every == 5


def test_flags_map_to_options() -> None:
    args = _parse("--no-animation", "--report", "--mcap", "out.mcap", "--fps", "4", "--stride", "3")
    options = OutputOptions.from_args(args)
    assert (options.gif, options.report, options.mcap) == (False, True, Path("out.mcap"))
    assert (options.fps, options.stride, options.snapshot_every) == (4.0, 3, 3)
    off = OutputOptions.from_args(_parse(animation_default=False))
    assert not off.any and off.snapshot_every == 0
    assert OutputOptions.from_args(_parse("--gif", animation_default=False)).gif
    assert OutputOptions.from_args({"report": True}).report  # a mapping works too


@pytest.mark.parametrize("argv", [["--stride", "0"], ["--fps", "0"], ["--fps", "nan"]])
def test_bad_numbers_are_argparse_errors(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        _parse(*argv)
    assert "expected a positive" in capsys.readouterr().err


def test_fps_and_stride_for_an_output_not_written_are_refused() -> None:
    """They were ignored without a word; --stride also sets the MCAP file's particle frames."""
    with pytest.raises(ConfigError, match="fps: --fps sets the frame rate"):
        OutputOptions.from_args(_parse("--no-animation", "--fps", "20"))
    with pytest.raises(ConfigError, match="fps: --fps"):
        OutputOptions.from_args(_parse("--no-animation", "--mcap", "a.mcap", "--fps", "20"))
    with pytest.raises(ConfigError, match="stride: --stride sets how often"):
        OutputOptions.from_args(_parse("--stride", "2", animation_default=False))
    only_mcap = OutputOptions.from_args(
        _parse("--no-animation", "--mcap", "a.mcap", "--stride", "2")
    )
    assert only_mcap.stride == 2 and only_mcap.snapshot_every == 2


def test_mp4_without_ffmpeg_fails_before_any_work(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("ceamcl.viz.animation.shutil.which", lambda name: None)
    with pytest.raises(ConfigError, match="ffmpeg"):
        OutputOptions.from_args(_parse("--mp4"))


def test_mcap_into_a_missing_folder_fails_before_any_work(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        OutputOptions.from_args(_parse("--mcap", str(tmp_path / "nope" / "run.mcap")))
    with pytest.raises(ConfigError, match="is a folder"):
        OutputOptions.from_args(_parse("--mcap", str(tmp_path)))


def test_options_check_their_values() -> None:
    with pytest.raises(ConfigError, match="stride"):
        OutputOptions(stride=0)
    with pytest.raises(ConfigError, match="fps"):
        OutputOptions(fps=float("inf"))


def test_write_outputs_writes_what_was_asked(tmp_path: Path) -> None:
    result, grid, log = short_run()
    options = OutputOptions(gif=True, stride=10, report=True, mcap=tmp_path / "x" / "r.mcap")
    (tmp_path / "x").mkdir()
    files = write_outputs(result, grid, tmp_path, options, log=log, summary={"seed": 7})
    assert files == [tmp_path / "run.gif", tmp_path / "report.html", tmp_path / "x" / "r.mcap"]
    assert all(f.stat().st_size > 0 for f in files)
    assert write_outputs(result, grid, tmp_path / "nothing", OutputOptions.none()) == []
    assert not (tmp_path / "nothing").exists()


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``ceamcl demo --report --mcap run.mcap`` in a fresh folder, as the issue checks it."""
    cwd = tmp_path_factory.mktemp("demo-cwd")
    old = Path.cwd()
    os.chdir(cwd)
    try:
        assert main(["demo", "--report", "--mcap", "run.mcap", "--quiet", "--stride", "10"]) == 0
    finally:
        os.chdir(old)
    return cwd


def test_demo_writes_species_in_long_format(demo_run: Path) -> None:
    """CEAMCL's species go to species.csv, one row per step and species; per step their sizes
    add up to the sample size in diagnostics.csv, whose width stays small."""
    out = demo_run / "demo-out"
    with (out / "diagnostics.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows[0]) < 30
    with (out / "species.csv").open(newline="") as fh:
        species = list(csv.DictReader(fh))
    size: dict[int, int] = {}
    count: dict[int, int] = {}
    for s in species:
        k = int(s["step"])
        size[k] = size.get(k, 0) + int(s["n"])
        count[k] = count.get(k, 0) + 1
    assert size == {int(r["step"]): int(r["n_particles"]) for r in rows}
    assert count == {int(r["step"]): int(r["n_species"]) for r in rows}


def test_demo_writes_gif_report_and_mcap(demo_run: Path) -> None:
    out = demo_run / "demo-out"
    with Image.open(out / "run.gif") as im:
        assert im.n_frames > 10
    text = (out / "report.html").read_text(encoding="utf-8")
    assert 'id="replay"' in text and "https://" not in text
    with (demo_run / "run.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    topics = {c.topic for c in summary.channels.values()}
    assert topics == {"/map", "/particles", "/estimate", "/ground_truth", "/scan", "/tf", "/state"}
    assert not list(demo_run.rglob("*.tmp*"))


def test_demo_parser_has_the_output_flags() -> None:
    parser = build_parser()
    assert parser.parse_args(["demo"]).gif is True  # the demo animates by default
    args = parser.parse_args(["demo", "--no-animation", "--mcap", "a.mcap", "--fps", "5"])
    assert (args.gif, args.mcap, args.fps, args.report) == (False, "a.mcap", 5.0, False)


def test_demo_mp4_without_ffmpeg_is_a_one_line_error(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    monkeypatch.setattr("ceamcl.viz.animation.shutil.which", lambda name: None)
    assert main(["demo", "--mp4", "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ceamcl: error: mp4:") and "ffmpeg" in err
    assert not (tmp_path / "o").exists()  # failed before the run


def test_run_files_and_outputs_create_their_folder(tmp_path: Path) -> None:
    """docs/outputs.md and docs/architecture.md call write_outputs / write_run_files with a
    folder that does not exist yet: both failed with FileNotFoundError (the animation after
    rendering every frame). They create it, with its parents."""
    from ceamcl.outputs import write_run_files

    result, grid, log = short_run()
    visual = tmp_path / "a" / "b"
    files = write_outputs(result, grid, visual, OutputOptions(gif=False, report=True), log=log)
    assert files == [visual / "report.html"] and files[0].stat().st_size > 0
    run = tmp_path / "c" / "d"
    write_run_files(result, grid, run, {"seed": 7}, title="t", log=log)
    assert {p.name for p in run.iterdir()} >= {"trajectory.tum", "diagnostics.csv", "summary.json"}


def test_a_failing_command_keeps_a_folder_a_library_call_created(tmp_path: Path) -> None:
    """The library's writers create their folder as the CLI's do, and a command that fails
    removes the folders it created: not one made by a library call before it."""
    from ceamcl.io.results import ensure_output_dir

    made = ensure_output_dir(tmp_path / "library" / "out")
    assert main(["world", "symmetric-hall"]) == 2  # fails: no output given
    assert made.is_dir()
