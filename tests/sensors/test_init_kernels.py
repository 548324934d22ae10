"""The compiled pieces of CEAMCL's initial species generation equal their NumPy references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from ceamcl.filters.ceamcl.initialisation import (
    best_in_parts,
    region_means,
    scale_cells,
    skiz_partition,
    skiz_partition_reference,
    smooth_cells,
    smooth_cells_reference,
    top_k_mean_per_cell,
    top_k_mean_per_cell_reference,
)
from tests.city_block import seed_distances


@pytest.mark.parametrize("k", [1, 3, 7])
def test_top_k_mean_equals_the_sort_based_reference(k: int) -> None:
    rng = np.random.default_rng(40)
    n_cells = 500
    cell = rng.integers(0, n_cells - 50, 20_000)  # the last 50 cells stay empty
    value = rng.random(20_000)
    value[rng.random(20_000) < 0.1] = 0.5  # ties
    got = top_k_mean_per_cell(cell, value, n_cells, k)
    want = top_k_mean_per_cell_reference(cell, value, n_cells, k)
    assert np.array_equal(got, want, equal_nan=True)  # bit for bit, NaN where empty
    assert np.isnan(got[-50:]).all()


def test_best_in_parts_equals_a_stable_full_sort() -> None:
    rng = np.random.default_rng(41)
    n = 30_000
    part = rng.integers(0, 6, n).astype(np.int32)  # 0: no part
    score = np.round(rng.normal(size=n), 2)  # many ties
    sizes = np.array([5, 100, 0, 4000, 10_000, 3], dtype=np.int64)
    got = best_in_parts(part, score, sizes)
    order = np.argsort(-score, kind="stable")
    for s, take in enumerate(got, start=1):
        want = order[part[order] == s][: sizes[s - 1]]
        assert np.array_equal(take, want)


def _sparse_weights(rng: np.random.Generator, ny: int, nx: int) -> np.ndarray:
    """Cell weights as section 3.1 makes them: NaN where no test pose fell."""
    w = np.full((ny, nx), np.nan)
    filled = rng.random((ny, nx)) < rng.random()
    w[filled] = rng.random(int(filled.sum()))
    return w


@pytest.mark.parametrize("size", [2, 3, 4, 5])
def test_smoothing_equals_scipys_uniform_filter_bit_for_bit(size: int) -> None:
    """The compiled NaN-aware mean repeats SciPy's running sums, roundings included: the
    cells scaled above ``mu`` (the set V) cannot differ by a last bit."""
    rng = np.random.default_rng(42)
    for _ in range(25):
        ny, nx = (int(v) for v in rng.integers(1, 40, 2))
        w = _sparse_weights(rng, ny, nx)
        assert np.array_equal(
            smooth_cells(w, size), smooth_cells_reference(w, size), equal_nan=True
        )


def test_skiz_partition_equals_scipys_chamfer_transform_ties_included() -> None:
    """Seeds of several labels close together make many cells equidistant from two of them;
    the compiled partition gives each such cell the label SciPy's transform gives it."""
    rng = np.random.default_rng(43)
    ties = 0
    for _ in range(40):
        ny, nx = (int(v) for v in rng.integers(1, 35, 2))
        seeds = np.zeros((ny, nx), dtype=np.int32)
        for label in range(1, int(rng.integers(1, 7))):
            y, x = int(rng.integers(0, ny)), int(rng.integers(0, nx))
            seeds[y : y + int(rng.integers(1, 4)), x : x + int(rng.integers(1, 4))] = label
        got = skiz_partition(seeds)
        assert np.array_equal(got, skiz_partition_reference(seeds))
        labels, d = seed_distances(seeds)
        if len(labels) > 1:
            ties += int(np.sum(np.sum(d == d.min(axis=0), axis=0) > 1))
    assert ties > 100  # the comparison covered ties, where the transform's order decides


def test_scaling_and_region_means_equal_their_numpy_forms() -> None:
    rng = np.random.default_rng(44)
    for trial in range(30):
        w = rng.random(300) * (-1.0 if trial % 5 == 0 else 1.0)
        w[rng.random(300) < 0.5] = np.nan
        if trial % 7 == 0:
            w[:] = np.nan
        for mu in (0.85, 0.0, -0.1):
            scaled, in_v = scale_cells(w, mu)
            best = np.nanmax(w) if np.any(np.isfinite(w)) else 0.0
            ref = w if best > 0 else np.where(np.isnan(w), np.nan, 1.0)
            ref = ref / (best if best > 0 else 1.0)
            assert np.array_equal(scaled, ref, equal_nan=True)
            assert np.array_equal(in_v, np.nan_to_num(ref, nan=0.0) > mu)
        seeds, n = ndimage.label(rng.random((20, 15)) < 0.35)
        values = rng.random(300)
        flat = seeds.reshape(-1)
        got = region_means(values, flat, np.flatnonzero(flat), n)
        want = ndimage.mean(values.reshape(20, 15), labels=seeds, index=np.arange(1, n + 1))
        assert np.array_equal(got, np.asarray(want, dtype=np.float64).reshape(-1))
