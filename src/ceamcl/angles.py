"""Angles: wrapping, differences and circular statistics.

Headings are never averaged as plain numbers anywhere in the package; every module that
needs a mean heading calls :func:`circular_mean` from here.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

TWO_PI = 2.0 * np.pi


def wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to the half-open interval (-pi, pi]."""
    a = np.asarray(angle, dtype=np.float64)
    m = np.mod(np.pi - a, TWO_PI)
    # np.mod of a tiny negative rounds up to 2 pi itself, which would give -pi
    return np.pi - np.where(m >= TWO_PI, 0.0, m)


@numba.njit(cache=True)
def wrap_one(angle: float) -> float:  # pragma: no cover
    """:func:`wrap` of one angle inside compiled kernels: the same operations, the same bits."""
    m = np.mod(np.pi - angle, TWO_PI)
    return np.pi - (0.0 if m >= TWO_PI else m)


def diff(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Signed shortest difference ``a - b``, wrapped to (-pi, pi]."""
    return wrap(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))


def circular_mean(angles: ArrayLike, weights: ArrayLike | None = None) -> float:
    """Weighted circular mean: the direction of the mean unit vector.

    Returns 0.0 when the resultant vector vanishes (perfectly spread headings), so the result
    is never NaN.
    """
    a = np.asarray(angles, dtype=np.float64)
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=np.float64)
    s = float(np.sum(w * np.sin(a)))
    c = float(np.sum(w * np.cos(a)))
    if s == 0.0 and c == 0.0:
        return 0.0
    return float(np.arctan2(s, c))


def circular_variance(angles: ArrayLike, weights: ArrayLike | None = None) -> float:
    """Angular spread ``-2 ln R`` (a wrapped normal's variance); R is the resultant length."""
    a = np.asarray(angles, dtype=np.float64)
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=np.float64)
    total = float(np.sum(w))
    if total <= 0.0:
        return 0.0
    r = np.hypot(np.sum(w * np.sin(a)), np.sum(w * np.cos(a))) / total
    r = float(np.clip(r, 1e-300, 1.0))
    return -2.0 * float(np.log(r))


def interpolate(a: ArrayLike, b: ArrayLike, fraction: ArrayLike) -> NDArray[np.float64]:
    """Interpolate from heading ``a`` towards ``b`` along the shorter arc; result wrapped."""
    a_ = np.asarray(a, dtype=np.float64)
    return wrap(a_ + np.asarray(fraction, dtype=np.float64) * diff(b, a_))
