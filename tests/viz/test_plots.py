"""``run.png`` and ``species.png`` on runs with many species: what is drawn."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image

from ceamcl.filters.base import StepDiagnostics
from ceamcl.filters.ceamcl.records import CEAMCLRecord, SpeciesRecord
from ceamcl.viz.plots import plot_run, plot_species, species_lives
from tests.viz.runs import short_run


def _step(k: int, ids: list[int], *, restart: bool = False) -> StepDiagnostics:
    species = tuple(
        SpeciesRecord(i, 5, 0.0, 0.5, 1.0, 1.0, 1.0, float(k), float(i), 0.0) for i in ids
    )
    record = CEAMCLRecord(reinitialised=restart, species=species, n_species=len(ids))
    return StepDiagnostics(k, 5 * len(ids), 1.0, 1.0, record)


def test_a_life_ends_at_a_restart_even_when_the_id_comes_back() -> None:
    result, _, _ = short_run("ceamcl")
    # id 0 lives at steps 0-3; the filter restarts at step 4 and numbers from 0 again;
    # id 1 dies at step 2 (missing at step 2) and an unrelated id 1 appears at step 3.
    steps = [
        _step(0, [0, 1]),
        _step(1, [0, 1]),
        _step(2, [0]),
        _step(3, [0, 1]),
        _step(4, [0], restart=True),
        _step(5, [0]),
    ]
    lives = species_lives(replace(result, diagnostics=steps))
    assert [(life.species_id, life.steps.tolist()) for life in lives] == [
        (0, [0, 1, 2, 3]),
        (1, [0, 1]),
        (1, [3]),
        (0, [4, 5]),
    ]
    living = [life for life in lives if life.steps[-1] == 5]
    assert [life.species_id for life in living] == [0]
    np.testing.assert_array_equal(living[0].xy, [[4.0, 0.0], [5.0, 0.0]])


def test_figures_of_a_run_with_thousands_of_species(tmp_path: Path) -> None:
    result, grid, _ = short_run("ceamcl")
    n = result.steps
    # 50 fresh species per step: thousands in all, as on a real log.
    steps = [_step(k, list(range(50 * k, 50 * k + 50))) for k in range(n)]
    many = replace(result, diagnostics=steps)
    assert len(species_lives(many)) == 50 * n
    for png in (plot_run(many, grid, tmp_path / "run.png"), plot_species(many, tmp_path / "s.png")):
        with Image.open(png) as img:
            assert img.format == "PNG" and min(img.size) > 500
