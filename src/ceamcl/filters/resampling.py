"""Resampling schemes: functions from normalised weights to ancestor indices."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def systematic(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Low-variance (systematic) resampling, Probabilistic Robotics Table 4.4.

    One uniform offset, ``n`` evenly spaced pointers into the cumulative weights. Each index
    ``i`` is drawn ``floor(n w_i)`` or ``ceil(n w_i)`` times. NaN, infinite or negative
    weights count as 0; if no weight is left, every index is equally likely.
    """
    w = np.asarray(weights, dtype=np.float64)
    if n <= 0 or w.size == 0:
        return np.zeros(0, dtype=np.intp)
    cdf = np.cumsum(w)
    if not (np.isfinite(cdf[-1]) and cdf[-1] > 0.0) or np.any(w < 0):
        w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
        cdf = np.cumsum(w)
        if not cdf[-1] > 0.0:
            cdf = np.arange(1.0, w.size + 1.0)
    cdf /= cdf[-1]
    pointers = (rng.random() + np.arange(n)) / n
    idx = np.searchsorted(cdf, pointers, side="right")
    return np.minimum(idx, w.size - 1).astype(np.intp)


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
