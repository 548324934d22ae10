"""Exact Euclidean distance fields of occupancy grids (the likelihood field's, the ray caster's).

A map's distance field is built once, the first time a filter weighs a scan on it, and on a
big building it was half of the first global localisation: SciPy's
``ndimage.distance_transform_edt`` took 1.0 s of 2.2 s on the bench's 3,900 m^2 composite
(7.8 million cells), most of it in the float64 index arrays it builds to turn its feature
transform into distances (docs/performance.md). :func:`squared_distance_cells` computes the
same field with the two-pass lower-envelope algorithm of Felzenszwalb and Huttenlocher
("Distance transforms of sampled functions", Theory of Computing 8, 2012), compiled with numba,
in integer arithmetic: the squared distances are exact, so the field equals SciPy's to the last
bit (``tests/maps/test_distance.py`` compares both; :func:`distance_cells_reference` keeps
SciPy's).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

#: Stands for "no obstacle in this column" after the first pass: larger than any squared
#: distance of a grid whose squared diagonal fits in int32 (checked before the passes run).
_FAR = np.int32(np.iinfo(np.int32).max)


@numba.njit(cache=True)
def _column_pass(obstacles: NDArray[np.bool_]) -> NDArray[np.int32]:
    """Squared distance from each cell to the nearest obstacle *in its own column*
    (``_FAR`` when the column has none)."""
    h, w = obstacles.shape
    out = np.empty((h, w), dtype=np.int32)
    for j in range(w):
        last = -1  # row of the last obstacle seen going down
        for i in range(h):
            if obstacles[i, j]:
                last = i
            out[i, j] = _FAR if last < 0 else (i - last) * (i - last)
        last = -1  # and going up
        for i in range(h - 1, -1, -1):
            if obstacles[i, j]:
                last = i
            if last >= 0:
                d = (last - i) * (last - i)
                if d < out[i, j]:
                    out[i, j] = d
    return out


@numba.njit(cache=True)
def _row_pass(g: NDArray[np.int32]) -> NDArray[np.int32]:
    """Along each row, ``min_k (j - k)^2 + g[i, k]``: the lower envelope of the parabolas
    rooted at the row's cells that see an obstacle in their column."""
    h, w = g.shape
    out = np.empty((h, w), dtype=np.int32)  # arithmetic below in int64 and float64
    v = np.empty(w, dtype=np.int64)  # roots of the envelope's parabolas
    z = np.empty(w + 1, dtype=np.float64)  # where each starts to be the lowest
    for i in range(h):
        k = -1
        for q in range(w):
            fq = np.int64(g[i, q])
            if fq >= _FAR:
                continue
            if k < 0:
                k = 0
                v[0] = q
                z[0] = -np.inf
                z[1] = np.inf
                continue
            p = v[k]
            s = ((fq + q * q) - (np.int64(g[i, p]) + p * p)) / (2.0 * (q - p))
            while s <= z[k]:  # never at k = 0, where z is -inf
                k -= 1
                p = v[k]
                s = ((fq + q * q) - (np.int64(g[i, p]) + p * p)) / (2.0 * (q - p))
            k += 1
            v[k] = q
            z[k] = s
            z[k + 1] = np.inf
        if k < 0:
            for q in range(w):
                out[i, q] = _FAR
            continue
        k = 0
        for q in range(w):
            while z[k + 1] < q:
                k += 1
            p = v[k]
            out[i, q] = (q - p) * (q - p) + np.int64(g[i, p])
    return out


def squared_distance_cells(obstacles: NDArray[np.bool_]) -> NDArray[np.int32]:
    """``(H, W)`` squared Euclidean distance, in cells, from each cell centre to the nearest
    cell where ``obstacles`` is true (0 there). Needs at least one obstacle."""
    mask = np.ascontiguousarray(obstacles, dtype=np.bool_)
    if mask.ndim != 2:
        raise ValueError(f"squared_distance_cells: expected a 2-D mask, got shape {mask.shape}")
    if not mask.any():
        raise ValueError("squared_distance_cells: the mask has no obstacle")
    h, w = mask.shape
    if h * h + w * w > np.iinfo(np.int32).max:
        raise ValueError(f"squared_distance_cells: a {h} x {w} grid is too large")
    return _row_pass(_column_pass(mask))


def distance_from_squared(squared: NDArray[np.int32], scale: float = 1.0) -> NDArray[np.float64]:
    """``sqrt(squared) * scale`` in float64, as SciPy's distances times a cell size."""
    dist = np.sqrt(squared.astype(np.float64))
    dist *= scale
    return dist


def distance_cells(obstacles: NDArray[np.bool_], scale: float = 1.0) -> NDArray[np.float64]:
    """Euclidean distance to the nearest obstacle, in cells times ``scale`` (a cell size gives
    metres); ``+inf`` everywhere without one."""
    mask = np.asarray(obstacles, dtype=np.bool_)
    if not mask.any():
        return np.full(mask.shape, np.inf)
    return distance_from_squared(squared_distance_cells(mask), scale)


def distance_cells_reference(obstacles: NDArray[np.bool_]) -> NDArray[np.float64]:
    """:func:`distance_cells` by SciPy (``ndimage.distance_transform_edt``): the reference the
    tests compare with."""
    mask = np.asarray(obstacles, dtype=np.bool_)
    if not mask.any():
        return np.full(mask.shape, np.inf)
    out: NDArray[np.float64] = ndimage.distance_transform_edt(~mask)
    return out


__all__ = [
    "distance_cells",
    "distance_cells_reference",
    "distance_from_squared",
    "squared_distance_cells",
]
