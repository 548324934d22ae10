"""Headings for the test poses from the scan's geometry (not in the paper; docs/ceamcl.md,
departure 27).

Section 3.1 draws test poses with uniform headings, so most of them point the scan the wrong
way: a pose whose heading is a few degrees off moves the end points of beams at 4 m by tens of
centimetres. The walls a scan sees and the walls the map holds share their directions: rotate
the scan's surface normals by the robot's heading and they fall on the map's. Correlating the
two histograms of normal directions (the map's once per map, the scan's once per search) gives
a density over the heading with peaks at the true heading and at the building's symmetries
(every quarter turn in a building of right angles). Test poses draw their headings from it,
mixed with a uniform share so that no heading goes unsearched where the correlation is wrong
(clutter, a scan of one wall, a building without dominant directions, where it is flat).

Nothing here evaluates the likelihood: the histograms cost one pass over the map's boundary
cells (cached per map) and one over the scan's beams.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ceamcl.angles import TWO_PI
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.scan import LaserScan, classify_ranges


@dataclass(frozen=True)
class HeadingPrior:
    """How test poses draw their headings: ``bins`` over the circle, histograms smoothed by
    ``smooth_rad``, a scan's normals estimated over chords of ``chord_m`` (end points at
    most ``gap_m`` apart count as one surface), and ``uniform_share`` of the mass spread
    uniformly over the circle. ``uniform_share=1`` gives the paper's uniform headings."""

    bins: int = 360
    smooth_rad: float = float(np.radians(3.0))
    chord_m: float = 0.2
    gap_m: float = 0.3
    uniform_share: float = 0.25

    def __post_init__(self) -> None:
        if not (self.bins >= 8 and self.smooth_rad > 0 and self.chord_m > 0 and self.gap_m > 0):
            raise ValueError(f"HeadingPrior: expected positive settings, got {self}")
        if not 0.0 <= self.uniform_share <= 1.0:
            raise ValueError(
                f"HeadingPrior.uniform_share: expected a share in [0, 1], got {self.uniform_share}"
            )


def heading_bins(angles: NDArray[np.float64], bins: int) -> NDArray[np.intp]:
    """The bin of each heading (bin ``s`` holds ``[s, s + 1) * 2 pi / bins``)."""
    return np.floor(np.mod(angles, TWO_PI) / TWO_PI * bins).astype(np.intp) % bins


def _histogram(
    angles: NDArray[np.float64], weights: NDArray[np.float64], prior: HeadingPrior
) -> NDArray[np.float64]:
    b = heading_bins(angles, prior.bins)
    hist = np.bincount(b, weights=weights, minlength=prior.bins).astype(np.float64)
    sigma_bins = prior.smooth_rad / TWO_PI * prior.bins
    return np.asarray(ndimage.gaussian_filter1d(hist, sigma_bins, mode="wrap"), dtype=np.float64)


def map_normal_histogram(grid: OccupancyGrid, prior: HeadingPrior) -> NDArray[np.float64]:
    """The directions (world frame) of the map's surface normals, pointing from each
    occupied cell that borders free space into the free side, one count per cell: what a
    robot inside can see. From the gradient of the occupancy smoothed over a cell; zeros where
    the map has no such cell. Computed once per map and histogram setting (kept with the
    grid, read-only)."""
    key = ("map normals", prior.bins, prior.smooth_rad)
    return grid.derived(key, lambda: _map_normals(grid, prior))


#: Tiles of the map in which :func:`_map_normals` smooths the occupancy, and the margin around
#: each: the Gaussian (sigma 1 cell, SciPy's radius 4) and the Sobel (radius 1) reach 5 cells.
NORMALS_TILE = 64
NORMALS_MARGIN = 6


