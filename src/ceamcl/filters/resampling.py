"""Resampling schemes: functions from normalised weights to ancestor indices (as in
nchopin/particles' ``resampling.py``), registered by name in :data:`RESAMPLERS`; resampling
inside labels (CEAMCL's species); and the log-weight arithmetic every filter shares."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: ``scheme(weights, n, rng) -> ancestor indices (n,)``.
Resampler = Callable[[ArrayLike, int, np.random.Generator], NDArray[np.intp]]


def systematic(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Low-variance (systematic) resampling, Probabilistic Robotics Table 4.4.

    One uniform offset, ``n`` evenly spaced pointers into the cumulative weights. Each index
    ``i`` is drawn ``floor(n w_i)`` or ``ceil(n w_i)`` times. NaN, infinite or negative
    weights count as 0; if no weight is left, every index is equally likely.
    """
    w = np.asarray(weights, dtype=np.float64)
    if n <= 0 or w.size == 0:
        return np.zeros(0, dtype=np.intp)
    cdf = _cdf(w)
    pointers = (rng.random() + np.arange(n)) / n
    idx = np.searchsorted(cdf, pointers, side="right")
    return np.minimum(idx, w.size - 1).astype(np.intp)


def multinomial(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Multinomial resampling: ``n`` independent draws from the weights (amcl's roulette
    wheel). Bad weights count as in :func:`systematic`."""
    w = np.asarray(weights, dtype=np.float64)
    if n <= 0 or w.size == 0:
        return np.zeros(0, dtype=np.intp)
    idx = np.searchsorted(_cdf(w), rng.random(n), side="right")
    return np.minimum(idx, w.size - 1).astype(np.intp)


def _cdf(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cumulative weights ending at 1; NaN, infinite or negative weights count as 0, and
    with no weight left every index is equally likely."""
    cdf = np.cumsum(w)
    if not (np.isfinite(cdf[-1]) and cdf[-1] > 0.0) or np.any(w < 0):
        w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
        cdf = np.cumsum(w)
        if not cdf[-1] > 0.0:
            cdf = np.arange(1.0, w.size + 1.0)
    cdf /= cdf[-1]
    return cdf


#: Resampling schemes by name.
RESAMPLERS: dict[str, Resampler] = {"systematic": systematic, "multinomial": multinomial}


def resampler(name: str) -> Resampler:
    """The resampling scheme ``name`` (see :data:`RESAMPLERS`)."""
    try:
        return RESAMPLERS[name]
    except KeyError:
        raise ValueError(
            f"resampling scheme: unknown {name!r}; expected one of {', '.join(RESAMPLERS)}"
        ) from None


def effective_sample_size(weights: ArrayLike) -> float:
    """``1 / sum w_i^2`` of normalised weights."""
    w = np.asarray(weights, dtype=np.float64)
    s = float(np.sum(w * w))
    return 1.0 / s if s > 0 else 0.0


def sanitise_log_likelihood(log_likelihood: ArrayLike) -> NDArray[np.float64]:
    """Log-likelihoods with NaN and +inf (a model's numerical failure) turned into -inf
    (impossible), so they can never spread into weights or poses."""
    ll = np.asarray(log_likelihood, dtype=np.float64)
    bad = np.isnan(ll) | (ll == np.inf)
    if bad.any():
        ll = np.where(bad, -np.inf, ll)
    return ll


def normalise_log_weights(
    log_weights: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Shift log-weights so the largest is 0 and return ``(log_w, w, ok)`` with ``w`` summing to 1.

    ``ok`` is False when no weight is finite (everything impossible or NaN); the weights are
    then uniform, so the caller never propagates NaN.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    lw = np.where(np.isnan(lw), -np.inf, lw)
    top = float(np.max(lw)) if lw.size else -np.inf
    if not np.isfinite(top):
        n = max(lw.size, 1)
        return np.zeros(lw.size), np.full(lw.size, 1.0 / n), False
    lw = lw - top
    w = np.exp(lw)
    total = float(w.sum())
    return lw - np.log(total), w / total, True


def label_segments(
    labels: NDArray[np.int64],
) -> tuple[NDArray[np.intp], NDArray[np.int64], NDArray[np.intp], NDArray[np.intp]]:
    """The particles sorted by label: ``(order, ids, starts, counts)``, so that label
    ``ids[k]`` (ascending) owns ``order[starts[k] : starts[k] + counts[k]]``."""
    if labels.size and labels[0] == labels[-1] and bool(np.all(labels == labels[0])):
        # one label (a lone species: CEAMCL tracking), the stable sort's answer without it
        first = np.zeros(1, dtype=np.intp)
        return np.arange(labels.size), labels[:1].copy(), first, np.array([labels.size])
    order = np.argsort(labels, kind="stable")
    ids, starts = np.unique(labels[order], return_index=True)
    counts = np.diff(np.append(starts, order.size))
    return order, ids, starts, counts


def segment_weights(
    loglik: NDArray[np.float64], starts: NDArray[np.intp], seg: NDArray[np.intp]
) -> NDArray[np.float64]:
    """In-label importance weights of log-likelihoods sorted by label (segment ``seg[i]``
    of particle ``i`` begins at ``starts[seg[i]]``): each segment's weights sum to 1, never
    NaN; a segment with no finite log-likelihood gets uniform weights."""
    ll = np.where(np.isnan(loglik), -np.inf, loglik)
    top = np.maximum.reduceat(ll, starts)
    finite_top = np.isfinite(top)
    w = np.exp(ll - np.where(finite_top, top, 0.0)[seg])
    w = np.where(finite_top[seg], w, 1.0)
    return np.asarray(w / np.add.reduceat(w, starts)[seg], dtype=np.float64)


def label_groups(labels: NDArray[np.int64]) -> dict[int, NDArray[np.intp]]:
    """Indices of the particles of each label (a species id), in ascending label order."""
    if labels.size == 0:
        return {}
    order, ids, starts, counts = label_segments(labels)
    return {int(i): order[s : s + c] for i, s, c in zip(ids, starts, counts, strict=True)}


def systematic_within_labels(
    labels: NDArray[np.int64],
    loglik: NDArray[np.float64],
    targets: dict[int, int],
    rng: np.random.Generator,
) -> tuple[NDArray[np.intp], dict[int, NDArray[np.intp]]]:
    """Low-variance resampling inside every label (species) at once: ``targets.get(id, size)``
    ancestors of each label, drawn from the in-label weights of ``loglik`` with one uniform
    offset per label (ascending ids), as :func:`systematic` would draw them label by label.

    Returns ``(ancestors, members)``: the ancestors' indices, grouped by label in ascending
    order, and the members of each surviving label among the resampled particles (contiguous
    ranges, what :func:`label_groups` would return for them).
    """
    if labels.size == 0:
        return np.zeros(0, dtype=np.intp), {}
    order, ids, starts, counts = label_segments(labels)
    seg = np.repeat(np.arange(ids.size), counts)
    w = segment_weights(loglik[order], starts, seg)
    # Cumulative weights inside each label, normalised by the label's total.
    cum = np.cumsum(w)
    local = cum - np.append(0.0, cum)[starts][seg]
    ends = starts + counts - 1
    cdf = local / local[ends][seg]
    n = np.array([targets.get(int(sid), int(c)) for sid, c in zip(ids, counts, strict=True)])
    n = np.maximum(n, 0)
    u = np.zeros(ids.size)
    u[n > 0] = rng.random(int(np.count_nonzero(n > 0)))
    ptr_seg = np.repeat(np.arange(ids.size), n)
    first = np.cumsum(n) - n
    k = np.arange(ptr_seg.size) - first[ptr_seg]
    pointers = (u[ptr_seg] + k) / n[ptr_seg]
    # One search for all labels: label k's cumulative weights lie in [2k, 2k + 1].
    pos = np.searchsorted(2.0 * seg + cdf, 2.0 * ptr_seg + pointers, side="right")
    pos = np.minimum(pos, ends[ptr_seg])
    members = {
        int(sid): np.arange(a, a + c, dtype=np.intp)
        for sid, a, c in zip(ids, first, n, strict=True)
        if c > 0
    }
    return order[pos].astype(np.intp), members
