"""Soak: the looping simulated drive, the report, and (slow) the 100,000-step run."""

from __future__ import annotations

import json
import os
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.errors import CeamclError
from ceamcl.maps.worlds import get_world
from ceamcl.soak import SOAK_WORLDS, SimulatedStream, SoakConfig, loop_route, run_soak


@pytest.mark.parametrize("world", SOAK_WORLDS)
def test_the_loop_is_closed_and_drivable(world: str) -> None:
    loop = loop_route(world)
    grid = get_world(world)
    step = np.diff(np.vstack([loop, loop[:1]]), axis=0)
    # Consecutive poses (including last -> first) are one simulator step apart at most.
    assert np.hypot(step[:, 0], step[:, 1]).max() <= 0.031
    assert np.abs(np.angle(np.exp(1j * step[:, 2]))).max() <= 0.061
    ix, iy = grid.world_to_cell(loop[:, 0], loop[:, 1])
    assert np.all(grid.free_mask[iy, ix]), "the loop must stay in free space"


def test_the_stream_holds_no_history() -> None:
    """Memory for 3,000 simulated steps is that of a few scans, not of the log."""
    grid = get_world("small-office")
    stream = SimulatedStream(grid, loop_route("small-office"), 3000, np.random.default_rng(0))
    it = iter(stream)
    for _ in range(200):  # warm caches (numba, distance field)
        next(it)
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    count = 200
    for _truth, _odom, scan in it:
        count += 1
        assert np.all(np.isfinite(scan.ranges))
    grown = tracemalloc.get_traced_memory()[0] - base
    tracemalloc.stop()
    assert count == 3000
    one_log_of_scans = 2800 * 181 * 8
    assert grown < one_log_of_scans / 20


def test_short_soak_reports_every_figure(tmp_path: Path) -> None:
    code = main(
        [
            "soak",
            "--steps",
            "300",
            "--algorithm",
            "mcl",
            "--particles",
            "300",
            "--warmup",
            "50",
            "--out",
            str(tmp_path),
            "--quiet",
        ]
    )
    report = json.loads((tmp_path / "soak.json").read_text())
    assert (tmp_path / "soak.png").stat().st_size > 0
    for key in (
        "rss_start_kb",
        "rss_end_kb",
        "growth_pct",
        "steps_per_s",
        "samples_min",
        "samples_max",
        "reinitialisations",
        "passed",
    ):
        assert key in report
    assert report["steps"] == 300 and report["warmup_steps"] == 50
    assert report["samples_min"] == report["samples_max"] == 300
    assert report["samples_within_bounds"] and report["nonfinite_estimates"] == 0
    assert report["rss_start_kb"] > 0 and report["rss_end_kb"] > 0
    assert code == (0 if report["passed"] else 1)
    assert report["series_step"][0] == 0 and report["series_step"][-1] == 299


def test_soak_config_is_checked() -> None:
    for bad in ({"steps": 1}, {"algorithm": "x"}, {"world": "moon"}, {"warmup_steps": 10**6}):
        with pytest.raises(CeamclError):
            SoakConfig(**bad)  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", [os.environ.get("CEAMCL_SOAK_ALGORITHM", "ceamcl")])
def test_soak_100k_steps_flat_memory(algorithm: str) -> None:
    steps = int(os.environ.get("CEAMCL_SOAK_STEPS", "100000"))
    report = run_soak(SoakConfig(steps=steps, algorithm=algorithm))
    assert report.nonfinite_estimates == 0
    assert report.samples_within_bounds, (report.samples_min, report.samples_max)
    assert report.growth_pct < 5.0, report.growth_pct
    assert report.share_within_0_5_m > 0.9  # still localised after all those loops