def _boundary_cells(grid: OccupancyGrid) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Rows and columns, in raster order, of the occupied cells with a free cell among their
    eight neighbours: ``occupied & binary_dilation(free, 3 x 3)`` (cells outside the map are
    not free), from the occupied cells alone."""
    occ, free = grid.occupied_mask, grid.free_mask
    ys, xs = np.nonzero(occ)
    h, w = occ.shape
    near_free = np.zeros(ys.size, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            y, x = ys + dy, xs + dx
            inside = (y >= 0) & (y < h) & (x >= 0) & (x < w)
            hit = np.zeros(ys.size, dtype=bool)
            hit[inside] = free[y[inside], x[inside]]
            near_free |= hit
    return ys[near_free], xs[near_free]


def _map_normals(grid: OccupancyGrid, prior: HeadingPrior) -> NDArray[np.float64]:
    """:func:`_map_normals_reference` (its numbers, to the last bit) with the smoothing and the
    gradient taken only around the boundary cells, tile by tile: a map of tens of millions of
    cells holds a few thousand of them (SciPy's filters over the whole of fr-clinic's 40 M
    cells took 2.3 s). Each output of the Gaussian and the Sobel is a sum over its own
    window, so a tile cut out with :data:`NORMALS_MARGIN` cells around it (or up to the map's
    own edge, where the filters reflect as they do over the whole map) gives the same values
    at its boundary cells."""
    occ = grid.occupied_mask
    ys, xs = _boundary_cells(grid)
    gy = np.empty(ys.size)
    gx = np.empty(ys.size)
    if ys.size:
        h, w = occ.shape
        tile = (ys // NORMALS_TILE) * ((w + NORMALS_TILE - 1) // NORMALS_TILE) + xs // NORMALS_TILE
        order = np.argsort(tile, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(tile[order]) != 0])
        for members in np.split(order, starts[1:]):
            ty, tx = ys[members], xs[members]
            y0 = max(int(ty.min()) - NORMALS_MARGIN, 0)
            y1 = min(int(ty.max()) + NORMALS_MARGIN + 1, h)
            x0 = max(int(tx.min()) - NORMALS_MARGIN, 0)
            x1 = min(int(tx.max()) + NORMALS_MARGIN + 1, w)
            smooth = ndimage.gaussian_filter(occ[y0:y1, x0:x1].astype(np.float64), 1.0)
            gy[members] = ndimage.sobel(smooth, axis=0)[ty - y0, tx - x0]
            gx[members] = ndimage.sobel(smooth, axis=1)[ty - y0, tx - x0]
    return _normals_histogram(gx, gy, grid, prior)


def _map_normals_reference(grid: OccupancyGrid, prior: HeadingPrior) -> NDArray[np.float64]:
    """:func:`_map_normals` with the filters over the whole map (the reference it equals)."""
    occ = grid.occupied_mask
    boundary = occ & ndimage.binary_dilation(grid.free_mask, structure=np.ones((3, 3), bool))
    smooth = ndimage.gaussian_filter(occ.astype(np.float64), 1.0)
    gy = ndimage.sobel(smooth, axis=0)[boundary]  # rows are y (grid.cell_to_world)
    gx = ndimage.sobel(smooth, axis=1)[boundary]
    return _normals_histogram(gx, gy, grid, prior)


def _normals_histogram(
    gx: NDArray[np.float64], gy: NDArray[np.float64], grid: OccupancyGrid, prior: HeadingPrior
) -> NDArray[np.float64]:
    strong = np.hypot(gx, gy) > 1e-9
    # the normal points down the occupancy's slope, into free space
    angles = np.arctan2(-gy[strong], -gx[strong]) + grid.origin[2]
    hist = _histogram(angles, np.ones(angles.size), prior)
    hist.setflags(write=False)
    return hist


def scan_normals(
    scan: LaserScan, prior: HeadingPrior
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The directions (robot frame, rad) of the surfaces a scan ends on, pointing back at the
    laser, and the length of surface (m) each stands for. A normal is taken across a chord of
    about ``chord_m`` along consecutive end points no more than ``gap_m`` apart (so it does not
    bridge two objects); max-range, invalid and isolated readings give none."""
    none = np.zeros(0)
    r = scan.ranges
    usable, is_max = classify_ranges(r, scan.range_min, scan.range_max)
    ok = usable & ~is_max  # hits (REP 117)
    if int(ok.sum()) < 3:
        return none, none
    lx, ly, lyaw = scan.pose
    a = scan.angles[ok] + lyaw
    rr = r[ok]
    px = lx + rr * np.cos(a)
    py = ly + rr * np.sin(a)
    step = np.hypot(np.diff(px), np.diff(py))
    joined = step <= prior.gap_m
    # runs of end points joined by short steps are surfaces; arc length along each run
    run = np.concatenate([[0], np.cumsum(~joined)])
    arc = np.concatenate([[0.0], np.cumsum(np.where(joined, step, 0.0))])
    n = px.size
    # for each end point the first one at least chord_m further along its run
    j = np.searchsorted(arc, arc + prior.chord_m, side="left")
    j = np.minimum(j, n - 1)
    use = (run[j] == run) & (arc[j] - arc >= prior.chord_m * 0.999)
    if not use.any():
        return none, none
    i = np.flatnonzero(use)
    j = j[use]
    dx = px[j] - px[i]
    dy = py[j] - py[i]
    nx, ny = -dy, dx
    # point the normal back at the laser
    mx = 0.5 * (px[i] + px[j]) - lx
    my = 0.5 * (py[i] + py[j]) - ly
    flip = nx * mx + ny * my > 0
    nx = np.where(flip, -nx, nx)
    ny = np.where(flip, -ny, ny)
    # each end point stands for the surface between it and its successor
    weight = np.concatenate([np.where(joined, step, 0.0), [0.0]])[i]
    return np.arctan2(ny, nx), weight


