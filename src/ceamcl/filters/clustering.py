"""Grouping particles into x-y clusters: connected regions of occupied grid cells.

The same mechanism serves the hypotheses of MCL and GMCL (clusters, as ROS amcl reports) and
CEAMCL's splitting rule (a species whose occupied cells form several regions splits).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from ceamcl.filters.base import Hypothesis
from ceamcl.pose import pose_covariance, pose_mean

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


_TWENTY_SIX = np.ones((3, 3, 3), dtype=bool)


def pose_cluster_labels(
    poses: ArrayLike, cell_m: float, cell_rad: float
) -> tuple[NDArray[np.int64], int]:
    """Label poses ``(N, 3)`` by the connected region (26-neighbourhood) of occupied
    ``cell_m x cell_m x cell_rad`` cells, with the heading axis wrapping around at +-pi.

    Two groups at the same place but with headings far apart get different labels: this is
    how a species holding two heading modes (a pose and its mirror image) splits.
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), 0
    n_theta = max(1, int(np.floor(2.0 * np.pi / cell_rad)))
    xy = np.floor(p[:, :2] / cell_m).astype(np.int64)
    xy -= xy.min(axis=0)
    th = np.floor((p[:, 2] + np.pi) / (2.0 * np.pi) * n_theta).astype(np.int64) % n_theta
    shape = (int(xy[:, 0].max()) + 1, int(xy[:, 1].max()) + 1, n_theta)
    if shape[0] * shape[1] * shape[2] > 50_000_000:
        raise ValueError("pose_cluster_labels: poses spread too far for the cell size")
    occ = np.zeros(shape, dtype=bool)
    occ[xy[:, 0], xy[:, 1], th] = True
    lab, count = ndimage.label(occ, structure=_TWENTY_SIX)
    if n_theta > 2 and count > 1:
        # Join regions that touch across the heading wrap: each occupied cell of the last
        # heading slice with the occupied cells of the first slice next to it in x-y.
        first = np.pad(lab[:, :, 0], 1)
        last = lab[:, :, -1]
        a, b = [], []
        for dx in range(3):
            for dy in range(3):
                near = first[dx : dx + shape[0], dy : dy + shape[1]]
                touch = (last > 0) & (near > 0)
                a.append(last[touch])
                b.append(near[touch])
        edges = np.concatenate(a), np.concatenate(b)
        graph = sparse.coo_matrix((np.ones(edges[0].size), edges), shape=(count + 1, count + 1))
        _, component = csgraph.connected_components(graph, directed=False)
        # Number the joined regions in the order of their lowest label (background stays 0).
        _, lowest = np.unique(component, return_index=True)
        lab = np.argsort(np.argsort(lowest))[component][lab]
        count = int(lowest.size - 1)
    return (lab[xy[:, 0], xy[:, 1], th] - 1).astype(np.int64), int(count)


def cluster_hypotheses(
    poses: NDArray[np.float64],
    weights: NDArray[np.float64],
    fitness: NDArray[np.float64],
    labels: NDArray[np.int64],
    count: int,
    limit: int | None = None,
) -> list[Hypothesis]:
    """The particle clusters ``labels`` (in ``0..count-1``) as hypotheses, heaviest first
    (equal masses: lower label first); only the ``limit`` heaviest when given. Each has its
    members' weighted mean pose and covariance, its share of the weight and mean fitness."""
    mass = np.bincount(labels, weights=weights, minlength=count)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(count + 1))
    out = []
    for k in np.argsort(-mass, kind="stable")[:limit]:
        members = order[bounds[k] : bounds[k + 1]]
        wk = weights[members]
        mean = pose_mean(poses[members], wk)
        out.append(
            Hypothesis(
                pose=mean,
                covariance=pose_covariance(poses[members], wk, mean),
                n_particles=int(members.size),
                weight=float(mass[k]),
                fitness=float(np.mean(fitness[members])),
                label=int(k),
            )
        )
    return out
