"""What the source distribution holds (MANIFEST.in on top of setuptools' defaults) and the
licence it ships."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_licence_is_mit() -> None:
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License\n")
    assert "Copyright (c) 2026 the ceamcl developers" in text


def test_the_sdist_holds_the_docs_and_ros_and_no_fragment_of_the_tests(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The sdist held only the top-level tests/test_*.py (setuptools' default), which cannot
    run without conftest.py and the helper modules, and no docs/, ros/ or licence. MANIFEST.in,
    applied here to that default as setuptools' sdist applies it, leaves the tests out and
    brings the rest in (``python -m build --sdist`` gives the same list)."""
    egg_info = pytest.importorskip("setuptools.command.egg_info")
    monkeypatch.chdir(ROOT)
    files = egg_info.FileList()
    files.extend(str(p.relative_to(ROOT)) for p in ROOT.glob("tests/test*.py"))
    for line in (ROOT / "MANIFEST.in").read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            files.process_template_line(line)
    held = set(files.files)
    assert not [f for f in held if f.startswith("tests")]
    assert {
        "README.md",
        "LICENSE",
        "docs/ros.md",
        "docs/img/frame.png",
        "ros/build-tf2-msgs.sh",
        "ros/tf2_msgs/CMakeLists.txt",
        "ros/tf2_msgs/package.xml",
        "ros/tf2_msgs/msg/TFMessage.msg",
    } <= held
    assert not [f for f in held if "__pycache__" in f]


def test_the_licence_is_declared_as_an_spdx_expression() -> None:
    """``license = { text = "MIT" }`` made every build warn that the table is deprecated (an
    error from 2027-02-18); the SPDX string with ``license-files`` needs setuptools >= 77."""
    import tomllib

    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert meta["project"]["license"] == "MIT"
    assert meta["project"]["license-files"] == ["LICENSE"]
    assert "setuptools>=77" in meta["build-system"]["requires"]
