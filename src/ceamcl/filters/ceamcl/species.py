"""Per-species statistics, vectorised where it pays: sizes, fitness, means, living domains.

Species are identified by integer ids; particles carry the id of their species. Everything
here is computed from arrays ``poses (N, 3)``, ``species (N,)``, ``loglik (N,)`` and
``fitness (N,)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ceamcl.angles import wrap, wrap_one
from ceamcl.filters.clustering import pose_cluster_labels
from ceamcl.filters.resampling import (
    c_library,
    label_segments,
    segment_max,
    segment_sum,
    segment_weights,
    segment_weights_into,
)


@dataclass(frozen=True, eq=False)
class SpeciesStats:
    """One species at one instant."""

    species_id: int
    members: NDArray[np.intp]
    weights: NDArray[np.float64]  # importance weights of the members, normalised in the species
    mean: NDArray[np.float64]  # weighted mean pose (circular heading)
    covariance: NDArray[np.float64]  # weighted 3 x 3 covariance
    cov_xy: NDArray[np.float64]  # unweighted x-y covariance of the individuals (living domain)
    heading_sd: float
    fitness: float  # mean fitness of the individuals, in (0, 1]
    domain_variances: NDArray[np.float64]
    domain_axes: NDArray[np.float64]
    area_m2: float
    best_fitness: float = float("nan")  # the fittest individual's (NaN: not computed)

    @property
    def n(self) -> int:
        return int(self.members.size)


def all_species_stats(
    species: NDArray[np.int64],
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    fitness: NDArray[np.float64],
) -> dict[int, SpeciesStats]:
    """:class:`SpeciesStats` of every species, in ascending id order.

    Every species' sums come from one compiled pass over the particles sorted by species
    (:func:`_species_moments`), which adds in the order ``np.add.reduceat`` does, so the
    numbers are those of :func:`all_species_stats_reference`, its NumPy form, to the last bit
    (docs/performance.md); they agree to rounding with ``pose_mean``, ``pose_covariance``,
    ``np.cov``, :func:`~ceamcl.filters.ceamcl.competition.living_domain` and
    ``circular_variance`` applied to each species alone.
    """
    if species.size == 0:
        return {}
    order, ids, starts, counts = label_segments(species)
    w, mean, cov, cov_xy, heading_sd, fit, best = _species_moments(
        np.ascontiguousarray(poses[order], dtype=np.float64),
        np.ascontiguousarray(loglik[order], dtype=np.float64),
        np.ascontiguousarray(fitness[order], dtype=np.float64),
        np.asarray(starts, dtype=np.intp),
        np.asarray(counts, dtype=np.intp),
    )
    domains = living_domains(cov_xy)
    return _collect(
        ids, order, starts, counts, w, mean, cov, cov_xy, heading_sd, fit, best, domains
    )


def _collect(
    ids: NDArray[np.int64],
    order: NDArray[np.intp],
    starts: NDArray[np.intp],
    counts: NDArray[np.intp],
    w: NDArray[np.float64],
    mean: NDArray[np.float64],
    cov: NDArray[np.float64],
    cov_xy: NDArray[np.float64],
    heading_sd: NDArray[np.float64],
    fit: NDArray[np.float64],
    best: NDArray[np.float64],
    domains: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
) -> dict[int, SpeciesStats]:
    """The stats of every species from the per-species sums and ``domains``, the living
    domains of ``cov_xy`` (:func:`living_domains`, or its NumPy reference for the reference)."""
    dv, axes, area = domains
    out: dict[int, SpeciesStats] = {}
    for k, sid in enumerate(ids.tolist()):
        a, b = int(starts[k]), int(starts[k] + counts[k])
        out[int(sid)] = SpeciesStats(
            species_id=int(sid),
            members=order[a:b],
            weights=w[a:b],
            mean=mean[k],
            covariance=cov[k],
            cov_xy=cov_xy[k],
            heading_sd=float(heading_sd[k]),
            fitness=float(fit[k]),
            best_fitness=float(best[k]),
            domain_variances=dv[k],
            domain_axes=axes[k],
            area_m2=float(area[k]),
        )
    return out


_PI_SQUARED = float(np.pi**2)


@numba.njit(cache=True)
def _species_moments(p, ll, fitness, starts, counts):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The sums of :func:`all_species_stats_reference` for particles sorted by species
    (``p``, ``ll``, ``fitness``; species ``k`` owns ``[starts[k], starts[k] + counts[k])``):
    in-species weights, weighted mean pose and covariance, unweighted x-y covariance, circular
    heading spread, mean and best fitness. Every elementwise operation is the reference's,
    in its order, and every sum is a :func:`~ceamcl.filters.resampling.segment_sum`."""
    n_all = p.shape[0]
    n_species = starts.size
    w = np.empty(n_all)
    buf = np.empty(n_all)
    dx = np.empty(n_all)
    dy = np.empty(n_all)
    dth = np.empty(n_all)
    mean = np.empty((n_species, 3))
    cov = np.empty((n_species, 3, 3))
    cov_xy = np.empty((n_species, 2, 2))
    heading_sd = np.empty(n_species)
    fit = np.empty(n_species)
    best = np.empty(n_species)
    for k in range(n_species):
        s = starts[k]
        e = s + counts[k]
        n = float(counts[k])
        segment_weights_into(ll, s, e, buf, w)  # in-species weights
        # weighted mean pose, circular heading
        for i in range(s, e):
            buf[i] = w[i] * np.sin(p[i, 2])
        sw = segment_sum(buf, s, e)
        for i in range(s, e):
            buf[i] = w[i] * np.cos(p[i, 2])
        cw = segment_sum(buf, s, e)
        for i in range(s, e):
            buf[i] = w[i] * p[i, 0]
        mx = segment_sum(buf, s, e)
        for i in range(s, e):
            buf[i] = w[i] * p[i, 1]
        my = segment_sum(buf, s, e)
        mth = 0.0 if (sw == 0.0 and cw == 0.0) else np.arctan2(sw, cw)
        mean[k, 0] = mx
        mean[k, 1] = my
        mean[k, 2] = mth
        # weighted covariance, heading deviations wrapped to (-pi, pi]
        for i in range(s, e):
            dx[i] = p[i, 0] - mx
            dy[i] = p[i, 1] - my
            dth[i] = wrap_one(p[i, 2] - mth)
        for a in range(3):
            da = dx if a == 0 else (dy if a == 1 else dth)
            for b in range(a, 3):
                db = dx if b == 0 else (dy if b == 1 else dth)
                for i in range(s, e):
                    buf[i] = w[i] * da[i] * db[i]
                c = segment_sum(buf, s, e)
                cov[k, a, b] = c
                cov[k, b, a] = c
        # unweighted x-y covariance of the individuals (np.cov, ddof 1)
        for i in range(s, e):
            buf[i] = p[i, 0]
        ux = segment_sum(buf, s, e) / n
        for i in range(s, e):
            buf[i] = p[i, 1]
        uy = segment_sum(buf, s, e) / n
        for i in range(s, e):
            dx[i] = p[i, 0] - ux
            dy[i] = p[i, 1] - uy
        dof = max(n - 1.0, 1.0)
        if counts[k] < 2:
            cov_xy[k, 0, 0] = cov_xy[k, 0, 1] = cov_xy[k, 1, 0] = cov_xy[k, 1, 1] = 0.0
        else:
            for i in range(s, e):
                buf[i] = dx[i] * dx[i]
            cov_xy[k, 0, 0] = segment_sum(buf, s, e) / dof
            for i in range(s, e):
                buf[i] = dy[i] * dy[i]
            cov_xy[k, 1, 1] = segment_sum(buf, s, e) / dof
            for i in range(s, e):
                buf[i] = dx[i] * dy[i]
            c = segment_sum(buf, s, e) / dof
            cov_xy[k, 0, 1] = c
            cov_xy[k, 1, 0] = c
        # unweighted circular spread of the headings
        for i in range(s, e):
            buf[i] = np.sin(p[i, 2])
        ss = segment_sum(buf, s, e)
        for i in range(s, e):
            buf[i] = np.cos(p[i, 2])
        cs = segment_sum(buf, s, e)
        r = np.hypot(ss, cs) / n
        if r < 1e-300:
            r = 1e-300
        if r > 1.0:
            r = 1.0
        v = -2.0 * np.log(r)
        if v > _PI_SQUARED:
            v = _PI_SQUARED
        heading_sd[k] = np.sqrt(v)
        for i in range(s, e):
            buf[i] = fitness[i]
        fit[k] = segment_sum(buf, s, e) / n
        best[k] = segment_max(fitness, s, e)
    return w, mean, cov, cov_xy, heading_sd, fit, best


