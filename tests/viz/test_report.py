"""Tests of ``ceamcl.viz.report``: a self-contained ``report.html`` with a working replay.

The browser test opens the page in headless Chromium (Debian's ``/usr/bin/chromium``, driven
by Playwright) and skips with the reason where either is missing.
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

from ceamcl.viz.animation import frame_steps
from ceamcl.viz.report import render_report, write_report
from tests.viz.runs import STEPS, short_run

CHROMIUM = os.environ.get("CEAMCL_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def _embedded_data(text: str) -> dict[str, Any]:
    m = re.search(r'<script id="replay-data" type="application/json">(.*?)</script>', text, re.S)
    assert m is not None
    data: dict[str, Any] = json.loads(m.group(1))
    return data


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    result, grid, _ = short_run()
    summary = {
        "algorithm": "ceamcl",
        "seed": 7,
        "note": "<b>not markup</b>",
        "steps": STEPS,
        "hypotheses_final": [{"x": 1.0, "y": 2.0, "theta": 0.5, "weight": 1.0, "fitness": 0.9}],
    }
    return write_report(
        tmp_path_factory.mktemp("report") / "report.html",
        result,
        grid,
        summary=summary,
        stride=5,
        fps=20.0,
    )


def test_report_loads_nothing_from_the_network(report: Path) -> None:
    text = report.read_text(encoding="utf-8")
    assert "http://" not in text and "https://" not in text
    assert not re.search(r"""(src|href)\s*=\s*["'](?!data:)""", text)
    assert "@import" not in text and "url(" not in text
    assert [p.name for p in report.parent.iterdir()] == ["report.html"]


def test_report_embeds_figures_and_summary(report: Path) -> None:
    text = report.read_text(encoding="utf-8")
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)
    assert len(images) == 3  # run.png, state.png and species.png (CEAMCL has species)
    assert 'id="fig-state"' in text
    for b64 in images:
        assert base64.b64decode(b64).startswith(b"\x89PNG\r\n\x1a\n")
    assert "&lt;b&gt;not markup&lt;/b&gt;" in text and "<b>not markup</b>" not in text
    assert "Final hypotheses" in text


def test_report_data_matches_the_run(report: Path) -> None:
    result, grid, _ = short_run()
    data = _embedded_data(report.read_text(encoding="utf-8"))
    assert [f["step"] for f in data["frames"]] == frame_steps(result, 5)
    assert len(data["times"]) == len(data["estimates"]) == len(data["truth"]) == STEPS
    assert data["fps"] == 20.0
    assert data["map"]["width"] == grid.width and data["map"]["height"] == grid.height
    assert base64.b64decode(data["map"]["png"]).startswith(b"\x89PNG")
    for f in data["frames"]:
        snap = result.snapshots[f["step"]]
        assert f["n"] == snap.poses.shape[0]
        assert len(f["p"]) == 3 * len(f["l"]) and len(f["l"]) == min(f["n"], 600)
        assert set(f["l"]) <= set(snap.labels.tolist())


def test_report_subsamples_particles_and_survives_script_in_titles() -> None:
    result, grid, _ = short_run()
    text = render_report(result, grid, title="</script><script>alert(1)</script>", max_particles=50)
    data = _embedded_data(text)
    assert all(len(f["l"]) <= 50 for f in data["frames"])
    assert any(f["n"] > 50 for f in data["frames"])
    assert "<script>alert(1)" not in text


def test_report_without_species_or_summary() -> None:
    result, grid, _ = short_run("mcl")
    text = render_report(result, grid)
    data = _embedded_data(text)
    assert data["label_name"] == "cluster" and data["resources"] is None
    # run.png and state.png (no species)
    assert len(re.findall(r'src="data:image/png;base64,', text)) == 2
    assert "final_position_error_m" in text


# ------------------------------------------------------------------ the replay in Chromium
def _browser_or_skip() -> Any:
    if not Path(CHROMIUM).exists() and shutil.which("chromium") is None:
        pytest.skip(
            f"Chromium not found at {CHROMIUM} (Debian: apt-get install chromium chromium-driver)"
        )
    playwright = pytest.importorskip(
        "playwright.sync_api", reason="playwright is not installed (pip install -e '.[dev]')"
    )
    return playwright


_CANVAS_STATS = """() => {
  const c = document.getElementById('replay');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  const colours = new Set();
  let notWhite = 0;
  for (let i = 0; i < d.length; i += 4) {
    if (d[i] < 250 || d[i + 1] < 250 || d[i + 2] < 250) notWhite++;
    colours.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]);
  }
  return {notWhite, colours: colours.size, url: c.toDataURL()};
}"""


def test_report_replays_in_headless_chromium(report: Path) -> None:
    sync_api = _browser_or_skip()
    executable = CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium")
    errors: list[str] = []
    requests: list[str] = []
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("request", lambda r: requests.append(r.url))
            page.goto(report.as_uri())
            page.wait_for_function("window.replayState && window.replayState.ready", timeout=15000)
            frames = page.evaluate("window.replayState.frames")
            assert frames == len(frame_steps(short_run()[0], 5))

            first = page.evaluate(_CANVAS_STATS)
            # map walls, particles in several species colours, truth and estimate
            assert first["notWhite"] > 1000
            assert first["colours"] > 5
            label0 = page.inner_text("#step-label")
            assert label0.startswith("step 0 ")

            page.click("#play")
            page.wait_for_function("window.replayState.frame >= 3", timeout=15000)
            moved = page.evaluate(_CANVAS_STATS)
            assert moved["url"] != first["url"]
            assert page.inner_text("#step-label") != label0
            assert int(page.input_value("#slider")) >= 3

            # the slider jumps to a frame and pauses the replay
            page.evaluate(
                "() => { const s = document.getElementById('slider'); s.value = '2';"
                " s.dispatchEvent(new Event('input')); }"
            )
            assert page.evaluate("window.replayState.frame") == 2
            assert page.inner_text("#step-label").startswith("step 10 ")
            assert page.inner_text("#play").strip().endswith("Play")
        finally:
            browser.close()
    assert errors == []
    assert all(u.startswith(("file:", "data:")) for u in requests), requests
