"""Inter-species competition (paper sections 3.2 and 3.3): living domains, resources,
carrying capacities and the Lotka-Volterra increments.

All functions are pure and vectorised over species, so the four outcomes of the paper's
Fig. 1 can be checked directly on :func:`lotka_volterra_increments`.

Reading of the paper (docs/ceamcl.md gives the reasons):
* the living domain is the 2-sigma ellipse of the species' x-y covariance, of area
  ``A = 4 pi sqrt(d1 d2)`` (eq. 14 corrected: NOTES.md error 1);
* ``dt`` is one filter step.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def living_domain(cov_xy: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Eqs. 10-14 for n = 2: eigen-decomposition ``Q = U D U^T`` of a ``2 x 2`` covariance and the
    area of the ellipse with radii ``2 sqrt(d_j)`` along ``e_j``.

    Returns ``(d, U, area)`` with ``d`` the variances (clipped at 0) and ``U`` the eigenvectors
    as columns. A degenerate covariance gives area 0, never NaN.
    """
    q = np.asarray(cov_xy, dtype=np.float64).reshape(2, 2)
    q = 0.5 * (q + q.T)
    if not np.all(np.isfinite(q)):
        return np.zeros(2), np.eye(2), 0.0
    d, u = np.linalg.eigh(q)
    d = np.clip(d, 0.0, None)
    area = 4.0 * np.pi * float(np.sqrt(d[0] * d[1]))  # eq. 14 (n = 2, C_2 = pi), corrected
    return d, u, area


def resources(area_m2: ArrayLike, delta_per_m2: float, epsilon_m2: float) -> NDArray[np.float64]:
    """Eq. 15: ``R_i = delta * max(A_i, epsilon)``."""
    return delta_per_m2 * np.maximum(np.asarray(area_m2, dtype=np.float64), epsilon_m2)


def carrying_capacity(fitness: ArrayLike, total_resources: float) -> NDArray[np.float64]:
    """Eq. 16: ``K_i = exp(1 - w_i) * R`` with ``R`` the resources of all species together."""
    return np.exp(1.0 - np.asarray(fitness, dtype=np.float64)) * total_resources


def competition_coefficients(fitness: ArrayLike) -> NDArray[np.float64]:
    """``alpha_ij = w_j / w_i`` (section 4); the diagonal is unused (set to 0)."""
    w = np.asarray(fitness, dtype=np.float64)
    w = np.maximum(w, 1e-300)
    alpha = w[None, :] / w[:, None]
    np.fill_diagonal(alpha, 0.0)
    return alpha


def lotka_volterra_increments(
    n: ArrayLike,
    capacity: ArrayLike,
    alpha: ArrayLike,
    growth_rate: ArrayLike,
) -> NDArray[np.float64]:
    """Eq. 9: ``dN_i/dt = r_i N_i (1 - (N_i + sum_{j != i} alpha_ij N_j) / K_i)``.

    ``alpha`` is ``(S, S)`` (its diagonal is ignored). Species with ``K_i <= 0`` shrink to
    zero instead of producing inf.
    """
    n_ = np.asarray(n, dtype=np.float64)
    k = np.asarray(capacity, dtype=np.float64)
    a = np.array(alpha, dtype=np.float64, copy=True).reshape(n_.size, n_.size)
    np.fill_diagonal(a, 0.0)
    pressure = n_ + a @ n_
    safe_k = np.where(k > 0, k, 1.0)
    growth = np.where(k > 0, 1.0 - pressure / safe_k, -1.0)
    return np.asarray(growth_rate, dtype=np.float64) * n_ * growth


def step_increments(
    n: ArrayLike,
    capacity: ArrayLike,
    alpha: ArrayLike,
    growth_rate: ArrayLike,
) -> NDArray[np.float64]:
    """Eq. 9 over one filter step (``dt = 1``) without overshoot.

    Growth is eq. 9's Euler step as the paper has it. A decline is integrated exactly over the
    step at eq. 9's per-capita rate ``rho = r (1 - pressure / K) < 0``: ``dN = N (e^rho - 1)``.
    The two agree to first order, but Euler's ``dN = N rho`` falls below ``-N`` when the
    pressure exceeds ``K`` many times over (e.g. right after the living domains shrink and the
    resources with them), wiping out every species in one step, the fittest too. With the exact
    decline a species only dies out by falling below the size floor over several steps, and
    which species grows or shrinks (the sign of ``dN``, hence Fig. 1's outcomes) is unchanged.
    """
    n_ = np.asarray(n, dtype=np.float64)
    dn = lotka_volterra_increments(n_, capacity, alpha, growth_rate)
    rho = np.divide(dn, n_, out=np.zeros_like(dn), where=n_ > 0)
    return np.where(rho < 0, n_ * np.expm1(rho), dn)


def simulate_competition(
    n0: ArrayLike,
    capacity: ArrayLike,
    alpha: ArrayLike,
    growth_rate: float,
    steps: int,
) -> NDArray[np.float64]:
    """Iterate eq. 9 with ``dt = 1`` and fixed ``K``, ``alpha`` as the filter does (its
    :func:`step_increments`): trajectories ``(steps + 1, S)``.

    Sizes are clipped at 0, as the algorithm's ``N_t = max(N_{t-1} + dN, 0)``.
    """
    traj = [np.asarray(n0, dtype=np.float64)]
    for _ in range(steps):
        cur = traj[-1]
        traj.append(np.maximum(cur + step_increments(cur, capacity, alpha, growth_rate), 0.0))
    return np.asarray(traj)
