"""Figures of runs: the map with paths and particles, and per-step series."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib import patheffects
from numpy.typing import NDArray

from ceamcl.filters.ceamcl.records import SpeciesRecord, species_of
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult
from ceamcl.viz.animation import series
from ceamcl.viz.draw import draw_map

#: ``species.png`` draws at most this many species' sizes (the longest-lived); run.png only
#: the species alive at the end.
MAX_SPECIES_DRAWN = 40


@dataclass(frozen=True)
class SpeciesLife:
    """One species from birth to death: its id, the steps it lived and its records there.
    CEAMCL never reuses an id; a life still ends at a restart of global localisation (and at
    any step it is missing), which keeps this safe for filters that do reuse ids."""

    species_id: int
    steps: NDArray[np.int64]
    records: tuple[SpeciesRecord, ...]

    @property
    def xy(self) -> NDArray[np.float64]:
        return np.array([(r.x, r.y) for r in self.records])


def species_lives(result: RunResult) -> list[SpeciesLife]:
    """Every species of the run (:class:`SpeciesLife`), in order of birth. A scan the update
    pace held back (``stepped`` False) changes no species and ends no life (under a pace every
    life was cut at each such scan and drawn as dots)."""
    open_lives: dict[int, tuple[list[int], list[SpeciesRecord]]] = {}
    done: list[tuple[int, list[int], list[SpeciesRecord]]] = []
    for k, d in enumerate(result.diagnostics):
        if not d.stepped:
            continue
        alive = {s.species_id: s for s in species_of(d)}
        for sid in list(open_lives):
            if d.reinitialised or sid not in alive:
                done.append((sid, *open_lives.pop(sid)))
        for sid, rec in alive.items():
            steps, recs = open_lives.setdefault(sid, ([], []))
            steps.append(k)
            recs.append(rec)
    done += [(sid, *life) for sid, life in open_lives.items()]
    done.sort(key=lambda life: (life[1][0], life[0]))
    return [SpeciesLife(sid, np.array(steps), tuple(recs)) for sid, steps, recs in done]


def plot_run(
    result: RunResult, grid: OccupancyGrid, path: str | os.PathLike[str], title: str = ""
) -> Path:
    """``run.png``: map, final particles coloured by label, the tracks of the species alive at
    the end (not of every species ever created), estimate, final hypotheses, and the true
    path on top; the legend below the map. The figure's height follows the map's shape, and
    the legend has its own strip at the bottom of the figure (below the axes of a wide map it
    covered the x label)."""
    x0, x1, y0, y1 = grid.bounds
    legend_in = 0.9
    map_in = float(np.clip(7.4 * (y1 - y0) / max(x1 - x0, 1e-9), 3.0, 8.0))
    height = map_in + legend_in + 0.9  # and the title and the x label
    fig, ax = plt.subplots(figsize=(8, height))
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
    # the last step the filter ran (a paced run's last scan may have been held back)
    last = max((k for k, d in enumerate(result.diagnostics) if d.stepped), default=0)
    living = [life for life in species_lives(result) if life.steps[-1] == last]
    if any(species_of(d) for d in result.diagnostics):
        # With species, the estimate (the fittest species) can hop between equally fit
        # symmetric hypotheses; each living species' own track reads better than one line.
        cmap = plt.get_cmap("tab10")
        for life in living:
            xy = life.xy
            ax.plot(xy[:, 0], xy[:, 1], "-", lw=1, color=cmap(life.species_id % 10), zorder=3)
        ax.plot(
            [],
            [],
            "-",
            color="gray",
            lw=1,
            label=f"species alive at the end ({len(living)}): tracks",
        )
        ax.plot(
            result.estimates[:, 0],
            result.estimates[:, 1],
            "r.",
            ms=2,
            alpha=0.5,
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
    ax.plot(*result.estimates[-1, :2], "rx", ms=10, mew=2, label="estimate (final)", zorder=6)
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
            zorder=4,
        )
    if result.truth is not None and result.truth_known.any():
        # On top of everything, with a white edge so it stays visible over the tracks; a raw
        # log has truth at its matched scans only.
        truth = result.truth[result.truth_known]
        edge = [patheffects.Stroke(linewidth=3.5, foreground="white"), patheffects.Normal()]
        ax.plot(
            truth[:, 0],
            truth[:, 1],
            "g-",
            lw=1.8,
            label="ground truth",
            zorder=7,
            path_effects=edge,
        )
        ax.plot(*truth[-1, :2], "go", ms=8, mec="white", label="truth (final)", zorder=8)
    handles, names = ax.get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=3, fontsize=8, frameon=False)
    ax.set_title(title or f"{result.algorithm}: {result.steps} steps")
    fig.tight_layout(rect=(0.0, legend_in / height, 1.0, 1.0))
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_species(result: RunResult, path: str | os.PathLike[str], title: str = "") -> Path:
    """``species.png`` (the paper's Fig. 6): total sample size and total resources over time,
    and the size of each species that lived long (at most :data:`MAX_SPECIES_DRAWN`, the
    longest-lived; the rest are counted in the panel's title), broken at restarts. Time is
    seconds since the first step (a real log's clock is its epoch, 9.76e8 s on intel)."""
    t = result.times - result.times[0]
    total_n, total_r = series(result)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    ax1.plot(t, total_n, "k-", lw=2, label="total sample size")
    ax1.plot(t, total_r, "g--", lw=2, label="total resources R")
    restarts = [t[d.step] for d in result.diagnostics[1:] if d.reinitialised]
    for i, when in enumerate(restarts):
        for ax in (ax1, ax2):
            ax.axvline(
                when, color="r", lw=0.8, ls=":", label="restart" if i == 0 and ax is ax1 else None
            )
    ax1.set_ylabel("samples / resources")
    ax1.legend(loc="upper right", fontsize=8)
    ax1.grid(alpha=0.3)
    lives = species_lives(result)
    drawn = sorted(lives, key=lambda life: -life.steps.size)[:MAX_SPECIES_DRAWN]
    cmap = plt.get_cmap("tab10")
    for life in sorted(drawn, key=lambda life: life.steps[0]):
        ax2.plot(
            t[life.steps],
            [r.n for r in life.records],
            lw=1.2,
            color=cmap(life.species_id % 10),
            label=f"species {life.species_id}" if len(lives) <= 12 else None,
        )
    ax2.set_xlabel("time since the first step [s]")
    ax2.set_ylabel("samples per species")
    ax2.grid(alpha=0.3)
    if len(drawn) < len(lives):
        ax2.set_title(f"the {len(drawn)} longest-lived of {len(lives)} species", fontsize=9)
    if 0 < len(lives) <= 12:
        ax2.legend(loc="upper right", fontsize=7, ncol=2)
    ax1.set_title(title or f"{result.algorithm}: sample size and resources")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