def all_species_stats_reference(
    species: NDArray[np.int64],
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    fitness: NDArray[np.float64],
) -> dict[int, SpeciesStats]:
    """:func:`all_species_stats` in NumPy segment sums (``np.add.reduceat``): the reference
    the compiled version equals bit for bit (``tests/filters/test_ceamcl_species.py``)."""
    if species.size == 0:
        return {}
    order, ids, starts, counts = label_segments(species)
    seg = np.repeat(np.arange(ids.size), counts)
    p = poses[order]
    x, y, th = p[:, 0], p[:, 1], p[:, 2]

    def total(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.add.reduceat(v, starts)

    w = segment_weights(loglik[order], starts, seg)
    # Weighted mean pose with circular heading (pose_mean).
    # the C library's sin, cos, atan2 and log, as the compiled pass (c_library)
    sin, cos = c_library(math.sin, th), c_library(math.cos, th)
    sw, cw = total(w * sin), total(w * cos)
    heading = np.where((sw == 0.0) & (cw == 0.0), 0.0, c_library(math.atan2, sw, cw))
    mean = np.column_stack([total(w * x), total(w * y), heading])
    # Weighted covariance, heading deviations wrapped (pose_covariance).
    d = np.column_stack([x - mean[seg, 0], y - mean[seg, 1], wrap(th - mean[seg, 2])])
    cov = np.empty((ids.size, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            cov[:, i, j] = cov[:, j, i] = total(w * d[:, i] * d[:, j])
    # Unweighted x-y covariance of the individuals (np.cov, ddof 1) for the living domain.
    n = counts.astype(np.float64)
    ux, uy = total(x) / n, total(y) / n
    ex, ey = x - ux[seg], y - uy[seg]
    dof = np.maximum(n - 1.0, 1.0)
    cov_xy = np.empty((ids.size, 2, 2))
    cov_xy[:, 0, 0] = total(ex * ex) / dof
    cov_xy[:, 1, 1] = total(ey * ey) / dof
    cov_xy[:, 0, 1] = cov_xy[:, 1, 0] = total(ex * ey) / dof
    cov_xy[counts < 2] = 0.0
    # Unweighted circular spread of the headings (circular_variance).
    resultant = np.clip(np.hypot(total(sin), total(cos)) / n, 1e-300, 1.0)
    heading_sd = np.sqrt(np.minimum(-2.0 * c_library(math.log, resultant), np.pi**2))
    fit = total(fitness[order]) / n
    best = np.maximum.reduceat(fitness[order], starts)
    return _collect(
        ids,
        order,
        starts,
        counts,
        w,
        mean,
        cov,
        cov_xy,
        heading_sd,
        fit,
        best,
        living_domains_reference(cov_xy),
    )


def living_domains(
    cov_xy: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`~ceamcl.filters.ceamcl.competition.living_domain` over a stack ``(S, 2, 2)``:
    the variances along the domain's axes ``(S, 2)`` (ascending), the axes ``(S, 2, 2)`` (as
    columns) and the areas ``(S,)``.

    One compiled pass (:func:`_living_domains`), equal bit for bit to
    :func:`living_domains_reference`, its NumPy form: ``np.linalg.eigh`` of one 2 x 2 matrix
    cost about 35 us inside a filter update (its LAPACK code cold in the caches, against 5 us
    in a loop), the largest single cost of a tracking update's species statistics. A matrix
    LAPACK would rescale first (largest entry below about 1e-146 or above 1e146) is left to
    NumPy."""
    c = np.ascontiguousarray(cov_xy, dtype=np.float64).reshape(-1, 2, 2)
    d, u, area, exact = _living_domains(c)
    if not exact.all():
        rest = ~exact
        d[rest], u[rest], area[rest] = living_domains_reference(c[rest])
    return d, u, area


#: LAPACK's machine constants (``dlamch``) and the bounds within which ``dsyevd`` and
#: ``dsteqr`` leave a matrix unscaled.
_EPS = 2.0**-53
_EPS2 = _EPS * _EPS
_SAFMIN = 2.0**-1022
_SSFMAX = math.sqrt(1.0 / _SAFMIN) / 3.0
_SSFMIN = math.sqrt(_SAFMIN) / _EPS2
_RMIN = math.sqrt(_SAFMIN / 2.0**-52)
_RMAX = math.sqrt(1.0 / (_SAFMIN / 2.0**-52))
_FOUR_PI = 4.0 * np.pi


@numba.njit(cache=True, inline="always")
def _laev2(a: float, b: float, c: float) -> tuple[float, float, float, float]:  # pragma: no cover
    """LAPACK ``dlaev2``: the eigen-decomposition of ``[[a, b], [b, c]]`` (``rt1`` the larger
    in absolute value, ``(cs1, sn1)`` its unit eigenvector), operation for operation."""
    sm = a + c
    df = a - c
    adf = abs(df)
    tb = b + b
    ab = abs(tb)
    if abs(a) > abs(c):
        acmx, acmn = a, c
    else:
        acmx, acmn = c, a
    if adf > ab:
        ratio = ab / adf
        rt = adf * math.sqrt(1.0 + ratio * ratio)
    elif adf < ab:
        ratio = adf / ab
        rt = ab * math.sqrt(1.0 + ratio * ratio)
    else:
        rt = ab * math.sqrt(2.0)
    if sm < 0.0:
        rt1 = 0.5 * (sm - rt)
        sgn1 = -1
        rt2 = (acmx / rt1) * acmn - (b / rt1) * b
    elif sm > 0.0:
        rt1 = 0.5 * (sm + rt)
        sgn1 = 1
        rt2 = (acmx / rt1) * acmn - (b / rt1) * b
    else:
        rt1 = 0.5 * rt
        rt2 = -0.5 * rt
        sgn1 = 1
    if df >= 0.0:
        cs = df + rt
        sgn2 = 1
    else:
        cs = df - rt
        sgn2 = -1
    if abs(cs) > ab:
        ct = -tb / cs
        sn1 = 1.0 / math.sqrt(1.0 + ct * ct)
        cs1 = ct * sn1
    elif ab == 0.0:
        cs1 = 1.0
        sn1 = 0.0
    else:
        tn = -cs / tb
        cs1 = 1.0 / math.sqrt(1.0 + tn * tn)
        sn1 = tn * cs1
    if sgn1 == sgn2:
        cs1, sn1 = -sn1, cs1
    return rt1, rt2, cs1, sn1


@numba.njit(cache=True)
def _living_domains(c):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`living_domains_reference` row by row, with ``np.linalg.eigh`` replaced by the
    path LAPACK's ``dsyevd`` (lower triangle) takes for a 2 x 2 matrix: the tridiagonal form is
    the matrix itself (its Householder reflector is the identity), ``dsteqr`` splits it when
    the off-diagonal is negligible or else rotates the identity by ``dlaev2``'s eigenvector
    (``dlasr``; QL or QR by the diagonal's larger end, which for one rotation differ only in
    the test that deflates), then sorts ascending. ``exact[k]`` is False where LAPACK would
    first rescale the matrix (:func:`living_domains` then asks NumPy)."""
    n = c.shape[0]
    d = np.empty((n, 2))
    u = np.empty((n, 2, 2))
    area = np.empty(n)
    exact = np.ones(n, dtype=np.bool_)
    for k in range(n):
        a11 = 0.5 * (c[k, 0, 0] + c[k, 0, 0])
        a21 = 0.5 * (c[k, 1, 0] + c[k, 0, 1])  # also q[0, 1]: a sum does not depend on order
        a22 = 0.5 * (c[k, 1, 1] + c[k, 1, 1])
        if not (math.isfinite(a11) and math.isfinite(a21) and math.isfinite(a22)):
            a11 = a21 = a22 = 0.0  # the zero matrix: no rotation, the identity's axes
        top = max(abs(a11), abs(a21), abs(a22))
        if (top > 0.0 and top < _RMIN) or top > _RMAX:
            exact[k] = False
            continue
        d1, d2, e = a11, a22, a21
        z11, z21, z12, z22 = 1.0, 0.0, 0.0, 1.0
        tst = abs(e)
        split = tst == 0.0 or tst <= (math.sqrt(abs(d1)) * math.sqrt(abs(d2))) * _EPS
        if not split:
            anorm = max(abs(d1), abs(d2), abs(e))
            if anorm > _SSFMAX or anorm < _SSFMIN:
                exact[k] = False
                continue
            if abs(d2) < abs(d1):  # QR iteration from the lower end
                deflates = tst * tst <= (_EPS2 * abs(d2)) * abs(d1) + _SAFMIN
            else:  # QL iteration from the upper end
                deflates = tst * tst <= (_EPS2 * abs(d1)) * abs(d2) + _SAFMIN
            if not deflates:
                rt1, rt2, cs, sn = _laev2(d1, e, d2)
                temp = z12
                z12 = cs * temp - sn * z11
                z11 = sn * temp + cs * z11
                temp = z22
                z22 = cs * temp - sn * z21
                z21 = sn * temp + cs * z21
                d1, d2 = rt1, rt2
        if d2 < d1:
            d1, d2 = d2, d1
            z11, z12 = z12, z11
            z21, z22 = z22, z21
        d1 = d1 if d1 > 0.0 else 0.0  # np.clip(d, 0.0, None): -0.0 becomes +0.0
        d2 = d2 if d2 > 0.0 else 0.0
        d[k, 0] = d1
        d[k, 1] = d2
        u[k, 0, 0] = z11
        u[k, 1, 0] = z21
        u[k, 0, 1] = z12
        u[k, 1, 1] = z22
        area[k] = _FOUR_PI * math.sqrt(d1 * d2)
    return d, u, area, exact


def living_domains_reference(
    cov_xy: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`living_domains` in NumPy (the reference it equals bit for bit)."""
    q = 0.5 * (cov_xy + np.swapaxes(cov_xy, 1, 2))
    bad = ~np.all(np.isfinite(q), axis=(1, 2))
    q[bad] = 0.0
    d, u = np.linalg.eigh(q)
    d = np.clip(d, 0.0, None)
    u[bad] = np.eye(2)
    area = 4.0 * np.pi * np.sqrt(d[:, 0] * d[:, 1])
    return d, u, area


def compact_species(
    members: dict[int, NDArray[np.intp]], poses: NDArray[np.float64], cell_m: float, cell_rad: float
) -> set[int]:
    """Ids of the species whose poses span less than one split cell in x, y and heading:
    their occupied cells are pairwise adjacent (26-neighbourhood), so they cannot split and
    :func:`split_parts` need not label them. (Heading spread: the range of the headings'
    deviations from the species' first member.) Every species in ``members`` is non-empty."""
    if not members:
        return set()
    counts = np.array([idx.size for idx in members.values()])
    starts = np.cumsum(counts) - counts
    seg = np.repeat(np.arange(counts.size), counts)
    p = poses[np.concatenate(list(members.values()))]
    dev = wrap(p[:, 2] - p[starts, 2][seg])
    spans = [
        np.maximum.reduceat(v, starts) - np.minimum.reduceat(v, starts)
        for v in (p[:, 0], p[:, 1], dev)
    ]
    compact = (spans[0] < cell_m) & (spans[1] < cell_m) & (spans[2] < cell_rad)
    return {sid for sid, ok in zip(members, compact.tolist(), strict=True) if ok}


#: Up to this many species every pair is tested; above it a k-d tree proposes the pairs whose
#: bounding circles meet (a recovery on a big map makes a thousand species and more).
ALL_PAIRS_MAX = 64


def overlapping_pairs(stats: list[SpeciesStats]) -> list[tuple[int, int]]:
    """Index pairs ``(i, j)``, ``i < j``, of species in ``stats`` whose living domains overlap
    (:func:`domains_overlap` for all pairs at once), in ascending order of ``(i, j)``."""
    m = len(stats)
    if m < 2:
        return []
    means = np.array([s.mean[:2] for s in stats])
    d = np.maximum(np.array([s.domain_variances for s in stats]), 1e-12)
    axes = np.array([s.domain_axes for s in stats])
    if m <= ALL_PAIRS_MAX or not (np.all(np.isfinite(means)) and np.all(np.isfinite(d))):
        i, j = np.triu_indices(m, 1)
    else:
        i, j = _pairs_within_reach(means, d)
    delta = means[j] - means[i]
    dist = np.hypot(delta[:, 0], delta[:, 1])
    u = delta / np.where(dist > 0, dist, 1.0)[:, None]

    def radius(k: NDArray[np.intp]) -> NDArray[np.float64]:
        c = np.einsum("pji,pj->pi", axes[k], u)  # components along the principal axes
        return np.asarray(1.0 / np.sqrt(np.sum(c * c / (4.0 * d[k]), axis=1)))

    hit = (dist == 0.0) | (dist < radius(i) + radius(j))
    return [(int(a), int(b)) for a, b in zip(i[hit], j[hit], strict=True)]


def _pairs_within_reach(
    means: NDArray[np.float64], variances: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The pairs ``(i, j)``, ``i < j``, in ascending order, whose centres lie closer than the
    sum of their domains' bounding circles (radius ``2 sqrt`` of the larger variance, widened
    by a relative 1e-9 against rounding): every pair whose domains can overlap, found by each
    species' k-d tree query of twice its own reach for the species no wider than itself
    (for ``R_j <= R_i``, ``R_i + R_j <= 2 R_i``)."""
    m = means.shape[0]
    reach = 2.0 * np.sqrt(np.max(variances, axis=1)) * (1.0 + 1e-9) + 1e-12
    near = cKDTree(means).query_ball_point(means, 2.0 * reach)
    rows = np.repeat(np.arange(m), [len(n) for n in near])
    cols = np.concatenate([np.asarray(n, dtype=np.intp) for n in near])
    keep = (cols != rows) & (reach[cols] <= reach[rows])
    a = np.minimum(rows, cols)[keep]
    b = np.maximum(rows, cols)[keep]
    key = np.unique(a.astype(np.int64) * m + b)  # ascending (a, b), each pair once
    return (key // m).astype(np.intp), (key % m).astype(np.intp)


def sample_living_domain(
    stats: SpeciesStats, count: int, rng: np.random.Generator, min_sd_m: float = 0.02
) -> NDArray[np.float64]:
    """``count`` poses uniform over the species' living domain (the ellipse with radii
    ``2 sqrt(d_j)`` along ``e_j``), headings from a normal around the species' circular mean
    with its circular spread (NOTES.md). Variances are floored at ``min_sd_m^2`` so a
    collapsed species still spreads its offspring."""
    radius = 2.0 * np.sqrt(np.maximum(stats.domain_variances, min_sd_m**2))
    r = np.sqrt(rng.random(count))
    phi = rng.uniform(0.0, 2.0 * np.pi, count)
    local = np.column_stack([r * np.cos(phi) * radius[0], r * np.sin(phi) * radius[1]])
    xy = stats.mean[:2] + local @ stats.domain_axes.T
    theta = wrap(stats.mean[2] + rng.standard_normal(count) * stats.heading_sd)
    return np.column_stack([xy, theta])


def split_parts(
    members: NDArray[np.intp], poses: NDArray[np.float64], cell_m: float, cell_rad: float
) -> list[NDArray[np.intp]]:
    """The members of one species grouped by connected region of occupied x-y-heading cells,
    largest first; one group means no split."""
    labels, count = pose_cluster_labels(poses[members], cell_m, cell_rad)
    if count <= 1:
        return [members]
    parts = [members[labels == k] for k in range(count)]
    return sorted(parts, key=lambda g: -g.size)


def domains_overlap(a: SpeciesStats, b: SpeciesStats) -> bool:
    """Whether two living domains overlap along the line joining their centres: the distance
    between the centres is below the sum of the two ellipses' radii in that direction."""
    delta = b.mean[:2] - a.mean[:2]
    dist = float(np.hypot(*delta))
    if dist == 0.0:
        return True
    u = delta / dist
    return dist < _radius_along(a, u) + _radius_along(b, u)


def _radius_along(s: SpeciesStats, u: NDArray[np.float64]) -> float:
    """Radius of the 2-sigma ellipse of ``s`` in unit direction ``u``."""
    d = np.maximum(s.domain_variances, 1e-12)
    c = s.domain_axes.T @ u  # components along the principal axes
    return float(1.0 / np.sqrt(np.sum(c * c / (4.0 * d))))
