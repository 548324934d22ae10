"""Figures of runs: the map with paths and particles, and per-step series."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ceamcl.filters.ceamcl.records import species_of
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult
from ceamcl.viz.animation import series
from ceamcl.viz.draw import draw_map


def plot_run(
    result: RunResult, grid: OccupancyGrid, path: str | os.PathLike[str], title: str = ""
) -> Path:
    """``run.png``: map, true and estimated paths, final particles coloured by label."""
    fig, ax = plt.subplots(figsize=(8, 8))
    draw_map(ax, grid)
    parts = result.final_particles
    if parts.poses.shape[0]:
        labels = parts.labels
        ax.scatter(
            parts.poses[:, 0],
            parts.poses[:, 1],
            s=8,
            c=labels % 10,
            cmap="tab10",
            vmin=0,
            vmax=9,
            alpha=0.6,
            label="particles (final)",
            zorder=2,
        )
    if result.truth is not None and result.truth_known.any():
        truth = result.truth[result.truth_known]  # a raw log has truth at its matched scans
        ax.plot(truth[:, 0], truth[:, 1], "g-", lw=2, label="ground truth", zorder=3)
        ax.plot(*truth[-1, :2], "go", ms=8, zorder=4)
    tracks = _species_tracks(result)
    if tracks:
        # With species, the estimate (the fittest species) can hop between equally fit
        # symmetric hypotheses; each species' own track reads better than one line.
        cmap = plt.get_cmap("tab10")
        for sid, xy in sorted(tracks.items()):
            ax.plot(xy[:, 0], xy[:, 1], "-", lw=1, color=cmap(sid % 10), alpha=0.8, zorder=3)
        ax.plot([], [], "-", color="gray", lw=1, label="species tracks")
        ax.plot(
            result.estimates[:, 0],
            result.estimates[:, 1],
            "r.",
            ms=2,
            alpha=0.6,
            label="estimate (fittest species)",
            zorder=3,
        )
    else:
        ax.plot(
            result.estimates[:, 0],
            result.estimates[:, 1],
            "r-",
            lw=1,
            alpha=0.8,
            label="estimate",
            zorder=3,
        )
    ax.plot(*result.estimates[-1, :2], "rx", ms=10, mew=2, zorder=4)
    hyps = result.hypotheses[-1]
    if hyps.shape[0]:
        ax.quiver(
            hyps[:, 0],
            hyps[:, 1],
            np.cos(hyps[:, 2]),
            np.sin(hyps[:, 2]),
            color="b",
            scale=25,
            width=0.004,
            label="hypotheses (final)",
            zorder=5,
        )
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    ax.set_title(title or f"{result.algorithm}: {result.steps} steps")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _species_tracks(result: RunResult) -> dict[int, np.ndarray]:
    tracks: dict[int, list[tuple[float, float]]] = {}
    for d in result.diagnostics:
        for s in species_of(d):
            tracks.setdefault(s.species_id, []).append((s.x, s.y))
    return {sid: np.asarray(pts) for sid, pts in tracks.items()}


def plot_species(result: RunResult, path: str | os.PathLike[str], title: str = "") -> Path:
    """``species.png`` (the paper's Fig. 6): total sample size and total resources over time,
    and each species' size."""
    t = result.times
    total_n, total_r = series(result)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    ax1.plot(t, total_n, "k-", lw=2, label="total sample size")
    ax1.plot(t, total_r, "g--", lw=2, label="total resources R")
    ax1.set_ylabel("samples / resources")
    ax1.legend(loc="upper right")
    ax1.grid(alpha=0.3)
    sizes: dict[int, list[tuple[float, int]]] = {}
    for time_s, d in zip(t, result.diagnostics, strict=True):
        for s in species_of(d):
            sizes.setdefault(s.species_id, []).append((float(time_s), s.n))
    for sid, pts in sorted(sizes.items()):
        arr = np.array(pts)
        ax2.plot(
            arr[:, 0],
            arr[:, 1],
            lw=1.2,
            color=plt.get_cmap("tab10")(sid % 10),
            label=f"species {sid}" if len(sizes) <= 12 else None,
        )
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("samples per species")
    ax2.grid(alpha=0.3)
    if 0 < len(sizes) <= 12:
        ax2.legend(loc="upper right", fontsize=7, ncol=2)
    ax1.set_title(title or f"{result.algorithm}: sample size and resources")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
