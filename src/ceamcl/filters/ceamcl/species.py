"""Per-species statistics, vectorised where it pays: sizes, fitness, means, living domains.

Species are identified by integer ids; particles carry the id of their species. Everything
here is computed from arrays ``poses (N, 3)``, ``species (N,)``, ``loglik (N,)`` and
``fitness (N,)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ceamcl.angles import circular_variance, wrap
from ceamcl.filters.ceamcl.competition import living_domain
from ceamcl.filters.clustering import pose_cluster_labels
from ceamcl.pose import pose_covariance, pose_mean


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

    @property
    def n(self) -> int:
        return int(self.members.size)


def in_species_weights(loglik: NDArray[np.float64]) -> NDArray[np.float64]:
    """Importance weights of one species' members, normalised to sum to 1 (never NaN)."""
    ll = np.where(np.isnan(loglik), -np.inf, loglik)
    top = float(np.max(ll)) if ll.size else -np.inf
    if not np.isfinite(top):
        return np.full(ll.size, 1.0 / max(ll.size, 1))
    w = np.exp(ll - top)
    return w / w.sum()


def group_members(species: NDArray[np.int64]) -> dict[int, NDArray[np.intp]]:
    """Indices of the particles of each species id, in ascending id order."""
    if species.size == 0:
        return {}
    order = np.argsort(species, kind="stable")
    ids, starts = np.unique(species[order], return_index=True)
    bounds = [*starts[1:], order.size]
    return {int(i): order[s:e] for i, s, e in zip(ids, starts, bounds, strict=True)}


def species_stats(
    species_id: int,
    members: NDArray[np.intp],
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    fitness: NDArray[np.float64],
) -> SpeciesStats:
    p = poses[members]
    w = in_species_weights(loglik[members])
    mean = pose_mean(p, w)
    cov = pose_covariance(p, w, mean)
    if p.shape[0] > 1:
        cov_xy = np.cov(p[:, :2], rowvar=False)
    else:
        cov_xy = np.zeros((2, 2))
    d, u, area = living_domain(cov_xy)
    return SpeciesStats(
        species_id=species_id,
        members=members,
        weights=w,
        mean=mean,
        covariance=cov,
        cov_xy=cov_xy,
        heading_sd=float(np.sqrt(min(circular_variance(p[:, 2]), np.pi**2))),
        fitness=float(np.mean(fitness[members])) if members.size else 0.0,
        domain_variances=d,
        domain_axes=u,
        area_m2=area,
    )


def all_species_stats(
    species: NDArray[np.int64],
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    fitness: NDArray[np.float64],
) -> dict[int, SpeciesStats]:
    """:func:`species_stats` of every species at once, in ascending id order.

    The same quantities, computed with segment sums over the particles sorted by species
    instead of one NumPy pass per species: the per-species Python overhead was most of a
    CEAMCL step (docs/performance.md). Results agree with :func:`species_stats` to rounding.
    """
    if species.size == 0:
        return {}
    order = np.argsort(species, kind="stable")
    ids, starts = np.unique(species[order], return_index=True)
    counts = np.diff(np.append(starts, order.size))
    seg = np.repeat(np.arange(ids.size), counts)
    p = poses[order]
    x, y, th = p[:, 0], p[:, 1], p[:, 2]

    def total(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.add.reduceat(v, starts)

    # In-species importance weights (in_species_weights, per segment).
    ll = loglik[order]
    ll = np.where(np.isnan(ll), -np.inf, ll)
    top = np.maximum.reduceat(ll, starts)
    finite_top = np.isfinite(top)
    w = np.exp(ll - np.where(finite_top, top, 0.0)[seg])
    w = np.where(finite_top[seg], w, 1.0)
    w = w / total(w)[seg]
    # Weighted mean pose with circular heading (pose_mean).
    sw, cw = total(w * np.sin(th)), total(w * np.cos(th))
    mean = np.column_stack(
        [total(w * x), total(w * y), np.where((sw == 0.0) & (cw == 0.0), 0.0, np.arctan2(sw, cw))]
    )
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
    dv, axes, area = living_domains(cov_xy)
    # Unweighted circular spread of the headings (circular_variance).
    resultant = np.clip(np.hypot(total(np.sin(th)), total(np.cos(th))) / n, 1e-300, 1.0)
    heading_sd = np.sqrt(np.minimum(-2.0 * np.log(resultant), np.pi**2))
    fit = total(fitness[order]) / n
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
            domain_variances=dv[k],
            domain_axes=axes[k],
            area_m2=float(area[k]),
        )
    return out


def living_domains(
    cov_xy: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`~ceamcl.filters.ceamcl.competition.living_domain` over a stack ``(S, 2, 2)``."""
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
    :func:`split_parts` need not label them."""
    out: set[int] = set()
    for sid, idx in members.items():
        p = poses[idx]
        if np.ptp(p[:, 0]) >= cell_m or np.ptp(p[:, 1]) >= cell_m:
            continue
        dev = wrap(p[:, 2] - p[0, 2])
        if np.ptp(dev) < cell_rad:
            out.add(sid)
    return out


def overlapping_pairs(stats: list[SpeciesStats]) -> list[tuple[int, int]]:
    """Index pairs ``(i, j)``, ``i < j``, of species in ``stats`` whose living domains overlap
    (:func:`domains_overlap` for all pairs at once)."""
    m = len(stats)
    if m < 2:
        return []
    means = np.array([s.mean[:2] for s in stats])
    d = np.maximum(np.array([s.domain_variances for s in stats]), 1e-12)
    axes = np.array([s.domain_axes for s in stats])
    i, j = np.triu_indices(m, 1)
    delta = means[j] - means[i]
    dist = np.hypot(delta[:, 0], delta[:, 1])
    u = delta / np.where(dist > 0, dist, 1.0)[:, None]

    def radius(k: NDArray[np.intp]) -> NDArray[np.float64]:
        c = np.einsum("pji,pj->pi", axes[k], u)  # components along the principal axes
        return np.asarray(1.0 / np.sqrt(np.sum(c * c / (4.0 * d[k]), axis=1)))

    hit = (dist == 0.0) | (dist < radius(i) + radius(j))
    return [(int(a), int(b)) for a, b in zip(i[hit], j[hit], strict=True)]


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
