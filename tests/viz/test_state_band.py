"""The state band (``ceamcl.viz.state``): one coloured stretch per run of equal states."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import to_hex

from ceamcl.filters.state import State
from ceamcl.viz.state import STATE_COLOURS, draw_state_band, plot_state_run
from tests.viz.runs import short_run


def test_one_stretch_per_run_of_equal_states_in_the_state_colour() -> None:
    fig, ax = plt.subplots()
    codes = np.array([3, 1, 1, 0, 0, 0, 2, -1, -1, 0])  # INIT, AMB x2, LOC x3, LOST, ?, ?, LOC
    draw_state_band(ax, np.arange(10) * 0.1, codes, 0.0, 1.0)
    colours = [to_hex(c.get_facecolor()[0]) for c in ax.collections]
    expected = [State.INITIALISING, State.AMBIGUOUS, State.LOCALISED, State.LOST, State.LOCALISED]
    assert colours == [STATE_COLOURS[s] for s in expected]  # unknown steps stay blank
    plt.close(fig)


def test_state_figure_of_a_run(tmp_path: Path) -> None:
    result, _, _ = short_run()
    out = plot_state_run(result, tmp_path / "state.png")
    assert out.read_bytes().startswith(b"\x89PNG")
