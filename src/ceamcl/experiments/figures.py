"""Figures of the experiments (matplotlib, Agg). Each takes numbers already measured
(:class:`~ceamcl.experiments.common.Curve` and summaries), so measurement is tested apart."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes

from ceamcl.experiments.common import Curve
from ceamcl.experiments.metrics import POSITION_TOL_M
from ceamcl.filters import registry
from ceamcl.io.results import atomic_write

if TYPE_CHECKING:
    from ceamcl.experiments.evaluate_log import Evaluation


def _save(fig: plt.Figure, path: str | os.PathLike[str]) -> Path:
    """The figure to ``path`` through a temporary file, removed if interrupted."""
    out = Path(path)
    try:
        fig.tight_layout()
        with atomic_write(out, keep_suffix=True) as tmp:
            fig.savefig(tmp, dpi=110)
    finally:
        plt.close(fig)
    return out


def algorithm_colour(name: str, fallback: int = 0) -> str:
    """The colour an algorithm has in every figure: by its place in the registry, whatever
    order ``--algorithms`` listed it in (CEAMCL was blue in one panel of fig6 and orange in
    the other); a label that is no algorithm takes the ``fallback`` index."""
    names = registry.names()
    return f"C{(names.index(name) if name in names else fallback) % 10}"


def _draw(ax: Axes, curves: Sequence[Curve], *, band: bool = True) -> None:
    for i, c in enumerate(curves):
        colour = algorithm_colour(c.label, i)
        (line,) = ax.plot(c.times, c.centre, label=c.label, lw=1.4, color=colour)
        if band:
            ax.fill_between(c.times, c.low, c.high, color=line.get_color(), alpha=0.15, lw=0)
    ax.grid(alpha=0.3)
    ax.set_xlabel("time (s)")
    if curves:
        ax.legend(fontsize=8)


def plot_error_over_time(
    estimate: Sequence[Curve], tracking: Sequence[Curve], path: str | os.PathLike[str], title: str
) -> Path:
    """Fig. 4: position error of the estimate, and of the hypothesis nearest the truth."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharex=True)
    _draw(axes[0], estimate)
    axes[0].set_ylabel("position error of the estimate (m)")
    axes[0].set_title("estimate (median, inter-quartile band)", fontsize=9)
    _draw(axes[1], tracking)
    axes[1].set_ylabel("error of the nearest hypothesis (m)")
    axes[1].set_yscale("log")
    axes[1].set_title("nearest hypothesis to the truth", fontsize=9)
    fig.suptitle(title)
    return _save(fig, path)


def plot_step_time(curves: Sequence[Curve], path: str | os.PathLike[str], title: str) -> Path:
    """Fig. 5: computation time per iteration."""
    fig, ax = plt.subplots(figsize=(7, 4))
    _draw(ax, curves)
    ax.set_ylabel("time per step (ms, median over trials)")
    ax.set_yscale("log")
    ax.set_title(title)
    return _save(fig, path)


def plot_resources(
    samples: Sequence[Curve],
    resources: Sequence[Curve],
    path: str | os.PathLike[str],
    title: str,
) -> Path:
    """Fig. 6: total sample size (every algorithm) and CEAMCL's total resources."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharex=True)
    _draw(axes[0], samples)
    axes[0].set_ylabel("total sample size (mean over trials)")
    axes[0].set_yscale("log")
    if samples:  # below the axes: inside, it hid CEAMCL's curve along the bottom
        axes[0].legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=4)
    _draw(axes[1], resources)
    axes[1].set_ylabel("total resources R (mean over trials)")
    fig.suptitle(title)
    return _save(fig, path)


def plot_delta(curves: Sequence[Curve], path: str | os.PathLike[str], title: str) -> Path:
    """Fig. 7: CEAMCL's total sample size over time for several delta."""
    fig, ax = plt.subplots(figsize=(7, 4))
    _draw(ax, curves)
    ax.set_ylabel("total sample size (mean over trials)")
    ax.set_title(title)
    return _save(fig, path)


def plot_shares(
    shares: Mapping[str, Mapping[str, float]],
    path: str | os.PathLike[str],
    title: str,
    ylabel: str,
) -> Path:
    """Grouped bars: ``shares[algorithm][group]`` in [0, 1]."""
    algs = list(shares)
    groups = list(dict.fromkeys(g for a in algs for g in shares[a]))
    fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(groups) * max(1, len(algs)) / 2), 4))
    width = 0.8 / max(1, len(algs))
    for i, alg in enumerate(algs):
        xs = [g + (i - (len(algs) - 1) / 2) * width for g in range(len(groups))]
        ax.bar(xs, [100 * shares[alg].get(g, float("nan")) for g in groups], width, label=alg)
    ax.set_xticks(range(len(groups)), groups)
    ax.set_ylim(0, 105)
    ax.set_ylabel(ylabel)
    ax.grid(axis="y", alpha=0.3)
    if algs:
        ax.legend(fontsize=8)
    else:  # every algorithm asked for lacks a global localisation of its own
        ax.text(0.5, 0.5, "no algorithm to compare", ha="center", transform=ax.transAxes)
    ax.set_title(title)
    return _save(fig, path)


