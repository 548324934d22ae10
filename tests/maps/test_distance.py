"""The compiled distance transform against SciPy's, and the likelihood table built from it."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.maps.distance import (
    distance_cells,
    distance_cells_reference,
    squared_distance_cells,
)
from ceamcl.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from ceamcl.maps.worlds import get_world
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel


def random_masks(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Masks of every shape class (single rows and columns, squares, long strips), from
    nearly empty to nearly full, some with a single obstacle in a corner or on an edge."""
    masks = []
    for k in range(n):
        h, w = (int(v) for v in rng.integers(1, 70, size=2))
        if k % 5 == 0:
            h = 1
        elif k % 5 == 1:
            w = 1
        density = float(rng.choice([0.0005, 0.005, 0.05, 0.3, 0.95]))
        m = rng.random((h, w)) < density
        if k % 3 == 0 or not m.any():
            m[:] = False
            m[int(rng.integers(h)), int(rng.integers(w))] = True
        masks.append(m)
    return masks


def test_distances_equal_scipys_to_the_bit() -> None:
    rng = np.random.default_rng(11)
    for m in random_masks(rng, 600):
        ours = distance_cells(m)
        ref = distance_cells_reference(m)
        assert np.array_equal(ours, ref), m.shape
        assert np.all(ours[m] == 0.0)


def test_squared_distances_are_exact_integers() -> None:
    m = np.zeros((7, 9), dtype=bool)
    m[0, 0] = True
    sq = squared_distance_cells(m)
    ii, jj = np.indices(m.shape)
    assert sq.dtype == np.int32
    assert np.array_equal(sq, ii * ii + jj * jj)
    m[6, 8] = True
    sq = squared_distance_cells(m)
    assert np.array_equal(sq, np.minimum(ii * ii + jj * jj, (6 - ii) ** 2 + (8 - jj) ** 2))


def test_without_obstacles() -> None:
    m = np.zeros((3, 4), dtype=bool)
    assert np.all(np.isinf(distance_cells(m)))
    with pytest.raises(ValueError, match="no obstacle"):
        squared_distance_cells(m)
    with pytest.raises(ValueError, match="2-D"):
        squared_distance_cells(np.ones(5, dtype=bool))


def test_grid_fields_equal_scipys_on_a_world() -> None:
    g = get_world("small-office")
    res = g.resolution
    assert np.array_equal(g.distance_to_occupied, distance_cells_reference(g.occupied_mask) * res)
    assert np.array_equal(g.distance_to_blocking, distance_cells_reference(g.blocking_mask) * res)


@pytest.mark.parametrize(
    "config",
    [
        LikelihoodFieldConfig(),
        LikelihoodFieldConfig(scoring="ros"),
        # a cap that is not a whole number of cells, a narrow Gaussian
        LikelihoodFieldConfig(max_occ_dist_m=0.73, sigma_hit_m=0.07),
        LikelihoodFieldConfig(max_occ_dist_m=100.0),  # nothing is capped
    ],
)
def test_likelihood_table_is_the_per_cell_formula(config: LikelihoodFieldConfig) -> None:
    rng = np.random.default_rng(3)
    data = rng.choice([FREE, OCCUPIED, UNKNOWN], size=(41, 57), p=[0.9, 0.05, 0.05])
    g = OccupancyGrid(data.astype(np.int8), 0.05)
    model = LikelihoodFieldModel(g, config)
    for range_max in (4.0, 30.0):
        per_cell = model._beam_value(
            np.minimum(
                distance_cells_reference(g.occupied_mask) * g.resolution, config.max_occ_dist_m
            ),
            range_max,
        )
        assert np.array_equal(model._log_p_table(range_max), per_cell)


def test_likelihood_table_without_obstacles_is_the_cap() -> None:
    g = OccupancyGrid(np.zeros((6, 8), np.int8), 0.1)
    model = LikelihoodFieldModel(g)
    table = model._log_p_table(10.0)
    assert table.shape == (6, 8)
    assert np.all(table == model._cap_value(10.0))


def test_likelihood_table_of_a_long_thin_map_with_a_far_cap() -> None:
    """A 1 x 40 corridor with one wall cell at its end and a cap beyond every distance: the
    list of values would be longer than the map, so the table is computed per cell, with the
    same numbers."""
    data = np.zeros((1, 40), np.int8)
    data[0, 0] = OCCUPIED
    g = OccupancyGrid(data, 0.05)
    assert int(g.squared_cells_to_occupied.max()) >= data.size  # type: ignore[union-attr]
    config = LikelihoodFieldConfig(max_occ_dist_m=100.0)
    model = LikelihoodFieldModel(g, config)
    per_cell = model._beam_value(
        np.minimum(distance_cells_reference(g.occupied_mask) * g.resolution, 100.0), 8.0
    )
    assert np.array_equal(model._log_p_table(8.0), per_cell)


def test_likelihood_table_is_an_index_of_two_bytes_a_cell() -> None:
    """The kernel reads a 2-byte index per cell and a short list of values (the random reads
    of 10^6 test poses then stay in the caches; docs/performance.md)."""
    data = np.full((100, 100), FREE, np.int8)
    data[[0, -1], :] = OCCUPIED
    data[:, [0, -1]] = OCCUPIED  # a room whose centre is 2.5 m from its walls
    model = LikelihoodFieldModel(OccupancyGrid(data, 0.05))
    index, values = model._indexed_table(8.0)
    assert index.dtype == np.uint16 and index.shape == data.shape
    assert values.size == 1601  # s = 0 .. 1600 squared cells: 2 m at 5 cm


def test_likelihood_table_with_a_cap_beyond_the_index() -> None:
    """A 1 x 300 corridor with one wall cell and a 100 m cap: squared distances up to 299^2,
    past a 2-byte index of every s, so the list holds only the distances the map has."""
    data = np.zeros((1, 300), np.int8)
    data[0, 0] = OCCUPIED
    g = OccupancyGrid(data, 0.05)
    model = LikelihoodFieldModel(g, LikelihoodFieldConfig(max_occ_dist_m=100.0))
    index, values = model._indexed_table(8.0)
    assert values.size == 300 and index.dtype == np.uint16
    per_cell = model._beam_value(
        np.minimum(distance_cells_reference(g.occupied_mask) * g.resolution, 100.0), 8.0
    )
    assert np.array_equal(model._log_p_table(8.0), per_cell)