def scan_normal_histogram(scan: LaserScan, prior: HeadingPrior) -> NDArray[np.float64]:
    """:func:`scan_normals` as a histogram over ``prior.bins`` directions, each weighted by the
    length of surface it stands for and smoothed by ``prior.smooth_rad``. Zeros where the scan
    gives no normal."""
    angles, weight = scan_normals(scan, prior)
    if angles.size == 0:
        return np.zeros(prior.bins)
    return _histogram(angles, weight, prior)


def facing_length(scan: LaserScan, prior: HeadingPrior, half_angle_rad: float) -> float:
    """How many metres of the surfaces a scan ends on face along the robot's x axis: their
    normals (:func:`scan_normals`) within ``half_angle_rad`` of straight ahead or straight
    behind. Surfaces that face the direction of travel are the ones that tell how far along it
    the robot is (CEAMCL's departure 44); a corridor's side walls face across it.

    CEAMCL asks it at every update of a lone species, so it is one compiled pass
    (:func:`_facing_length_kernel`, 0.01 ms for 360 beams against 0.07 ms in NumPy) with the
    operations of :func:`facing_length_reference`, which it equals but where a normal lies
    within rounding of ``half_angle_rad`` (the two libraries' cosines differ in the last bit)."""
    lx, ly, lyaw = scan.pose
    return float(
        _facing_length_kernel(
            np.ascontiguousarray(scan.ranges, dtype=np.float64),
            float(scan.angle_min),
            float(scan.angle_increment),
            float(lx),
            float(ly),
            float(lyaw),
            float(scan.range_min),
            float(scan.range_max),
            float(prior.chord_m),
            float(prior.gap_m),
            math.cos(half_angle_rad),
        )
    )


def facing_length_reference(scan: LaserScan, prior: HeadingPrior, half_angle_rad: float) -> float:
    """:func:`facing_length` in NumPy, from :func:`scan_normals` (the tests' reference)."""
    angles, weight = scan_normals(scan, prior)
    return float(weight[np.abs(np.cos(angles)) >= math.cos(half_angle_rad)].sum())


