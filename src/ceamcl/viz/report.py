"""``report.html``: one self-contained page with a run's summary, figures and a replay.

Everything is inside the file: the figures are base64 PNGs, the run is JSON, the replay is
plain JavaScript drawing on a ``<canvas>`` (slider, play/pause, step counter, particles coloured
by species, living domains, truth and estimate, a live chart of sample size and resources).
It loads nothing from the network and opens from disk in any browser.

Particles are subsampled per frame (evenly, deterministically) to at most ``max_particles`` so
the file stays at a few MB for long runs.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import os
import tempfile
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from string import Template
from typing import Any

import numpy as np
from PIL import Image

from ceamcl.filters.ceamcl.records import species_of
from ceamcl.io.results import atomic_write
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult
from ceamcl.viz.animation import SPECIES_COLOURS, replay_frames, series
from ceamcl.viz.plots import plot_run, plot_species
from ceamcl.viz.state import plot_state_run

_TEMPLATE = "report_template.html"


def _round(values: Any, digits: int = 3) -> Any:
    return np.round(np.asarray(values, dtype=np.float64), digits).tolist()


def _poses_or_null(poses: Any, digits: int = 3) -> list[list[float] | None]:
    """Each pose rounded, ``None`` where it is not finite (no truth at that scan)."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    rows: list[list[float]] = _round(p, digits)
    return [r if all(math.isfinite(v) for v in r) else None for r in rows]


def _nullable(values: Any, digits: int = 3) -> list[float | None]:
    return [None if not math.isfinite(v) else round(float(v), digits) for v in values]


def map_png(grid: OccupancyGrid) -> bytes:
    """The grid as a greyscale PNG, top row = highest y (free white, occupied black,
    unknown grey)."""
    img = np.full(grid.data.shape, 255, dtype=np.uint8)
    img[grid.unknown_mask] = 190
    img[grid.occupied_mask] = 0
    buf = io.BytesIO()
    Image.fromarray(img[::-1]).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def replay_data(
    result: RunResult,
    grid: OccupancyGrid,
    *,
    stride: int = 5,
    fps: float = 10.0,
    max_particles: int = 600,
) -> dict[str, Any]:
    """The JSON the page's replay draws from."""
    n, r = series(result)
    frames = []
    for fr in replay_frames(result, stride):
        poses, labels = fr.particles.poses, fr.particles.labels
        if poses.shape[0] > max_particles:
            keep = np.linspace(0, poses.shape[0] - 1, max_particles).round().astype(np.intp)
            poses, labels = poses[keep], labels[keep]
        frames.append(
            {
                "step": fr.step,
                "t": round(fr.time, 3),
                "n": int(fr.particles.poses.shape[0]),
                "species": int(np.unique(fr.particles.labels).size),
                "p": _round(poses[:, :3].reshape(-1)),
                "l": np.asarray(labels, dtype=np.int64).tolist(),
                "e": [[int(e[0]), *_round(e[1:], 4)] for e in fr.ellipses],
            }
        )
    has_species = any(species_of(d) for d in result.diagnostics)
    return {
        "fps": float(fps),
        "colours": list(SPECIES_COLOURS),
        "label_name": "species" if has_species else "cluster",
        "map": {
            "png": base64.b64encode(map_png(grid)).decode("ascii"),
            "origin": list(grid.origin),
            "resolution": grid.resolution,
            "width": grid.width,
            "height": grid.height,
            "bounds": list(grid.bounds),
        },
        "times": _round(result.times - result.times[0], 3),  # since the first step, as "t"
        # a raw log's truth is known at its paired scans only: null elsewhere (NaN is no JSON)
        "truth": None if result.truth is None else _poses_or_null(result.truth, 3),
        "estimates": _round(result.estimates, 3),
        "n": n.astype(int).tolist(),
        "resources": _nullable(r, 1) if np.any(np.isfinite(r)) else None,
        "frames": frames,
    }


