"""Streams sniffed without loss, safe YAML, scan-time checks, ground truth decided by content."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pytest

from ceamcl.errors import ConfigError, LogFormatError
from ceamcl.io import streams
from ceamcl.io.carmen import read_carmen
from ceamcl.io.logs import poses_look_corrected
from ceamcl.io.safe_yaml import load_yaml_text
from ceamcl.io.timestamps import check_times
from tests.robustness.hostile_cases import box_log_lines, flaser


def write(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_pipe_sniffed_then_read_loses_nothing() -> None:
    data = os.urandom(200_000)
    r, w = os.pipe()

    def feed() -> None:
        with os.fdopen(w, "wb") as fh:
            fh.write(data)

    threading.Thread(target=feed).start()
    path = f"/dev/fd/{r}"
    try:
        assert streams.is_stream(path)
        assert streams.sniff(path, 13) == data[:13]
        assert streams.sniff(path, 2) == data[:2]  # the kept buffer, not the pipe
        with streams.open_input(path) as fh:
            assert fh.read() == data
    finally:
        os.close(r)


def test_a_fifo_without_writer_is_refused_after_the_wait(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CEAMCL_STREAM_WAIT_S", "0.2")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(streams.StreamError, match=r"fifo: no data arrived for 0\.2 s"):
        streams.sniff(fifo, 13, "log")


def test_safe_yaml_reads_yaml_12_floats_and_refuses_aliases() -> None:
    doc = load_yaml_text("a: 5e-2\nb: 1E3\nc: .5\nd: 7\ne: '5e-2'\n", "x.yaml")
    assert doc == {"a": 0.05, "b": 1000.0, "c": 0.5, "d": 7, "e": "5e-2"}
    with pytest.raises(ConfigError, match=r"x\.yaml:2: not valid YAML: aliases \(\*a\)"):
        load_yaml_text("a: &a [1]\nb: *a\n", "x.yaml")


def test_safe_yaml_refuses_a_repeated_key_naming_it_and_its_lines() -> None:
    """PyYAML kept the last value of a repeated key silently (yaml-cpp's choice has varied by
    version): a map with 'resolution' twice was read at the second value."""
    text = "image: m.pgm\nresolution: 0.05\nnested:\n  a: 1\n  b: 2\nresolution: 0.5\n"
    with pytest.raises(
        ConfigError,
        match=r"x\.yaml:6: not valid YAML: duplicate key 'resolution' \(first on line 2\)",
    ):
        load_yaml_text(text, "x.yaml")
    with pytest.raises(ConfigError, match=r"x\.yaml:3: .*duplicate key 'a' \(first on line 2\)"):
        load_yaml_text("n:\n  a: 1\n  a: 2\n", "x.yaml")
    with pytest.raises(ConfigError, match=r"x\.yaml:1: .*duplicate key 'a'"):
        load_yaml_text("{a: 1, b: 2, a: 3}\n", "x.yaml")
    # the same name in different mappings is fine, so are keys of different YAML types
    doc = load_yaml_text("a: {x: 1}\nb: {x: 2}\n", "x.yaml")
    assert doc == {"a": {"x": 1}, "b": {"x": 2}}
    load_yaml_text("1: int\n1.0: float\n", "x.yaml")
    # a merge key's entries may be overridden (they are not written twice)
    assert load_yaml_text("<<: {a: 1, b: 2}\na: 3\n", "x.yaml") == {"a": 3, "b": 2}


def test_ground_truth_is_decided_by_content_not_by_name(tmp_path: Path) -> None:
    corrected = read_carmen(write(tmp_path / "plain.log", box_log_lines(5, neff=True)))
    assert poses_look_corrected(corrected)[0]
    raw = read_carmen(write(tmp_path / "x-corrected.log", box_log_lines(5)))
    looks, why = poses_look_corrected(raw)
    assert not looks and "no NEFF" in why
    lines = box_log_lines(5, neff=True)
    lines[1] = lines[1].replace(" 0 0 0 0 0 0 ", " 0 0 0 0.1 0 0 ", 1)  # laser != robot pose
    moved = read_carmen(write(tmp_path / "moved.log", lines))
    assert not np.all(moved.laser_mount == 0)
    assert not poses_look_corrected(moved)[0]


def test_scan_times_jitter_kept_big_step_back_refused_with_its_line_or_repaired(
    tmp_path: Path,
) -> None:
    lines = box_log_lines(6)
    lines[4] = flaser(0.3, "0.1")  # 0.1 s back from 0.2: jitter
    log = read_carmen(write(tmp_path / "jitter.log", lines))
    assert check_times(log) is log
    lines[5] = flaser(0.4, "-5")  # line 6 of the file
    log = read_carmen(write(tmp_path / "back.log", lines))
    with pytest.raises(LogFormatError, match=r"back\.log:6: scan time -5\.000000 s is 5\.200 s"):
        check_times(log)
    fixed = check_times(log, repair=True)
    assert np.all(np.diff(fixed.times) >= 0) and fixed.info["repaired_times"] == 2
    assert fixed.times[4] == pytest.approx(0.2)


def test_a_literal_nan_timestamp_is_refused_with_its_line(tmp_path: Path) -> None:
    lines = box_log_lines(4)
    lines[2] = flaser(0.1, "nan")
    with pytest.raises(LogFormatError, match=r"nan\.log:3: FLASER: timestamp: expected a finite"):
        read_carmen(write(tmp_path / "nan.log", lines))
