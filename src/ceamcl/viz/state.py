"""The localisation state drawn as a coloured band over time (run.png, report.html, the state
experiment's figure): green LOCALISED, orange AMBIGUOUS, red LOST, grey INITIALISING."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Patch
from numpy.typing import ArrayLike

from ceamcl.filters.state import DEFAULT_THRESHOLDS, STATES, LocalisationState, State

if TYPE_CHECKING:
    from ceamcl.runner import RunResult

#: One colour per state (colour-blind-safe enough: they also differ in lightness).
STATE_COLOURS: dict[State, str] = {
    State.LOCALISED: "#2ca02c",
    State.AMBIGUOUS: "#ff9f1c",
    State.LOST: "#d62728",
    State.INITIALISING: "#9e9e9e",
}


def state_codes(states: Sequence[LocalisationState | None]) -> np.ndarray:
    """Index into :data:`~ceamcl.filters.state.STATES` per step (-1: unknown)."""
    return np.array(
        [STATES.index(s.state) if s is not None else -1 for s in states], dtype=np.int64
    )


def draw_state_band(ax: Axes, times: ArrayLike, codes: ArrayLike, y0: float, y1: float) -> None:
    """Fill ``[y0, y1]`` of ``ax`` with the colour of the state at each time (``codes``:
    indices into ``STATES``, -1 left blank); one rectangle per run of equal states."""
    t = np.asarray(times, dtype=np.float64)
    c = np.asarray(codes, dtype=np.int64)
    if t.size == 0:
        return
    edges = np.append(t, t[-1] + (t[-1] - t[-2] if t.size > 1 else 1.0))
    start = 0
    for k in range(1, c.size + 1):
        if k == c.size or c[k] != c[start]:
            if c[start] >= 0:
                colour = STATE_COLOURS[STATES[int(c[start])]]
                ax.fill_between([edges[start], edges[k]], y0, y1, color=colour, lw=0, step="pre")
            start = k


def state_legend(ax: Axes, **kwargs: Any) -> None:
    """A legend of the state colours."""
    handles = [Patch(color=STATE_COLOURS[s], label=s.name) for s in STATES]
    ax.legend(handles=handles, **kwargs)


def plot_state_run(result: RunResult, path: str | os.PathLike[str], title: str = "") -> Path:
    """``state.png`` of a run: the position error of the estimate over time (when the truth is
    known) above the band of the state the filter reported, its confidence (solid) and the
    share of the scan's end points the map explains at the leading hypothesis (dashed, where
    judged; the dotted line is where the state stops trusting the map)."""
    import matplotlib.pyplot as plt

    t = result.times - result.times[0]
    codes = state_codes(result.states)
    conf = np.array([np.nan if s is None else s.confidence for s in result.states])
    share = np.array([np.nan if s is None else s.map_explained for s in result.states])
    fig, (ax_e, ax_s) = plt.subplots(
        2, 1, figsize=(8, 3.6), sharex=True, gridspec_kw={"height_ratios": (3, 1)}
    )
    err = result.position_errors
    if err is not None:
        ax_e.plot(t, np.maximum(err, 1e-3), color="k", lw=1)
        ax_e.axhline(0.5, color="k", ls=":", lw=0.8)
        ax_e.set_yscale("log")
        ax_e.set_ylabel("position error (m)")
    else:
        ax_e.text(0.5, 0.5, "no ground truth", ha="center", transform=ax_e.transAxes)
    ax_e.grid(alpha=0.3)
    ax_e.set_title(title or f"{result.algorithm}: localisation state", fontsize=10)
    draw_state_band(ax_s, t, codes, 0.0, 1.0)
    ax_s.plot(t, conf, color="k", lw=0.8, label="confidence")
    judged = np.isfinite(share)
    if judged.any():
        ax_s.plot(t[judged], share[judged], color="#1f4e9c", lw=0.8, ls="--", label="map explains")
        ax_s.axhline(DEFAULT_THRESHOLDS.explained_below, color="#1f4e9c", ls=":", lw=0.6)
        ax_s.legend(fontsize=6, loc="lower left", ncol=2, framealpha=0.6)
    ax_s.set_ylim(0.0, 1.0)
    ax_s.set_ylabel("confidence", fontsize=8)
    ax_s.set_xlabel("time (s)")
    state_legend(ax_e, fontsize=7, loc="upper right", ncol=4)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
