"""Grouping particles into x-y clusters: connected regions of occupied grid cells.

The same mechanism serves the hypotheses of MCL and GMCL (clusters, as ROS amcl reports) and
CEAMCL's splitting rule (a species whose occupied cells form several regions splits).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

_EIGHT = np.ones((3, 3), dtype=bool)


def cluster_labels(xy: ArrayLike, cell_m: float) -> tuple[NDArray[np.int64], int]:
    """Label points ``(N, 2)`` by the 8-connected region of ``cell_m`` cells they fall in.

    Returns ``(labels, count)``, labels in ``0..count-1``. Works in a bounding box of the
    points, so the cost depends on their spread, not on the map.
    """
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), 0
    cells = np.floor(p / cell_m).astype(np.int64)
    lo = cells.min(axis=0)
    cells -= lo
    shape = tuple(int(v) + 1 for v in cells.max(axis=0))
    if shape[0] * shape[1] > 50_000_000:
        raise ValueError("cluster_labels: points spread too far for the cell size")
    occ = np.zeros(shape, dtype=bool)
    occ[cells[:, 0], cells[:, 1]] = True
    lab, count = ndimage.label(occ, structure=_EIGHT)
    return (lab[cells[:, 0], cells[:, 1]] - 1).astype(np.int64), int(count)
