"""``ceamcl bench --real-maps``: composite maps, the absent-data error, and a quick run on the
real logs of ``../shared/data`` (skipped, saying why, where they are absent)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ceamcl.bench.real_maps import (
    GAP_CELLS,
    RealMapsSettings,
    evaluate_targets,
    mirrored,
    side_by_side,
)
from ceamcl.cli import main
from ceamcl.maps.grid import UNKNOWN
from ceamcl.maps.worlds import get_world

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def test_side_by_side_keeps_every_part_and_adds_their_free_area() -> None:
    a, b = get_world("small-office"), get_world("symmetric-hall")
    both = side_by_side([a, b, mirrored(a)], 2, "composite")
    assert both.free_area_m2 == pytest.approx(2 * a.free_area_m2 + b.free_area_m2)
    bh, bw = max(a.height, b.height) + GAP_CELLS, max(a.width, b.width) + GAP_CELLS
    assert both.data.shape == (2 * bh, 2 * bw)
    np.testing.assert_array_equal(both.data[: a.height, : a.width], a.data)
    np.testing.assert_array_equal(both.data[: b.height, bw : bw + b.width], b.data)
    np.testing.assert_array_equal(both.data[bh : bh + a.height, : a.width], a.data[:, ::-1])
    assert np.all(both.data[bh:, bw:] == UNKNOWN)  # the empty fourth block
    assert np.all(both.data[bh - GAP_CELLS : bh, :] == UNKNOWN)  # the gap between the rows


def test_targets_read_the_maps_nearest_1000_and_4000_m2() -> None:
    result = {
        "settings": {"quick": False},
        "maps": [
            {"free_area_m2": 525.0, "ceamcl": {"first_s": 0.3}},
            {"free_area_m2": 1015.0, "ceamcl": {"first_s": 0.9}},
            {"free_area_m2": 3907.0, "ceamcl": {"first_s": 3.2}},
        ],
        "steps": [
            {
                "log": "a",
                "mode": "global",
                "pace": "p",
                "algorithm": "ceamcl",
                "median_update_ms": 1.2,
                "median_update_state_ms": 1.3,
            },
            {
                "log": "a",
                "mode": "global",
                "pace": "p",
                "algorithm": "mcl-tuned",
                "median_update_ms": 1.5,
                "median_update_state_ms": 2.6,
            },
            {
                "log": "a",
                "mode": "global",
                "pace": "every scan",
                "algorithm": "ceamcl",
                "median_update_ms": 9,
            },
        ],
    }
    got = {t["key"]: (t["value"], t["pass"]) for t in evaluate_targets(result)}
    assert got["init_1000"] == (0.9, True)
    assert got["init_4000"] == (3.2, False)
    assert got["step_ms"] == (1.2, True)  # the every-scan run is not the paced target
    assert got["step_vs_mcl"][0] == pytest.approx(0.8)
    assert got["step_state_vs_mcl"][0] == pytest.approx(0.5)
    assert got["step_state_vs_mcl"][1] is True
    result["settings"]["quick"] = True
    assert all(t["pass"] is None for t in evaluate_targets(result))


def test_absent_data_is_a_clear_error_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "bench"
    args = ["bench", "--real-maps", "--quick", "--quiet", "--data", str(tmp_path / "none")]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "carmen-raw/intel.clf.gz" in err and "--data" in err
    assert not out.exists()
    assert main(["bench", "--quick", "--data", str(tmp_path), "--out", str(out)]) == 2


def test_quick_run_on_the_real_logs(tmp_path: Path) -> None:
    settings = RealMapsSettings.quick_run(DATA)
    if settings.missing():
        pytest.skip(f"real logs absent: {settings.missing()[0]} (the shared data is not mounted)")
    out = tmp_path / "bench"
    args = ["bench", "--real-maps", "--quick", "--quiet", "--data", str(DATA), "--out", str(out)]
    assert main(args) == 0
    r = json.loads((out / "real_maps.json").read_text())
    (fhw,) = r["maps"]
    assert fhw["map"] == "fhw" and 900 < fhw["free_area_m2"] < 1100
    for algo in ("ceamcl", "mcl-tuned"):
        assert fhw[algo]["first_s"] > 0 and fhw[algo]["particles"] > 0
    modes = {(s["mode"], s["pace"] == "every scan", s["algorithm"]) for s in r["steps"]}
    assert ("global", False, "ceamcl") in modes and ("tracking", True, "mcl-tuned") in modes
    for s in r["steps"]:
        assert s["scans"] == settings.scans
        every = s["pace"] == "every scan"
        assert s["updates"] == s["scans"] - 1 if every else 0 < s["updates"] < s["scans"] - 1
        assert s["median_update_ms"] > 0 and np.isfinite(s["ape_rmse_m"])
        # the quick window (intel raw's first scans) has no doubtful truth: the same figure
        assert s["ape_rmse_outside_doubtful_m"] == s["ape_rmse_m"]
        # reading the state after an update costs something, and is not in the update
        assert s["median_update_state_ms"] > s["median_update_ms"]
        if s["mode"] == "tracking" and s["algorithm"] != "ceamcl":
            # the peers run with CEAMCL's mean sample size of the same run
            ours = next(
                o
                for o in r["steps"]
                if o["mode"] == "tracking" and o["pace"] == s["pace"] and o["algorithm"] == "ceamcl"
            )
            assert s["particle_budget"] == round(ours["mean_particles"])
            assert s["mean_particles"] == s["particle_budget"]
    assert all(t["pass"] is None for t in r["targets"])  # a quick run is no target
    md = (out / "real_maps.md").read_text()
    assert "## Global initialisation against map area" in md and "| fhw |" in md
    assert (out / "real_maps.png").stat().st_size > 10_000
