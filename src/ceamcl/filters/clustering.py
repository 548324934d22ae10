"""Grouping particles into x-y clusters: connected regions of occupied grid cells.

The same mechanism serves the hypotheses of MCL and GMCL (clusters, as ROS amcl reports) and
CEAMCL's splitting rule (a species whose occupied cells form several regions splits).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from ceamcl.filters.base import Hypothesis
from ceamcl.pose import pose_covariance, pose_mean

_EIGHT = np.ones((3, 3), dtype=bool)
#: The largest bounding box :func:`cluster_labels` labels as a dense grid (50 MB of booleans).
DENSE_CELLS = 50_000_000


def cluster_labels(xy: ArrayLike, cell_m: float) -> tuple[NDArray[np.int64], int]:
    """Label points ``(N, 2)`` by the 8-connected region of ``cell_m`` cells they fall in.

    Returns ``(labels, count)``, labels in ``0..count-1``. Works in a bounding box of the
    points, so the cost depends on their spread, not on the map; points spread over more than
    :data:`DENSE_CELLS` cells (particles scattered kilometres apart by an absurd odometry jump
    or initial covariance) are labelled over their occupied cells only
    (:func:`pose_cluster_labels` with one heading cell).
    """
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), 0
    if not np.isfinite(p).all():
        raise ValueError("cluster_labels: a point is not finite")
    cells = np.floor(p / cell_m).astype(np.int64)
    lo = cells.min(axis=0)
    cells -= lo
    shape = tuple(int(v) + 1 for v in cells.max(axis=0))
    if shape[0] * shape[1] > DENSE_CELLS:
        flat = np.column_stack([p, np.zeros(p.shape[0])])
        return pose_cluster_labels(flat, cell_m, 2.0 * np.pi)
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
    how a species holding two heading modes (a pose and its mirror image) splits. Regions are
    numbered in the order of their first cell in the bounding box (x, then y, then heading), as
    ``scipy.ndimage.label`` numbers them (:func:`pose_cluster_labels_reference`). Compiled: a
    union-find over the occupied cells only (sorted keys, binary search for the neighbours), so
    the cost depends on the number of poses, not on their bounding box; it runs at every step
    for every species (docs/performance.md).
    """
    p = np.ascontiguousarray(poses, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), 0
    n_theta = max(1, int(np.floor(2.0 * np.pi / cell_rad)))
    keys, ny, status = _cell_keys(p, float(cell_m), n_theta)
    if status == _NOT_FINITE:
        raise ValueError("pose_cluster_labels: a pose is not finite")
    if status == _TOO_FAR:
        raise ValueError("pose_cluster_labels: poses spread too far for the cell size")
    # Sorting stays in NumPy: numba's own sort takes seconds to compile on a fresh machine.
    labels, count = _label_sorted(keys, np.argsort(keys), ny, n_theta)
    return labels, int(count)


#: :func:`_cell_keys`'s status codes (module constants, frozen into the compiled code)
_OK, _TOO_FAR, _NOT_FINITE = 0, -1, -2


@numba.njit(cache=True)
def _label_sorted(
    keys: NDArray[np.int64], order: NDArray[np.intp], ny: int, n_theta: int
) -> tuple[NDArray[np.int64], int]:
    """Each pose's region from its cell key and the order that sorts the keys: the distinct
    keys, then :func:`_label_cells`."""
    n = keys.shape[0]
    cells = np.empty(n, np.int64)  # the distinct keys, ascending
    cell_of = np.empty(n, np.int64)  # each pose's index into cells
    m = 0
    for r in range(n):
        i = order[r]
        if m == 0 or keys[i] != cells[m - 1]:
            cells[m] = keys[i]
            m += 1
        cell_of[i] = m - 1
    region, count = _label_cells(cells[:m], ny, n_theta)
    labels = np.empty(n, np.int64)
    for i in range(n):
        labels[i] = region[cell_of[i]]
    return labels, count