@numba.njit(cache=True)
def _facing_length_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    ranges, angle_min, angle_inc, lx, ly, lyaw, range_min, range_max, chord, gap, cos_half
):
    """:func:`facing_length_reference` in one pass: the hits' end points, their runs and arc
    lengths, each end point's chord, its normal turned back at the laser, and the sum of the
    surface lengths whose normal faces along the axis."""
    m = ranges.size
    px = np.empty(m)
    py = np.empty(m)
    n = 0
    for b in range(m):
        r = ranges[b]
        if r >= range_min and r < range_max:  # a hit (REP 117): not NaN, not max-range
            a = angle_min + angle_inc * b + lyaw
            px[n] = lx + r * math.cos(a)
            py[n] = ly + r * math.sin(a)
            n += 1
    if n < 3:
        return 0.0
    step = np.empty(n - 1)
    joined = np.empty(n - 1, dtype=np.bool_)
    run = np.empty(n, dtype=np.int64)
    arc = np.empty(n)
    run[0] = 0
    arc[0] = 0.0
    for k in range(n - 1):
        step[k] = math.hypot(px[k + 1] - px[k], py[k + 1] - py[k])
        joined[k] = step[k] <= gap
        run[k + 1] = run[k] + (0 if joined[k] else 1)
        arc[k + 1] = arc[k] + (step[k] if joined[k] else 0.0)
    total = 0.0
    j = 0
    for i in range(n):
        target = arc[i] + chord
        while j < n and arc[j] < target:  # searchsorted(arc, target, side="left")
            j += 1
        jj = min(j, n - 1)
        if run[jj] != run[i] or not arc[jj] - arc[i] >= chord * 0.999:
            continue
        weight = step[i] if i < n - 1 and joined[i] else 0.0
        if weight == 0.0:
            continue
        nx = -(py[jj] - py[i])
        ny = px[jj] - px[i]
        mx = 0.5 * (px[i] + px[jj]) - lx
        my = 0.5 * (py[i] + py[jj]) - ly
        if nx * mx + ny * my > 0:
            nx, ny = -nx, -ny
        if abs(math.cos(math.atan2(ny, nx))) >= cos_half:
            total += weight
    return total


def heading_density(
    map_hist: NDArray[np.float64], scan_hist: NDArray[np.float64], prior: HeadingPrior
) -> NDArray[np.float64]:
    """Probability of each heading bin (bin ``s`` is headings ``[s, s + 1) * 2 pi / bins``):
    the circular correlation of the map's normal histogram with the scan's, above its median
    (the level any heading reaches), normalised, mixed with ``uniform_share`` of uniform.
    Uniform where either histogram is empty or the correlation is flat."""
    b = prior.bins
    uniform = np.full(b, 1.0 / b)
    if not (map_hist.sum() > 0 and scan_hist.sum() > 0) or prior.uniform_share >= 1.0:
        return uniform
    # C[s] = sum_k map[k] scan[k - s]: the scan's normals turned by heading s
    corr = np.fft.irfft(np.fft.rfft(map_hist) * np.conj(np.fft.rfft(scan_hist)), n=b)
    corr = np.maximum(corr - np.median(corr), 0.0)
    total = corr.sum()
    if not (np.isfinite(total) and total > 0):
        return uniform
    u = prior.uniform_share
    return u * uniform + (1.0 - u) * corr / total


def scan_heading_density(
    grid: OccupancyGrid, scan: LaserScan, prior: HeadingPrior
) -> NDArray[np.float64]:
    """:func:`heading_density` of ``scan`` on ``grid`` (the map's normals kept with it)."""
    return heading_density(
        map_normal_histogram(grid, prior), scan_normal_histogram(scan, prior), prior
    )


def sample_headings(
    density: NDArray[np.float64], n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``n`` headings in ``[-pi, pi)`` drawn from a bin density (uniform within a bin)."""
    b = density.size
    cdf = np.cumsum(density)
    cdf /= cdf[-1]
    k = np.minimum(np.searchsorted(cdf, rng.random(n), side="right"), b - 1)
    theta = (k + rng.random(n)) * (TWO_PI / b)
    return np.mod(theta + np.pi, TWO_PI) - np.pi
