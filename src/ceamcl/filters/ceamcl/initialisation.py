"""Initial species generation (paper section 3.1).

1. ``N_test`` poses uniform over free space, each weighted by the first scan (fitness in
   (0, 1], see ``sensors.base.fitness``).
2. The x-y plane is cut into square cells (0.1 m in the paper). A cell's weight is the mean
   tempered fitness ``w^beta`` of its best ``cell_top_k`` test poses (NOTES.md: the plain mean
   over random headings dilutes a sharp likelihood), averaged over the 3 x 3 cells around it
   (NaN-aware), and scaled so the best cell scores 1. Why the tempering and the smoothing:
   with 10^6 test poses each 0.1 m cell holds ~47 random headings, 7.7 degrees apart, which
   moves beam end points at 4 m by ~0.5 m; a likelihood sharper than that makes a cell's best
   sample a matter of luck, so ``V`` comes out tiny and broken into islands (one image of the
   pose split into several species). ``beta = 0.16 = (0.2 / 0.5)^2`` gives the landscape a
   likelihood field with sigma 0.5 m would give; docs/ceamcl.md has the measurements.
3. ``V``: cells whose weight exceeds ``mu``. ``N_0 = eta |V| / mean weight of V`` (eq. 5).
4. The connected regions of ``V`` (4-neighbourhood, the city-block network) seed a partition of
   the grid into influence zones by city-block distance (SKIZ).
5. Part ``i`` receives ``N_0^(i) = N_0 * wbar(i) / sum_k wbar(k)`` samples (eq. 6), the test
   poses of the part with the largest weights; ``wbar(i)`` is the mean weight of the part's
   cells in ``V``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numba
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ceamcl import budget
from ceamcl.errors import InputWarning
from ceamcl.filters.headings import HeadingPrior, sample_headings, scan_heading_density
from ceamcl.filters.resampling import sanitise_log_likelihood
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.scan import LaserScan, PreparedScan
from ceamcl.sensors.search import judged

_FOUR = ndimage.generate_binary_structure(2, 1)

#: Memory per cell of the initialisation grid: top-k weights, counts, smoothed weights, V,
#: labels, the SKIZ partition and its distance-transform indices.
CELL_BYTES = 256


@dataclass(frozen=True)
class InitialisationConfig:
    """The settings of section 3.1 (``CEAMCLConfig().initialisation`` gives them with the
    paper's defaults): ``n_test`` test poses (``test_poses_per_m2`` of free space, where that
    is set; both rounds together at most ``n_test``) scored ``test_batch`` at a time, cells of
    ``cell_m``, threshold ``mu``, eq. 5 factor ``eta``, how a cell's weight is formed
    (``cell_top_k``, ``cell_fitness_exponent``, ``cell_smoothing``), the smallest viable
    species and the cap on the total sample size; a second round of test poses,
    ``refine_per_pose`` drawn around each of the best ``refine_share`` of the first with
    ``refine_sigma`` (x-y metres, heading radians); ``polish_rounds`` greedy moves of the
    chosen samples with ``polish_sigma`` halved each round; ``headings``: the first round's
    headings drawn from the scan's geometry (:mod:`~ceamcl.filters.headings`; ``None``:
    uniform, the paper's)."""

    n_test: int
    test_batch: int
    cell_m: float
    mu: float
    eta: float
    cell_top_k: int
    cell_fitness_exponent: float
    cell_smoothing: int
    min_species_size: int
    max_samples: int
    test_poses_per_m2: float | None = None
    refine_share: float = 0.0
    refine_per_pose: int = 0
    refine_sigma: tuple[float, float] = (0.1, 0.1)
    polish_rounds: int = 0
    polish_sigma: tuple[float, float] = (0.1, 0.06)
    headings: HeadingPrior | None = None

    def test_pose_count(self, free_area_m2: float) -> int:
        """How many test poses the first round gives a map with ``free_area_m2`` of free
        space: ``test_poses_per_m2`` per square metre (``None``: as many as the budget
        allows), at least 1, and at most what leaves the second round its share of the
        ``n_test`` budget (:meth:`refine_count`)."""
        cap = max(1, int(self.n_test / (1 + self.refine_share * self.refine_per_pose)))
        if self.test_poses_per_m2 is None:
            return cap
        return int(np.clip(round(self.test_poses_per_m2 * free_area_m2), 1, cap))

    def refine_count(self, first: int) -> int:
        """How many of a first round of ``first`` test poses the second round draws around:
        the best ``refine_share`` of them (at least one), as many as the ``n_test`` budget
        leaves ``refine_per_pose`` draws for; 0 without a second round."""
        if self.refine_share <= 0 or self.refine_per_pose <= 0 or first <= 0:
            return 0
        k = min(first, max(1, int(np.ceil(self.refine_share * first))))
        return max(0, min(k, (self.n_test - first) // self.refine_per_pose))


@dataclass(frozen=True, eq=False)
class CellGrid:
    """The x-y grid of section 3.1 laid over a map's bounding box."""

    x0: float
    y0: float
    cell_m: float
    nx: int
    ny: int

    @classmethod
    def over(cls, grid: OccupancyGrid, cell_m: float) -> CellGrid:
        """Cells of ``cell_m`` over the map's bounding box, where they fit the memory budget
        (:mod:`ceamcl.budget`, :data:`CELL_BYTES` each); over a larger map the side is the
        smallest multiple of ``cell_m`` that fits, with a warning (docs/robustness.md)."""
        xmin, xmax, ymin, ymax = grid.bounds
        max_cells = max(1, budget.current().memory_bytes // CELL_BYTES)
        side = cell_m
        factor = 1
        while True:
            nx = max(1, int(np.ceil((xmax - xmin) / side)))
            ny = max(1, int(np.ceil((ymax - ymin) / side)))
            if nx * ny <= max_cells:
                break
            factor = max(factor + 1, int(np.ceil(factor * np.sqrt(nx * ny / max_cells))))
            side = cell_m * factor
        if factor > 1:
            warnings.warn(
                f"CEAMCL initialisation grid: {cell_m:g} m cells over the map's "
                f"{xmax - xmin:.0f} m x {ymax - ymin:.0f} m would exceed the memory budget of "
                f"{budget.format_bytes(budget.current().memory_bytes)}; using {side:g} m cells",
                InputWarning,
                stacklevel=3,
            )
        return cls(xmin, ymin, side, nx, ny)

    def index(self, xy: NDArray[np.float64]) -> NDArray[np.intp]:
        """Flat cell index ``iy * nx + ix`` of points ``(N, 2)`` (clipped into the grid)."""
        ix = np.clip(np.floor((xy[:, 0] - self.x0) / self.cell_m).astype(np.intp), 0, self.nx - 1)
        iy = np.clip(np.floor((xy[:, 1] - self.y0) / self.cell_m).astype(np.intp), 0, self.ny - 1)
        return iy * self.nx + ix


@dataclass(frozen=True, eq=False)
class InitialSpecies:
    """What section 3.1 produces, with its intermediate results for plots and tests.

    ``poses``/``loglik``/``fitness``/``labels`` are the selected samples and their species
    (``0..n_species-1``). ``cell_weight`` is the scaled grid (NaN where no test pose fell),
    ``in_v`` the set ``V``, ``seeds`` the connected regions of ``V`` and ``partition`` the SKIZ
    label of every cell (both ``(ny, nx)``, labels from 1).
    """

    poses: NDArray[np.float64]
    loglik: NDArray[np.float64]
    fitness: NDArray[np.float64]
    labels: NDArray[np.int64]
    n_species: int
    n0: int
    v_size: int
    v_mean_weight: float
    cells: CellGrid
    cell_weight: NDArray[np.float64]
    in_v: NDArray[np.bool_]
    seeds: NDArray[np.int32]
    partition: NDArray[np.int32]


@numba.njit(cache=True)
def _top_k_mean_kernel(
    cell: NDArray[np.intp], value: NDArray[np.float64], n_cells: int, k: int
) -> NDArray[np.float64]:
    """One pass keeping each cell's ``k`` largest values in descending order; their sum is
    taken largest first, the order in which a sort-then-bincount would add them. Only the
    cells that hold a value keep a row of ``k`` (a big map's grid holds tens of millions of
    cells and a few hundred thousand test poses): until the means are written, the output
    holds each such cell's row number."""
    out = np.full(n_cells, np.nan)
    where = np.empty(cell.shape[0], dtype=np.int64)  # the cell of each row
    m = 0
    for i in range(cell.shape[0]):
        c = cell[i]
        if np.isnan(out[c]):
            out[c] = m
            where[m] = c
            m += 1
    best = np.full((m, k), -np.inf)
    count = np.zeros(m, dtype=np.int64)
    for i in range(cell.shape[0]):
        s = int(out[cell[i]])
        v = value[i]
        pos = count[s]
        if pos < k:
            count[s] = pos + 1
        elif v > best[s, k - 1]:
            pos = k - 1
        else:
            continue
        while pos > 0 and v > best[s, pos - 1]:
            best[s, pos] = best[s, pos - 1]
            pos -= 1
        best[s, pos] = v
    for s in range(m):
        acc = 0.0
        for r in range(count[s]):
            acc += best[s, r]
        out[where[s]] = acc / count[s]
    return out


def top_k_mean_per_cell(
    cell: NDArray[np.intp], value: NDArray[np.float64], n_cells: int, k: int
) -> NDArray[np.float64]:
    """Mean of the ``k`` largest values in each cell (fewer where a cell has fewer); NaN where
    a cell is empty. Compiled, O(N k); :func:`top_k_mean_per_cell_reference` is the sort-based
    NumPy version the tests hold it to."""
    return _top_k_mean_kernel(  # type: ignore[no-any-return,unused-ignore]
        np.ascontiguousarray(cell, dtype=np.intp),
        np.ascontiguousarray(value, dtype=np.float64),
        int(n_cells),
        int(k),
    )


def top_k_mean_per_cell_reference(
    cell: NDArray[np.intp], value: NDArray[np.float64], n_cells: int, k: int
) -> NDArray[np.float64]:
    """Sort-based reference of :func:`top_k_mean_per_cell`."""
    order = np.lexsort((-value, cell))
    c_sorted = cell[order]
    v_sorted = value[order]
    starts = np.searchsorted(c_sorted, np.arange(n_cells))
    rank = np.arange(c_sorted.size) - starts[c_sorted]
    keep = rank < k
    sums = np.bincount(c_sorted[keep], weights=v_sorted[keep], minlength=n_cells)
    counts = np.bincount(c_sorted[keep], minlength=n_cells)
    out = np.full(n_cells, np.nan)
    nz = counts > 0
    out[nz] = sums[nz] / counts[nz]
    return out


def best_in_parts(
    part: NDArray[np.int32], score: NDArray[np.float64], sizes: NDArray[np.int64]
) -> list[NDArray[np.intp]]:
    """For each part ``s`` (labels ``1..len(sizes)`` in ``part``), the indices of its
    ``sizes[s - 1]`` highest scores, highest first, ties by index: exactly what a stable
    ``argsort(-score)`` filtered by part gives, without sorting all ``N`` scores."""
    out = []
    # the members of every part at once, ascending within each part (one stable sort instead
    # of a scan of all N labels per part: regions number in the hundreds on a big map)
    order = np.argsort(part, kind="stable")
    bounds = np.searchsorted(part[order], np.arange(1, sizes.size + 2))
    for s, size in enumerate(sizes.tolist(), start=1):
        members = order[bounds[s - 1] : bounds[s]]
        vals = score[members]
        k = min(int(size), members.size)
        if k == 0:
            out.append(members[:0])
            continue
        if k < members.size:
            kth = np.partition(vals, members.size - k)[members.size - k]  # k-th largest
            keep = vals > kth
            ties = np.flatnonzero(vals == kth)
            keep[ties[: k - int(keep.sum())]] = True
            members, vals = members[keep], vals[keep]
        out.append(members[np.lexsort((members, -vals))])
    return out


@numba.njit(cache=True, inline="always")
def _finite_or_zero(weight: NDArray[np.float64], i: int, j: int) -> tuple[float, float]:
    """A cell's weight and count for the NaN-aware mean (0 and 0 outside or where empty)."""
    if i < 0 or j < 0 or i >= weight.shape[0] or j >= weight.shape[1]:
        return 0.0, 0.0
    w = weight[i, j]
    if np.isfinite(w):
        return w, 1.0
    return 0.0, 0.0


@numba.njit(cache=True)
def _smooth_kernel(weight: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """:func:`smooth_cells_reference` in one compiled pass, operation for operation: SciPy's
    ``uniform_filter`` (``mode="constant"``) keeps a running sum along axis 0, then along
    axis 1, adding ``entering - leaving`` at each step and dividing by ``size`` for the
    output; this repeats its roundings, so the result is the reference's to the last bit.
    Axis 0's running sums advance a row at a time and each row is finished along axis 1 at
    once, so only the output is as large as the grid."""
    ny, nx = weight.shape
    before = size // 2
    after = size - before - 1
    run_val = np.zeros(nx)
    run_cnt = np.zeros(nx)
    col_val = np.empty(nx)
    col_cnt = np.empty(nx)
    out = np.full((ny, nx), np.nan)
    for r in range(size):
        for j in range(nx):
            a, b = _finite_or_zero(weight, r - before, j)
            run_val[j] += a
            run_cnt[j] += b
    for i in range(ny):
        if i > 0:
            for j in range(nx):
                ea, eb = _finite_or_zero(weight, i + after, j)
                la, lb = _finite_or_zero(weight, i - 1 - before, j)
                run_val[j] += ea - la
                run_cnt[j] += eb - lb
        for j in range(nx):
            col_val[j] = run_val[j] / size
            col_cnt[j] = run_cnt[j] / size
        tv = 0.0
        tc = 0.0
        for r in range(size):
            src = r - before
            tv += col_val[src] if 0 <= src < nx else 0.0
            tc += col_cnt[src] if 0 <= src < nx else 0.0
        for j in range(nx):
            if j > 0:
                enter = j + after
                leave = j - 1 - before
                tv += (col_val[enter] if enter < nx else 0.0) - (
                    col_val[leave] if leave >= 0 else 0.0
                )
                tc += (col_cnt[enter] if enter < nx else 0.0) - (
                    col_cnt[leave] if leave >= 0 else 0.0
                )
            if np.isfinite(weight[i, j]):
                out[i, j] = (tv / size) / max(tc / size, 1e-12)
    return out


def smooth_cells(weight: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """Mean over the ``size x size`` neighbourhood of each non-empty cell, ignoring empty (NaN)
    cells; empty cells stay NaN. ``size <= 1`` returns the input. Compiled
    (:func:`_smooth_kernel`); equal to :func:`smooth_cells_reference` bit for bit, in a
    fraction of its time on a big map (0.34 s for SciPy's filters over the 10 M cells of a
    hospital campus)."""
    if size <= 1:
        return weight
    out: NDArray[np.float64] = _smooth_kernel(
        np.ascontiguousarray(weight, dtype=np.float64), int(size)
    )
    return out


def smooth_cells_reference(weight: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """:func:`smooth_cells` with SciPy's ``uniform_filter`` (the reference it equals)."""
    if size <= 1:
        return weight
    valid = np.isfinite(weight)
    num = ndimage.uniform_filter(np.where(valid, weight, 0.0), size, mode="constant")
    den = ndimage.uniform_filter(valid.astype(np.float64), size, mode="constant")
    return np.where(valid, num / np.maximum(den, 1e-12), np.nan)


@numba.njit(cache=True)
def _skiz_kernel(seeds: NDArray[np.int32]) -> NDArray[np.int32]:
    """:func:`skiz_partition_reference` compiled, step for step: SciPy's chamfer transform
    (``distance_transform_cdt``, taxicab) passes over the cells in raster order taking the
    cell above, then the one to the left, where it is strictly nearer; then in reverse raster
    order the cell below, then the one to the right. It carries each cell's nearest seed; we
    carry that seed's label, which is all the partition keeps, so ties fall as there."""
    ny, nx = seeds.shape
    dist = np.empty((ny, nx), dtype=np.int32)
    label = np.empty((ny, nx), dtype=np.int32)
    for i in range(ny):
        for j in range(nx):
            dist[i, j] = 0 if seeds[i, j] != 0 else -1
            label[i, j] = seeds[i, j]
    for i in range(ny):
        for j in range(nx):
            d = dist[i, j]
            if d == 0:
                continue
            best = d
            lab = label[i, j]
            if i > 0:
                t = dist[i - 1, j]
                if t >= 0 and (best < 0 or t + 1 < best):
                    best = t + 1
                    lab = label[i - 1, j]
            if j > 0:
                t = dist[i, j - 1]
                if t >= 0 and (best < 0 or t + 1 < best):
                    best = t + 1
                    lab = label[i, j - 1]
            dist[i, j] = best
            label[i, j] = lab
    for i in range(ny - 1, -1, -1):
        for j in range(nx - 1, -1, -1):
            d = dist[i, j]
            if d == 0:
                continue
            best = d
            lab = label[i, j]
            if i < ny - 1:
                t = dist[i + 1, j]
                if t >= 0 and (best < 0 or t + 1 < best):
                    best = t + 1
                    lab = label[i + 1, j]
            if j < nx - 1:
                t = dist[i, j + 1]
                if t >= 0 and (best < 0 or t + 1 < best):
                    best = t + 1
                    lab = label[i, j + 1]
            dist[i, j] = best
            label[i, j] = lab
    return label


def skiz_partition(seeds: NDArray[np.int32]) -> NDArray[np.int32]:
    """Influence zones of labelled seed regions under the city-block distance: every cell gets
    the label of its nearest seed cell (ties go to the seed found first by the transform).
    Compiled (:func:`_skiz_kernel`); equal to :func:`skiz_partition_reference`, ties
    included."""
    if seeds.max(initial=0) == 0:
        return np.zeros_like(seeds)
    out: NDArray[np.int32] = _skiz_kernel(np.ascontiguousarray(seeds, dtype=np.int32))
    return out


def skiz_partition_reference(seeds: NDArray[np.int32]) -> NDArray[np.int32]:
    """:func:`skiz_partition` with SciPy's chamfer distance transform (the reference)."""
    if seeds.max(initial=0) == 0:
        return np.zeros_like(seeds)
    _, (iy, ix) = ndimage.distance_transform_cdt(seeds == 0, metric="taxicab", return_indices=True)
    return seeds[iy, ix].astype(np.int32)


@numba.njit(cache=True)
def _scale_kernel(weight: NDArray[np.float64], mu: float) -> NDArray[np.bool_]:
    best = -np.inf
    for w in weight:
        if np.isfinite(w) and w > best:
            best = w
    uniform = not best > 0.0  # no cell, or none above 0: every non-empty cell weighs 1
    if uniform:
        best = 1.0
    big = np.finfo(np.float64).max
    in_v = np.empty(weight.size, dtype=np.bool_)
    for c in range(weight.size):
        w = weight[c]
        if uniform and not np.isnan(w):
            w = 1.0
        x = w / best
        weight[c] = x
        if np.isnan(x):
            x = 0.0
        elif x == np.inf:
            x = big
        elif x == -np.inf:
            x = -big
        in_v[c] = x > mu
    return in_v


def scale_cells(
    weight: NDArray[np.float64], mu: float, *, in_place: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The cells' weights scaled so the best scores 1 (every non-empty cell 1 where none
    scores above 0), and ``V``, the cells above ``mu`` (empty cells count 0): one compiled
    pass instead of NumPy's five over every cell of the grid; ``in_place`` writes the scaled
    weights over ``weight`` (a float64 contiguous array) instead of a copy."""
    scaled = weight if in_place else np.array(weight, dtype=np.float64, order="C")
    in_v = _scale_kernel(scaled, float(mu))
    return scaled, in_v


def region_means(
    values: NDArray[np.float64], labels: NDArray[np.int32], cells: NDArray[np.intp], n: int
) -> NDArray[np.float64]:
    """Mean of ``values`` over each labelled region ``1..n``, from the region's ``cells``
    (flat indices, ascending: every cell with a label > 0 and no other): what
    ``ndimage.mean(values, labels, index=arange(1, n + 1))`` gives, to the last bit (it adds
    with ``bincount`` in the same order), without a pass over the unlabelled cells."""
    lab = labels[cells]
    sums = np.bincount(lab, weights=values[cells], minlength=n + 1)[1:]
    counts = np.bincount(lab, minlength=n + 1)[1:]
    out: NDArray[np.float64] = sums / counts
    return out


def generate_initial_species(
    grid: OccupancyGrid,
    test_poses: NDArray[np.float64],
    test_loglik: NDArray[np.float64],
    test_fitness: NDArray[np.float64],
    config: InitialisationConfig,
) -> InitialSpecies:
    """Steps 2-5 of section 3.1 on weighted test poses (step 1: :func:`sample_test_poses`
    and :func:`score_test_poses`)."""
    cell_m, mu, eta = config.cell_m, config.mu, config.eta
    cell_top_k, fitness_exponent = config.cell_top_k, config.cell_fitness_exponent
    smoothing_cells, min_species_size = config.cell_smoothing, config.min_species_size
    max_samples = config.max_samples
    cells = CellGrid.over(grid, cell_m)
    n_cells = cells.nx * cells.ny
    idx = cells.index(test_poses[:, :2])
    tempered = np.power(np.clip(test_fitness, 0.0, 1.0), fitness_exponent)
    weight = top_k_mean_per_cell(idx, tempered, n_cells, cell_top_k)
    weight = smooth_cells(weight.reshape(cells.ny, cells.nx), smoothing_cells).reshape(-1)
    # every array here is as large as the grid, tens of millions of cells on a big map: the
    # weights are scaled where they stand, and the labels are not copied
    scaled, in_v = scale_cells(weight, mu, in_place=True)
    v_cells = np.flatnonzero(in_v)
    v_size = int(v_cells.size)
    v_mean = float(np.mean(scaled[v_cells])) if v_size else 1.0
    n0 = int(np.clip(round(eta * v_size / v_mean), 1, max_samples))  # eq. 5

    grid2d_v = in_v.reshape(cells.ny, cells.nx)
    seeds, n_regions = ndimage.label(grid2d_v, structure=_FOUR)
    seeds = seeds.astype(np.int32, copy=False)
    partition = skiz_partition(seeds)
    part_of_test = partition.reshape(-1)[idx]

    region_weight = region_means(scaled, seeds.reshape(-1), v_cells, n_regions)
    share = region_weight / region_weight.sum()  # eq. 6
    sizes = np.maximum(np.round(n0 * share).astype(np.int64), min_species_size)

    chosen = best_in_parts(part_of_test, test_loglik, sizes)
    labels = [np.full(take.size, s, dtype=np.int64) for s, take in enumerate(chosen)]
    sel = np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.intp)
    return InitialSpecies(
        poses=test_poses[sel].copy(),
        loglik=test_loglik[sel].copy(),
        fitness=test_fitness[sel].copy(),
        labels=np.concatenate(labels) if labels else np.zeros(0, dtype=np.int64),
        n_species=n_regions,
        n0=n0,
        v_size=v_size,
        v_mean_weight=v_mean,
        cells=cells,
        cell_weight=scaled.reshape(cells.ny, cells.nx),
        in_v=grid2d_v,
        seeds=seeds,
        partition=partition,
    )


def sample_test_poses(
    grid: OccupancyGrid,
    config: InitialisationConfig,
    rng: np.random.Generator,
    headings: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Step 1 of section 3.1: poses uniform over free space, ``test_poses_per_m2`` per
    square metre of it, at most ``n_test``; with ``headings`` (a density over heading bins,
    :func:`~ceamcl.filters.headings.heading_density`) their headings drawn from it
    instead of uniformly."""
    poses = grid.sample_free_poses(config.test_pose_count(grid.free_area_m2), rng)
    if headings is not None:
        poses[:, 2] = sample_headings(headings, poses.shape[0], rng)
    return poses


def heading_proposal(
    grid: OccupancyGrid,
    scan: LaserScan | None,
    config: InitialisationConfig,
) -> NDArray[np.float64] | None:
    """The density the first round draws its headings from (``None``: uniform headings,
    where ``config.headings`` is unset or there is no scan)."""
    prior = config.headings
    if prior is None or scan is None:
        return None
    return scan_heading_density(grid, scan, prior)


def refine_test_poses(
    grid: OccupancyGrid,
    test_poses: NDArray[np.float64],
    test_loglik: NDArray[np.float64],
    config: InitialisationConfig,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """A second round of test poses (not in the paper; docs/ceamcl.md, departure 20):
    ``refine_per_pose`` Gaussian draws (``refine_sigma``) around each of the best
    ``refine_share`` of the first round's poses (at least one), those in free space. A sparse
    first round finds every place that fits the scan somewhere near its peak; the second
    puts test poses at the peaks, so the cells of section 3.1 weigh a place by how well it
    can fit rather than by how near a uniform draw happened to fall. With the first round,
    at most ``n_test`` (:meth:`InitialisationConfig.refine_count`)."""
    k = config.refine_count(test_poses.shape[0])
    if k == 0:
        return test_poses[:0]
    best = np.sort(np.argpartition(-test_loglik, k - 1)[:k])
    centres = np.repeat(test_poses[best], config.refine_per_pose, axis=0)
    sxy, sth = config.refine_sigma
    drawn = gaussian_step(centres, np.array([sxy, sxy, sth]), rng)
    return drawn[grid.is_free(drawn[:, 0], drawn[:, 1])]


def gaussian_step(
    poses: NDArray[np.float64], sigma: NDArray[np.float64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """Each pose moved by one Gaussian draw with standard deviations ``sigma`` (x, y,
    heading), the heading wrapped: the second round's draws and :func:`polish`'s moves."""
    moved = poses + rng.standard_normal(poses.shape) * sigma
    moved[:, 2] = np.arctan2(np.sin(moved[:, 2]), np.cos(moved[:, 2]))
    return moved


def with_second_round(
    grid: OccupancyGrid,
    test_poses: NDArray[np.float64],
    test_loglik: NDArray[np.float64],
    test_fitness: NDArray[np.float64],
    sensor: SensorModel,
    prepared: PreparedScan | None,
    config: InitialisationConfig,
    rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]:
    """The scored first round with :func:`refine_test_poses`' second round scored and
    appended (unchanged where there is none): poses, log-likelihoods, fitness and the
    evaluations the second round spent."""
    more = refine_test_poses(grid, test_poses, test_loglik, config, rng)
    if more.shape[0] == 0:
        return test_poses, test_loglik, test_fitness, 0
    ll, fit, spent = score_test_poses(more, sensor, prepared, config)
    return (
        np.vstack([test_poses, more]),
        np.concatenate([test_loglik, ll]),
        np.concatenate([test_fitness, fit]),
        spent,
    )


def polish(
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    sensor: SensorModel,
    prepared: PreparedScan | None,
    config: InitialisationConfig,
    rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Greedy moves of the chosen initial samples: ``polish_rounds`` rounds, each proposing
    one Gaussian step per sample (``polish_sigma``, halved each round) and keeping it where
    the first scan scores it higher (as a motion update may, a move can end a few centimetres
    inside an obstacle or unknown cell). With fewer test poses the best of a region lies farther
    from its likelihood peak; a few moves bring it there for a few evaluations a sample
    (docs/ceamcl.md, "test poses"). Returns the poses, their log-likelihoods and the
    evaluations spent."""
    n = poses.shape[0]
    if config.polish_rounds == 0 or n == 0 or prepared is None or prepared.n_beams == 0:
        return poses, loglik, 0
    poses, loglik = poses.copy(), loglik.copy()
    sxy, sth = config.polish_sigma
    sigma = np.array([sxy, sxy, sth])
    evaluations = 0
    for _ in range(config.polish_rounds):
        trial = gaussian_step(poses, sigma, rng)
        ll = sanitise_log_likelihood(sensor.log_likelihood(trial, prepared))
        evaluations += n
        better = ll > loglik
        poses[better] = trial[better]
        loglik[better] = ll[better]
        sigma = sigma / 2
    return poses, loglik, evaluations


def score_test_poses(
    test_poses: NDArray[np.float64],
    sensor: SensorModel,
    prepared: PreparedScan | None,
    config: InitialisationConfig,
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Step 1 of section 3.1: the test poses' log-likelihoods (``test_batch`` per call, which
    bounds memory) and fitness, and the evaluations spent. Without a usable beam (``prepared``
    None or empty) every pose is equally fit."""
    n = test_poses.shape[0]
    if prepared is None or prepared.n_beams == 0:
        ll = np.zeros(n)
        evaluations = 0
    else:
        ll = sanitise_log_likelihood(
            np.concatenate(
                [
                    sensor.log_likelihood(test_poses[i : i + config.test_batch], prepared)
                    for i in range(0, n, config.test_batch)
                ]
            )
        )
        evaluations = n
    fit = np.ones(n) if prepared is None else fitness(ll, prepared, sensor)
    return ll, fit, evaluations


def initial_species(
    grid: OccupancyGrid,
    sensor: SensorModel,
    prepared: PreparedScan | None,
    config: InitialisationConfig,
    rng: np.random.Generator,
    headings: NDArray[np.float64] | None = None,
    judge: tuple[SensorModel, PreparedScan] | None = None,
) -> tuple[InitialSpecies, int]:
    """Section 3.1 whole: test poses (with the second round of :func:`refine_test_poses`
    where the scan has beams to score them), their scores, the species; and the evaluations
    spent. ``headings``: the density of :func:`heading_proposal` (``None``: uniform).
    ``judge``: the filter's own model and its scan when ``sensor`` is a cheaper search model:
    the best of the test poses under ``sensor`` (:func:`~ceamcl.sensors.search.judged`) are
    scored again with it, and the species are formed from those scores alone (docs/ceamcl.md,
    departure 29)."""
    test = sample_test_poses(grid, config, rng, headings if prepared is not None else None)
    ll, fit, evaluations = score_test_poses(test, sensor, prepared, config)
    if evaluations:
        refine = config
        if judge is not None:
            sensor, prepared = judge
            first = ll.size
            test = test[judged(ll)]
            ll, fit, spent = score_test_poses(test, sensor, prepared, config)
            evaluations += spent
            # the second round draws around as many of the judged poses as it would have
            # drawn around of the whole first round
            share = config.refine_share * first / test.shape[0]
            refine = replace(config, refine_share=min(1.0, share))
        test, ll, fit, spent = with_second_round(grid, test, ll, fit, sensor, prepared, refine, rng)
        evaluations += spent
    return generate_initial_species(grid, test, ll, fit, config), evaluations
