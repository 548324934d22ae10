"""The README's Python examples run as written (given the inputs they name but do not make)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def python_block_after(marker: str) -> str:
    """The first ```python block after the line ``marker`` in the README."""
    text = README.read_text(encoding="utf-8")
    found = re.search(re.escape(marker) + r".*?```python\n(.*?)```", text, re.S)
    assert found, f"README: no python block after {marker!r}"
    return found.group(1)


def test_the_lower_level_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """It used ``np`` without importing numpy (NameError)."""
    from ceamcl.maps.ros_io import save_map
    from ceamcl.simulation import paper_scenario

    scenario = paper_scenario(start_room=0, world="symmetric-hall")
    grid = scenario.grid()
    save_map(grid, tmp_path / "map.yaml")
    log = scenario.simulate(np.random.default_rng(1), grid)
    inputs = {
        "first_scan": log.scan(0),
        "odom_prev": log.odometry[0],
        "odom_now": log.odometry[1],
        "scan": log.scan(1),
    }
    monkeypatch.chdir(tmp_path)
    code = python_block_after("Lower level, each part on its own:")
    namespace: dict[str, object] = dict(inputs)
    exec(compile(code, "README.md", "exec"), namespace)
    pose = namespace["pose"]
    assert isinstance(pose, np.ndarray) and pose.shape == (3,) and np.all(np.isfinite(pose))
