"""The compiled pieces of CEAMCL's initial species generation equal their NumPy references."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters.ceamcl.initialisation import (
    best_in_parts,
    top_k_mean_per_cell,
    top_k_mean_per_cell_reference,
)


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
