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