def _format(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return "-" if value is None else str(value).lower()
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else "-"
    return str(value)


def summary_html(summary: Mapping[str, Any]) -> str:
    """The summary as HTML tables: scalars, then the final hypotheses."""
    rows = []
    for key, value in summary.items():
        if isinstance(value, list | tuple | dict):
            continue
        cls = ' class="num"' if isinstance(value, int | float) else ""
        rows.append(
            f"<tr><th>{html.escape(str(key))}</th><td{cls}>{html.escape(_format(value))}</td></tr>"
        )
    out = f'<table id="summary">{"".join(rows)}</table>'
    hyps = summary.get("hypotheses_final")
    if isinstance(hyps, list) and hyps and isinstance(hyps[0], Mapping):
        cols = list(hyps[0].keys())
        head = "".join(f"<th>{html.escape(str(c))}</th>" for c in cols)
        body = "".join(
            "<tr>"
            + "".join(f'<td class="num">{html.escape(_format(h.get(c)))}</td>' for c in cols)
            + "</tr>"
            for h in hyps
        )
        out += f"<h2>Final hypotheses</h2><table><tr>{head}</tr>{body}</table>"
    return out


def default_summary(result: RunResult) -> dict[str, Any]:
    """What a report shows when the caller has no summary of its own."""
    out: dict[str, Any] = {
        "algorithm": result.algorithm,
        "steps": result.steps,
        "duration_s": float(result.times[-1] - result.times[0]),
        "samples_initial": int(result.diagnostics[0].n_particles),
        "samples_final": int(result.diagnostics[-1].n_particles),
    }
    pos, head = result.position_errors, result.heading_errors
    if pos is not None and head is not None:
        out["final_position_error_m"] = float(pos[-1])
        out["final_heading_error_rad"] = float(head[-1])
    return out


def _png_b64(path: Path) -> str:
    return base64.b64encode(path.read_bytes()).decode("ascii")


def figures_html(result: RunResult, grid: OccupancyGrid, title: str) -> str:
    """``run.png`` and (with species) ``species.png``, rendered afresh and embedded."""
    parts = []
    with tempfile.TemporaryDirectory(prefix="ceamcl-report-") as tmp:
        run_png = plot_run(result, grid, Path(tmp) / "run.png", title=title)
        parts.append(
            (
                "run",
                run_png,
                "Map, tracks of the living species, final particles and hypotheses, true path.",
            )
        )
        if any(st is not None for st in result.states):
            parts.append(
                (
                    "state",
                    plot_state_run(result, Path(tmp) / "state.png", title=f"{title}: state"),
                    "The localisation state the filter reported at each step (green LOCALISED, "
                    "orange AMBIGUOUS, red LOST, grey INITIALISING) and its confidence, "
                    "beneath the true position error.",
                )
            )
        if any(species_of(d) for d in result.diagnostics):
            sp = plot_species(result, Path(tmp) / "species.png", title=f"{title}: species")
            parts.append(
                (
                    "species",
                    sp,
                    "Sample size, resources and species sizes over time (the paper's Fig. 6).",
                )
            )
        return "".join(
            f'<figure id="fig-{name}"><img alt="{name}" src="data:image/png;base64,'
            f'{_png_b64(p)}"><figcaption>{html.escape(caption)}</figcaption></figure>'
            for name, p, caption in parts
        )


def render_report(
    result: RunResult,
    grid: OccupancyGrid,
    *,
    summary: Mapping[str, Any] | None = None,
    title: str = "",
    stride: int = 5,
    fps: float = 10.0,
    max_particles: int = 600,
) -> str:
    """The report's HTML text."""
    title = title or f"{result.algorithm} on {grid.name}"
    template = Template(resources.files("ceamcl.viz").joinpath(_TEMPLATE).read_text("utf-8"))
    data = replay_data(result, grid, stride=stride, fps=fps, max_particles=max_particles)
    # "</" inside a <script> would end it; JSON allows "\/" for "/".
    data_json = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    summ = dict(summary) if summary is not None else default_summary(result)
    subtitle = (
        f"{result.steps} steps, {float(result.times[-1] - result.times[0]):.1f} s, "
        f"{len(data['frames'])} replay frames (every {stride} steps)"
    )
    return template.substitute(
        title=html.escape(title),
        subtitle=html.escape(subtitle),
        summary_html=summary_html(summ),
        figures_html=figures_html(result, grid, title),
        data_json=data_json,
    )


def write_report(
    path: str | os.PathLike[str],
    result: RunResult,
    grid: OccupancyGrid,
    *,
    summary: Mapping[str, Any] | None = None,
    title: str = "",
    stride: int = 5,
    fps: float = 10.0,
    max_particles: int = 600,
) -> Path:
    """Write ``report.html`` (atomically: a temporary file, then a rename)."""
    text = render_report(
        result,
        grid,
        summary=summary,
        title=title,
        stride=stride,
        fps=fps,
        max_particles=max_particles,
    )
    with atomic_write(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
