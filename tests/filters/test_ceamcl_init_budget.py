"""CEAMCL's initialisation grid is sized from the map within the memory budget."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ceamcl import budget
from ceamcl.errors import InputWarning
from ceamcl.filters.ceamcl.initialisation import CELL_BYTES, CellGrid
from ceamcl.maps.grid import FREE, OccupancyGrid
from ceamcl.maps.worlds import get_world


def test_paper_hall_keeps_its_01_m_cells_without_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cells = CellGrid.over(get_world("symmetric-hall"), 0.1)
    assert (cells.cell_m, cells.nx, cells.ny) == (0.1, 150, 150)


def test_a_coarse_large_map_gets_coarser_cells_that_fit_the_budget() -> None:
    grid = OccupancyGrid(np.full((300, 300), FREE, dtype=np.int8), 10.0)  # 3 km x 3 km
    limit = 64 << 20
    with budget.use(budget.Budget(limit)), pytest.warns(InputWarning, match="using .* m cells"):
        cells = CellGrid.over(grid, 0.1)
    assert cells.nx * cells.ny * CELL_BYTES <= limit
    factor = cells.cell_m / 0.1
    assert factor == pytest.approx(round(factor)) and factor > 1  # a multiple of 0.1 m
    # the smallest such multiple: one step finer would not fit
    finer = 0.1 * (round(factor) - 1)
    assert np.ceil(3000 / finer) ** 2 * CELL_BYTES > limit