def plot_kidnapped(
    curves: Sequence[Curve],
    kidnap_s: float,
    window_s: float,
    path: str | os.PathLike[str],
    title: str,
) -> Path:
    """Position error over time around the kidnap (median over trials)."""
    fig, ax = plt.subplots(figsize=(8, 4))
    _draw(ax, curves)
    ax.axvline(kidnap_s, color="k", ls="--", lw=1, label="kidnap")
    ax.axvspan(kidnap_s, kidnap_s + window_s, color="grey", alpha=0.1, label="recovery window")
    ax.set_yscale("symlog", linthresh=0.1)
    ax.set_ylim(bottom=0.0)
    ax.set_ylabel("position error of the estimate (m)")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _save(fig, path)


def errors_over_time(
    runs: Sequence[tuple[np.ndarray, np.ndarray]], points: int = 300
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs ``(elapsed_s, errors)`` on one time grid from 0 to the longest run's end: each
    run's error held from its scan until the next, NaN after its own end (windows differ in
    length; cutting every run to the shortest hid the rest). Returns the grid and the
    ``(runs, points)`` errors, with how many runs are still going at each point."""
    end = max((float(t[-1]) for t, _ in runs if t.size), default=0.0)
    grid = np.linspace(0.0, end, points) if end > 0 else np.zeros(1)
    out = np.full((len(runs), grid.size), np.nan)
    for k, (t, e) in enumerate(runs):
        if t.size == 0:
            continue
        at = np.searchsorted(t, grid, side="right") - 1
        inside = (at >= 0) & (grid <= t[-1])
        out[k, inside] = e[at[inside]]
    return grid, out, np.sum(np.isfinite(out), axis=0)


def plot_evaluation(ev: Evaluation, out_dir: Path) -> None:
    """``errors.png``: median and quartiles of the position error over the time since each
    window's start, per algorithm, over the runs whose window lasts that long;
    ``success.png``: success rate per algorithm."""
    algos = [row["algorithm"] for row in ev.table]
    fig, ax = plt.subplots(figsize=(8, 5))
    for i, algo in enumerate(algos):
        rs = [r for r in ev.results if r.algorithm == algo]
        t, err, going = errors_over_time([(r.elapsed_s, r.position_errors) for r in rs])
        live = going > 0  # points where some run of this algorithm is still going
        q1, med, q3 = np.nanpercentile(err[:, live], [25, 50, 75], axis=0)
        ax.plot(t[live], med, color=algorithm_colour(algo, i), label=algo)
        ax.fill_between(t[live], q1, q3, color=algorithm_colour(algo, i), alpha=0.2)
    ax.axhline(POSITION_TOL_M, color="k", ls=":", lw=1, label=f"{POSITION_TOL_M} m")
    ax.set_yscale("log")
    ax.set_xlabel("time since the window's start [s] (runs leave as their windows end)")
    ax.set_ylabel("position error [m] (median, quartiles)")
    ax.legend(fontsize=8)
    _save(fig, out_dir / "errors.png")

    fig, ax = plt.subplots(figsize=(6, 4))
    # an algorithm without a global localisation of its own gets no bar, and says why not
    shown = [registry.localises_globally(a) for a in algos]
    rates = [
        100 * row["success_rate"] if ok else 0.0 for row, ok in zip(ev.table, shown, strict=True)
    ]
    ax.bar(algos, rates, color=[algorithm_colour(a, i) for i, a in enumerate(algos)])
    for i, ok in enumerate(shown):
        if not ok:
            ax.text(
                i, 2, registry.NOT_COMPARABLE, rotation=90, ha="center", va="bottom", fontsize=8
            )
    ax.set_ylim(0, 100)
    ax.set_ylabel("success [%]")
    ax.set_title(f"global localisation from {len(ev.windows)} starts")
    _save(fig, out_dir / "success.png")


def plot_state(
    runs: Sequence[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
    path: str | os.PathLike[str],
) -> Path:
    """One row per run ``(label, times, state codes, position error)``: the position error of
    the estimate over time (log scale), the reported state as a coloured band beneath it."""
    from ceamcl.viz.state import draw_state_band, state_legend

    n = max(len(runs), 1)
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.9 * n + 0.6), squeeze=False, sharex=False)
    for ax, (label, times, codes, errors) in zip(axes[:, 0], runs, strict=False):
        t = np.asarray(times) - float(times[0])
        err = np.maximum(np.asarray(errors), 1e-3)
        draw_state_band(ax, t, codes, 1e-3, 2e-3)
        # a raw log has a true pose at some scans only: join those, not the gaps between them
        known = np.isfinite(err)
        ax.plot(t[known], err[known], color="k", lw=1.0)
        ax.axhline(POSITION_TOL_M, color="k", ls=":", lw=0.8)
        ax.set_yscale("log")
        ax.set_ylim(1e-3, 50.0)
        ax.set_ylabel("error (m)")
        ax.set_title(label, fontsize=9, loc="left")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s); band: the state the filter reports")
    state_legend(axes[0, 0], fontsize=7, loc="upper right", ncol=4)
    return _save(fig, path)
