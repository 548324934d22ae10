"""Tests of resampling and weight normalisation (``ceamcl.filters.resampling``)."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters.resampling import (
    RESAMPLERS,
    effective_sample_size,
    label_segments,
    multinomial,
    normalise_log_weights,
    resampler,
    systematic,
    systematic_within_labels,
    systematic_within_labels_reference,
)


@pytest.mark.parametrize("n", [1, 7, 100, 1000])
def test_systematic_gives_floor_or_ceil_copies(n: int) -> None:
    rng = np.random.default_rng(40)
    for _ in range(200):
        w = rng.dirichlet(np.full(50, 0.3))
        idx = systematic(w, n, rng)
        assert idx.shape == (n,)
        assert np.all(np.diff(idx) >= 0)  # ancestors come out in order
        counts = np.bincount(idx, minlength=w.size)
        # n w_i may land a hair off an integer by round-off; a copy count must still be one of
        # the two integers around it.
        nw = n * w
        assert np.all((counts >= np.floor(nw - 1e-9)) & (counts <= np.ceil(nw + 1e-9)))
        assert np.all(counts[w == 0] == 0)


def test_systematic_is_unbiased() -> None:
    # E[copies of i] = n w_i. Each count takes only floor/ceil values, so its variance is at
    # most 1/4; the mean over R draws has SE <= 0.5 / sqrt(R). Allow 5 SE.
    rng = np.random.default_rng(41)
    w = rng.dirichlet(np.ones(30))
    n, draws = 100, 4000
    total = np.zeros(w.size)
    for _ in range(draws):
        total += np.bincount(systematic(w, n, rng), minlength=w.size)
    mean = total / draws
    assert np.all(np.abs(mean - n * w) < 5 * 0.5 / np.sqrt(draws))


def test_systematic_edge_cases() -> None:
    rng = np.random.default_rng(42)
    assert systematic([0.2, 0.8], 0, rng).size == 0
    assert systematic([], 5, rng).size == 0
    one_hot = np.zeros(10)
    one_hot[6] = 1.0
    assert np.all(systematic(one_hot, 25, rng) == 6)
    # Unnormalised weights are normalised first.
    idx = systematic([2.0, 6.0], 8, rng)
    assert np.bincount(idx, minlength=2).tolist() == [2, 6]
    # Changing the sample size: 3 particles to 12.
    idx = systematic([1 / 3, 1 / 3, 1 / 3], 12, rng)
    assert np.bincount(idx, minlength=3).tolist() == [4, 4, 4]
    # Finite weights whose sum overflows are weights like any others (every pointer fell on
    # the last index), for both schemes.
    for scheme in (systematic, multinomial):
        idx = scheme([1e308, 1e308], 400, rng)
        assert 150 <= np.bincount(idx, minlength=2)[0] <= 250


def test_effective_sample_size() -> None:
    for n in (1, 10, 5000):
        assert effective_sample_size(np.full(n, 1.0 / n)) == pytest.approx(n)
    one_hot = np.zeros(100)
    one_hot[3] = 1.0
    assert effective_sample_size(one_hot) == pytest.approx(1.0)
    # Two equal particles out of many: ESS 2.
    w = np.zeros(100)
    w[[1, 50]] = 0.5
    assert effective_sample_size(w) == pytest.approx(2.0)
    assert effective_sample_size(np.zeros(5)) == 0.0


def test_normalise_log_weights_regular_and_extreme() -> None:
    lw, w, ok = normalise_log_weights([np.log(1.0), np.log(3.0)])
    assert ok
    np.testing.assert_allclose(w, [0.25, 0.75])
    np.testing.assert_allclose(np.exp(lw), w)
    # Huge magnitudes (sums of thousands of log-likelihoods) neither overflow nor underflow.
    lw, w, ok = normalise_log_weights([-1e5, -1e5 + np.log(2.0), -2e5])
    assert ok
    np.testing.assert_allclose(w, [1 / 3, 2 / 3, 0.0], atol=1e-15)
    lw, w, ok = normalise_log_weights([800.0, 800.0])
    assert ok
    np.testing.assert_allclose(w, [0.5, 0.5])
    assert np.all(np.isfinite(lw))


def test_normalise_log_weights_all_impossible_or_nan() -> None:
    for bad in (
        np.full(4, -np.inf),
        np.full(4, np.nan),
        np.array([np.nan, -np.inf, np.nan, -np.inf]),
    ):
        lw, w, ok = normalise_log_weights(bad)
        assert not ok
        np.testing.assert_allclose(w, 0.25)
        assert not np.any(np.isnan(lw)) and not np.any(np.isnan(w))
    lw, w, ok = normalise_log_weights(np.zeros(0))
    assert not ok and w.size == 0


def test_normalise_log_weights_treats_nan_as_impossible() -> None:
    lw, w, ok = normalise_log_weights([np.nan, 0.0, -np.inf, 0.0])
    assert ok
    np.testing.assert_allclose(w, [0.0, 0.5, 0.0, 0.5])
    assert not np.any(np.isnan(lw))
    assert lw[0] == -np.inf and lw[2] == -np.inf


def test_multinomial_counts_follow_the_weights() -> None:
    # n independent draws: copies of i ~ Binomial(n, w_i); 5 standard deviations.
    rng = np.random.default_rng(42)
    w = np.array([0.5, 0.3, 0.15, 0.05, 0.0])
    n = 20_000
    counts = np.bincount(multinomial(w, n, rng), minlength=w.size)
    sd = np.sqrt(n * w * (1 - w))
    assert np.all(np.abs(counts - n * w) <= 5 * sd + 1e-9)
    assert counts[-1] == 0


def test_resamplers_are_found_by_name() -> None:
    assert resampler("systematic") is systematic and resampler("multinomial") is multinomial
    assert set(RESAMPLERS) == {"systematic", "multinomial"}
    with pytest.raises(ValueError, match="unknown 'stratified'"):
        resampler("stratified")


def test_label_segments_is_the_stable_sort_with_one_label_or_many() -> None:
    """One label takes a shortcut (a lone species); every case gives the stable sort's arrays,
    dtypes included."""
    rng = np.random.default_rng(3)
    cases = [np.full(n, v, dtype=np.int64) for n in (1, 2, 120) for v in (0, 5, 10**9)]
    cases += [rng.integers(0, k, n).astype(np.int64) for k in (2, 5) for n in (2, 50, 300)]
    cases += [np.array([4, 1, 4], dtype=np.int64), np.array([3, 3, 3, 2], dtype=np.int64)]
    for labels in cases:
        order = np.argsort(labels, kind="stable")
        ids, starts = np.unique(labels[order], return_index=True)
        want = (order, ids, starts, np.diff(np.append(starts, order.size)))
        for got, ref in zip(label_segments(labels), want, strict=True):
            assert got.dtype == ref.dtype
            np.testing.assert_array_equal(got, ref)


def test_systematic_within_labels_equals_its_numpy_reference_bit_for_bit() -> None:
    """Labels unsorted and sparse, 1 to 300 particles each, targets of 0, 1, fewer and more,
    log-likelihoods with NaN, -inf, ties and whole labels impossible: the same ancestors,
    members and random stream afterwards."""
    rng = np.random.default_rng(8)
    for _ in range(300):
        sizes = rng.integers(1, 300, rng.integers(1, 6))
        ids = rng.choice(5_000, sizes.size, replace=False)
        labels = rng.permutation(np.repeat(ids, sizes)).astype(np.int64)
        loglik = np.round(rng.normal(-30, 10, labels.size), int(rng.integers(0, 2)))
        loglik[rng.random(labels.size) < 0.1] = np.nan
        loglik[rng.random(labels.size) < 0.1] = -np.inf
        if rng.random() < 0.3:
            loglik[labels == ids[0]] = -np.inf
        targets = {int(i): int(rng.choice([0, 1, 7, 40, 500])) for i in ids if rng.random() < 0.8}
        seed = int(rng.integers(0, 2**32))
        r1, r2 = np.random.default_rng(seed), np.random.default_rng(seed)
        a1, m1 = systematic_within_labels(labels, loglik, targets, r1)
        a2, m2 = systematic_within_labels_reference(labels, loglik, targets, r2)
        assert a1.dtype == a2.dtype
        np.testing.assert_array_equal(a1, a2)
        assert list(m1) == list(m2)
        for sid in m1:
            np.testing.assert_array_equal(m1[sid], m2[sid])
        assert r1.random() == r2.random()
