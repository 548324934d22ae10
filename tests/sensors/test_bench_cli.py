"""``ceamcl bench --quick`` writes bench.json and bench.md with every section."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ceamcl.cli import main


def test_bench_quick_writes_both_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench"
    assert main(["bench", "--quick", "--quiet", "--out", str(out)]) == 0
    data = json.loads((out / "bench.json").read_text())
    for key in (
        "machine",
        "peer",
        "jit",
        "filter_update",
        "ceamcl_init",
        "ceamcl_step",
        "scaling",
        "memory_peak_rss_mb",
        "targets",
    ):
        assert key in data, key
    assert data["settings"]["quick"] is True
    assert data["machine"]["cores"] >= 1
    assert {r["sensor"] for r in data["filter_update"]} == {"beam", "likelihood-field"}
    for row in data["filter_update"]:
        assert row["ours"]["ns_per_pb"] > 0
        assert ("nav2" in row) == data["peer"]["available"]
    assert [t["key"] for t in data["targets"]] == [
        "beam_vs_nav2",
        "lf_vs_nav2",
        "init_s",
        "step_ms",
    ]
    # a quick run is no target (its N = 1,000 once passed for the N = 5,000 target)
    assert all(t["pass"] is None for t in data["targets"])
    assert data["targets"][2]["value"] is None  # 1M test poses are not run in a quick bench
    md = (out / "bench.md").read_text()
    assert "## Targets" in md and "ns/pb" in md and data["machine"]["cpu"] in md
    assert "wrote" in capsys.readouterr().out


def test_bench_unwritable_out_is_a_clean_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["bench", "--quick", "--quiet", "--out", str(blocker / "sub")]) == 2