@numba.njit(cache=True)
def _cell_keys(
    p: NDArray[np.float64], cell_m: float, n_theta: int
) -> tuple[NDArray[np.int64], int, int]:
    """Each pose's cell (as :func:`pose_cluster_labels_reference` computes it) as the key
    ``(cx * ny + cy) * n_theta + ct`` in its bounding box, ``ny`` and a status: ``_OK``, or
    ``_TOO_FAR`` when the box has too many cells for the keys, ``_NOT_FINITE`` when a pose is
    not finite (the keys are then meaningless)."""
    n = p.shape[0]
    keys = np.empty(n, np.int64)
    cx = np.empty(n, np.int64)
    cy = np.empty(n, np.int64)
    ct = np.empty(n, np.int64)
    for i in range(n):
        if not (np.isfinite(p[i, 0]) and np.isfinite(p[i, 1]) and np.isfinite(p[i, 2])):
            return keys, 0, _NOT_FINITE
        fx, fy = np.floor(p[i, 0] / cell_m), np.floor(p[i, 1] / cell_m)
        if abs(fx) > 2.0**40 or abs(fy) > 2.0**40:
            return keys, 0, _TOO_FAR
        cx[i], cy[i] = np.int64(fx), np.int64(fy)
        ct[i] = np.int64(np.floor((p[i, 2] + np.pi) / (2.0 * np.pi) * n_theta)) % n_theta
    lo_x, hi_x, lo_y, hi_y = cx[0], cx[0], cy[0], cy[0]
    for i in range(1, n):
        lo_x, hi_x = min(lo_x, cx[i]), max(hi_x, cx[i])
        lo_y, hi_y = min(lo_y, cy[i]), max(hi_y, cy[i])
    nx, ny = hi_x - lo_x + 1, hi_y - lo_y + 1
    if float(nx) * float(ny) * float(n_theta) > 2.0**62 / 27.0:
        return keys, 0, _TOO_FAR
    for i in range(n):
        keys[i] = ((cx[i] - lo_x) * ny + (cy[i] - lo_y)) * n_theta + ct[i]
    return keys, ny, _OK


@numba.njit(cache=True)
def _find(parent: NDArray[np.int64], i: int) -> int:
    root = i
    while parent[root] != root:
        root = parent[root]
    while parent[i] != root:  # path compression
        nxt = parent[i]
        parent[i] = root
        i = nxt
    return root


@numba.njit(cache=True)
def _label_cells(cells: NDArray[np.int64], ny: int, n_theta: int) -> tuple[NDArray[np.int64], int]:
    """Connected regions (26-neighbourhood, heading periodic when ``n_theta > 2``) of the
    occupied cells, given by their distinct keys ``cells`` (ascending, see :func:`_cell_keys`);
    each cell's region, numbered by the region's lowest key (the raster order of
    ``ndimage.label``). Union-find; neighbours found by binary search in ``cells``."""
    m = cells.shape[0]
    parent = np.empty(m, np.int64)
    for c in range(m):
        parent[c] = c
    wrap = n_theta > 2
    for c in range(m):
        k = cells[c]
        t = k % n_theta
        y = (k // n_theta) % ny
        x = k // (n_theta * ny)
        for dx in range(-1, 2):
            xx = x + dx
            if xx < 0:
                continue
            for dy in range(-1, 2):
                yy = y + dy
                if yy < 0 or yy >= ny:
                    continue
                for dt in range(-1, 2):
                    tt = t + dt
                    if tt < 0 or tt >= n_theta:
                        if not wrap:
                            continue
                        tt %= n_theta
                    key = (xx * ny + yy) * n_theta + tt
                    if key <= k:
                        continue  # each pair once, from its lower key
                    lo, hi = c + 1, m  # binary search: the first cell >= key
                    while lo < hi:
                        mid = (lo + hi) // 2
                        if cells[mid] < key:
                            lo = mid + 1
                        else:
                            hi = mid
                    if lo < m and cells[lo] == key:
                        a, b = _find(parent, c), _find(parent, lo)
                        if a != b:
                            if a < b:
                                parent[b] = a
                            else:
                                parent[a] = b
    # Number the regions by their lowest cell (the root is the lowest: unions keep the lower).
    region = np.empty(m, np.int64)
    for c in range(m):
        region[c] = -1
    count = 0
    for c in range(m):
        r = _find(parent, c)
        if region[r] < 0:
            region[r] = count
            count += 1
        region[c] = region[r]
    return region, count


def pose_cluster_labels_reference(
    poses: ArrayLike, cell_m: float, cell_rad: float
) -> tuple[NDArray[np.int64], int]:
    """:func:`pose_cluster_labels` with SciPy's ``ndimage.label`` on a dense grid of the
    poses' bounding box, the heading wrap joined through a graph: the reference the compiled
    labelling is tested against (same labels, same numbering)."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), 0
    n_theta = max(1, int(np.floor(2.0 * np.pi / cell_rad)))
    xy = np.floor(p[:, :2] / cell_m).astype(np.int64)
    xy -= xy.min(axis=0)
    th = np.floor((p[:, 2] + np.pi) / (2.0 * np.pi) * n_theta).astype(np.int64) % n_theta
    shape = (int(xy[:, 0].max()) + 1, int(xy[:, 1].max()) + 1, n_theta)
    if shape[0] * shape[1] * shape[2] > 50_000_000:
        raise ValueError("pose_cluster_labels_reference: poses spread too far for the cell size")
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
