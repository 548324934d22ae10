"""Genetic operators of GMCL and CEAMCL (paper section 3.4), vectorised over pairs.

Fitness is the observation likelihood ``p(y_t | x)``; the operators compare log-likelihoods,
which orders poses exactly as the likelihood does.

* Crossover (eq. 17): parents ``p1, p2`` and ``xi ~ U[0, 1]`` give
  ``c1 = xi p1 + (1 - xi) p2`` and ``c2 = (1 - xi) p1 + xi p2`` (headings along the shorter arc);
  the best two of the four take the parents' places.
* Mutation (eq. 18, corrected as in NOTES.md: the child's weight is the child's likelihood):
  ``c = p + tau``, ``tau ~ N(0, Sigma)``; the better of parent and child stays.

With ``selection="best"`` (the paper's) both operators never lower the best likelihood of the
set they act on, and they pull a species onto its likelihood peak, far tighter than the real
error of the pose (docs/ceamcl.md, "calibration"). ``selection="metropolis"`` accepts children
with a Metropolis acceptance on the (tempered) likelihood: a mutant replaces its parent with
probability ``min(1, p(y | c) / p(y | p))``, a crossover pair replaces both parents with
probability ``min(1, p(y | c1) p(y | c2) / (p(y | p1) p(y | p2)))``. Better children are always
kept, worse ones sometimes. The mutation is then a random-walk Metropolis move, which keeps
the scan's tempered likelihood (wider than the posterior of many scans); eq. 17's blend is
not: it contracts a pair (``c1 - c2 = (2 xi - 1)(p1 - p2)``) and is not its own reverse, so
no acceptance rule makes it keep a distribution. The two pull opposite ways, and their balance
is what keeps a species about as wide as its error instead of collapsing onto its mode
(docs/ceamcl.md, "Why a tracked species is too wide").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from ceamcl.angles import interpolate, wrap, wrap_one
from ceamcl.filters.resampling import maximum

Evaluator = Callable[[NDArray[np.float64]], NDArray[np.float64]]

#: How children replace parents (``EvolutionConfig.selection``, module docstring).
SELECTIONS: tuple[str, ...] = ("best", "metropolis")


@dataclass(frozen=True)
class EvolutionConfig:
    """Crossover probability ``p_c``, mutation probability ``p_m`` (paper: 0.85 and 0.15) and
    the standard deviations of the mutation's Gaussian ``Sigma = diag(sx^2, sy^2, stheta^2)``
    (the paper leaves Sigma open; docs/ceamcl.md explains the default)."""

    p_crossover: float = 0.85
    p_mutation: float = 0.15
    mutation_sigma_xy_m: float = 0.05
    mutation_sigma_theta_rad: float = 0.03
    selection: str = "best"

    def __post_init__(self) -> None:
        if self.selection not in SELECTIONS:
            raise ValueError(
                f"selection: expected one of {', '.join(SELECTIONS)}, got {self.selection!r}"
            )
        for name in ("p_crossover", "p_mutation"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name}: expected a probability in [0, 1], got {v}")
        for name in ("mutation_sigma_xy_m", "mutation_sigma_theta_rad"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {v}")


def crossover(
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    first: NDArray[np.intp],
    second: NDArray[np.intp],
    p_crossover: float,
    evaluate: Evaluator,
    rng: np.random.Generator,
    selection: str = "best",
    best_seen: NDArray[np.float64] | None = None,
) -> int:
    """Eq. 17 on the disjoint pairs ``(first[k], second[k])``, in place; returns how many poses
    were evaluated. The arithmetic is compiled (:func:`_crossover_children`,
    :func:`_crossover_select`); the random numbers are drawn here, in the order and sizes
    :func:`crossover_reference` draws them, so both give the same bits."""
    mate = rng.random(first.size) < p_crossover
    xi = rng.random(first.size)
    a, b, xi = first[mate], second[mate], xi[mate]
    if a.size == 0:
        return 0
    a, b = a.astype(np.intp, copy=False), b.astype(np.intp, copy=False)
    children = _crossover_children(poses, a, b, xi)
    ll_children = np.asarray(evaluate(children), dtype=np.float64)
    metropolis = selection == "metropolis"
    u = rng.random(a.size) if metropolis else _NONE
    track = best_seen is not None
    _crossover_select(
        poses, loglik, a, b, children, ll_children, u, metropolis,
        best_seen if best_seen is not None else _NONE, track,
    )  # fmt: skip
    return 2 * int(a.size)


def mutation(
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    candidates: NDArray[np.intp],
    p_mutation: float,
    sigma: NDArray[np.float64],
    evaluate: Evaluator,
    rng: np.random.Generator,
    selection: str = "best",
    best_seen: NDArray[np.float64] | None = None,
) -> int:
    """Eq. 18 (corrected) on each index of ``candidates`` with probability ``p_mutation``, in
    place; returns how many poses were evaluated. Compiled like :func:`crossover`, with the
    random numbers of :func:`mutation_reference`."""
    chosen = candidates[rng.random(candidates.size) < p_mutation]
    z = rng.standard_normal((chosen.size, 3))
    if chosen.size == 0:
        return 0
    chosen = chosen.astype(np.intp, copy=False)
    child = _mutants(poses, chosen, z, np.asarray(sigma, dtype=np.float64))
    ll_child = np.asarray(evaluate(child), dtype=np.float64)
    metropolis = selection == "metropolis"
    u = rng.random(chosen.size) if metropolis else _NONE
    track = best_seen is not None
    _mutation_select(
        poses, loglik, chosen, child, ll_child, u, metropolis,
        best_seen if best_seen is not None else _NONE, track,
    )  # fmt: skip
    return int(chosen.size)


_NONE = np.zeros(0)  # an absent array argument of the kernels


@numba.njit(cache=True)
def _crossover_children(poses, a, b, xi):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``vstack([c1, c2])`` of eq. 17: positions blended, headings along the shorter arc
    (:func:`ceamcl.angles.interpolate`), operation for operation as the reference."""
    m = a.size
    out = np.empty((2 * m, 3))
    for k in range(m):
        x = xi[k]
        pa, pb = poses[a[k]], poses[b[k]]
        for j in range(2):
            out[k, j] = x * pa[j] + (1.0 - x) * pb[j]
            out[m + k, j] = (1.0 - x) * pa[j] + x * pb[j]
        out[k, 2] = wrap_one(pb[2] + x * wrap_one(pa[2] - pb[2]))
        out[m + k, 2] = wrap_one(pa[2] + x * wrap_one(pb[2] - pa[2]))
    return out


@numba.njit(cache=True)
def _crossover_select(  # type: ignore[no-untyped-def]  # pragma: no cover
    poses, loglik, a, b, children, ll_children, u, metropolis, best_seen, track
):
    """Which two of parents and children take the parents' places (module docstring), in
    place; NaN log-likelihoods count as -inf; ``best_seen`` raised at both parents."""
    m = a.size
    cand_ll = np.empty(4)
    cand = np.empty((4, 3))
    for k in range(m):
        i, j = a[k], b[k]
        cand_ll[0], cand_ll[1] = loglik[i], loglik[j]
        cand_ll[2], cand_ll[3] = ll_children[k], ll_children[m + k]
        for c in range(4):
            if np.isnan(cand_ll[c]):
                cand_ll[c] = -np.inf
        for d in range(3):
            cand[0, d], cand[1, d] = poses[i, d], poses[j, d]
            cand[2, d], cand[3, d] = children[k, d], children[m + k, d]
        if track:
            top = max(max(cand_ll[0], cand_ll[1]), max(cand_ll[2], cand_ll[3]))
            best_seen[i] = maximum(best_seen[i], top)
            best_seen[j] = maximum(best_seen[j], top)
        if metropolis:
            log_ratio = cand_ll[2] + cand_ll[3] - cand_ll[0] - cand_ll[1]
            if np.isnan(log_ratio):
                log_ratio = -np.inf
            first, second = (2, 3) if np.log(u[k]) < log_ratio else (0, 1)
        else:  # the best two, ties to the earlier (a stable sort of -log-likelihood)
            first = 0
            for c in range(1, 4):
                if cand_ll[c] > cand_ll[first]:
                    first = c
            second = -1
            for c in range(4):
                if c != first and (second < 0 or cand_ll[c] > cand_ll[second]):
                    second = c
        for d in range(3):
            poses[i, d] = cand[first, d]
            poses[j, d] = cand[second, d]
        loglik[i] = cand_ll[first]
        loglik[j] = cand_ll[second]


@numba.njit(cache=True)
def _mutants(poses, chosen, z, sigma):  # type: ignore[no-untyped-def]  # pragma: no cover
    """``poses[chosen] + z * sigma``, headings wrapped."""
    child = np.empty((chosen.size, 3))
    for k in range(chosen.size):
        for d in range(3):
            child[k, d] = poses[chosen[k], d] + z[k, d] * sigma[d]
        child[k, 2] = wrap_one(child[k, 2])
    return child


@numba.njit(cache=True)
def _mutation_select(  # type: ignore[no-untyped-def]  # pragma: no cover
    poses, loglik, chosen, child, ll_child, u, metropolis, best_seen, track
):
    """A mutant replaces its parent when better (or by the Metropolis rule), in place."""
    for k in range(chosen.size):
        i = chosen[k]
        ll = ll_child[k]
        if track:
            best_seen[i] = maximum(best_seen[i], -np.inf if np.isnan(ll) else ll)
        if metropolis:
            log_ratio = ll - loglik[i]
            if np.isnan(log_ratio):
                log_ratio = -np.inf
            keep = np.log(u[k]) < log_ratio
        else:
            keep = ll > loglik[i]
        if keep:
            for d in range(3):
                poses[i, d] = child[k, d]
            loglik[i] = ll


def crossover_reference(
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    first: NDArray[np.intp],
    second: NDArray[np.intp],
    p_crossover: float,
    evaluate: Evaluator,
    rng: np.random.Generator,
    selection: str = "best",
    best_seen: NDArray[np.float64] | None = None,
) -> int:
    """:func:`crossover` in NumPy, the reference it equals bit for bit
    (``tests/filters/test_evolution.py``)."""
    mate = rng.random(first.size) < p_crossover
    xi = rng.random(first.size)
    a, b, xi = first[mate], second[mate], xi[mate]
    if a.size == 0:
        return 0
    pa, pb = poses[a], poses[b]
    c1 = np.empty_like(pa)
    c2 = np.empty_like(pa)
    c1[:, :2] = xi[:, None] * pa[:, :2] + (1.0 - xi[:, None]) * pb[:, :2]
    c2[:, :2] = (1.0 - xi[:, None]) * pa[:, :2] + xi[:, None] * pb[:, :2]
    c1[:, 2] = interpolate(pb[:, 2], pa[:, 2], xi)
    c2[:, 2] = interpolate(pa[:, 2], pb[:, 2], xi)
    ll_children = evaluate(np.vstack([c1, c2]))
    m = a.size
    cand_poses = np.stack([pa, pb, c1, c2], axis=1)  # (m, 4, 3)
    cand_ll = np.column_stack([loglik[a], loglik[b], ll_children[:m], ll_children[m:]])
    cand_ll = np.where(np.isnan(cand_ll), -np.inf, cand_ll)
    if best_seen is not None:
        top = cand_ll.max(axis=1)
        np.maximum.at(best_seen, a, top)
        np.maximum.at(best_seen, b, top)
    if selection == "metropolis":
        log_ratio = cand_ll[:, 2] + cand_ll[:, 3] - cand_ll[:, 0] - cand_ll[:, 1]
        accept = _accepted(log_ratio, rng)
        order = np.where(accept[:, None], np.array([[2, 3]]), np.array([[0, 1]]))
    else:
        order = np.argsort(-cand_ll, axis=1, kind="stable")[:, :2]
    rows = np.arange(m)
    poses[a] = cand_poses[rows, order[:, 0]]
    poses[b] = cand_poses[rows, order[:, 1]]
    loglik[a] = cand_ll[rows, order[:, 0]]
    loglik[b] = cand_ll[rows, order[:, 1]]
    return 2 * m


def mutation_reference(
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    candidates: NDArray[np.intp],
    p_mutation: float,
    sigma: NDArray[np.float64],
    evaluate: Evaluator,
    rng: np.random.Generator,
    selection: str = "best",
    best_seen: NDArray[np.float64] | None = None,
) -> int:
    """:func:`mutation` in NumPy, the reference it equals bit for bit."""
    chosen = candidates[rng.random(candidates.size) < p_mutation]
    noise = rng.standard_normal((chosen.size, 3)) * sigma
    if chosen.size == 0:
        return 0
    child = poses[chosen] + noise
    child[:, 2] = wrap(child[:, 2])
    ll_child = evaluate(child)
    if best_seen is not None:
        np.maximum.at(best_seen, chosen, np.where(np.isnan(ll_child), -np.inf, ll_child))
    if selection == "metropolis":
        better = _accepted(ll_child - loglik[chosen], rng)
    else:
        better = ll_child > loglik[chosen]
    poses[chosen[better]] = child[better]
    loglik[chosen[better]] = ll_child[better]
    return int(chosen.size)


def _accepted(log_ratio: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.bool_]:
    """Metropolis acceptance: ``u < exp(log_ratio)`` for ``u ~ U[0, 1)`` (NaN: rejected)."""
    u = rng.random(log_ratio.size)
    with np.errstate(invalid="ignore"):
        return np.log(u) < np.where(np.isnan(log_ratio), -np.inf, log_ratio)


def random_pairs(
    groups: list[NDArray[np.intp]], rng: np.random.Generator
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Disjoint random pairs inside each group (``floor(n/2)`` pairs from a group of ``n``)."""
    firsts, seconds = [], []
    for g in groups:
        perm = rng.permutation(g)
        half = perm.size // 2
        firsts.append(perm[:half])
        seconds.append(perm[half : 2 * half])
    if not firsts:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    return np.concatenate(firsts).astype(np.intp), np.concatenate(seconds).astype(np.intp)


def evolve_groups(
    poses: NDArray[np.float64],
    loglik: NDArray[np.float64],
    groups: list[NDArray[np.intp]],
    config: EvolutionConfig,
    evaluate: Evaluator,
    rng: np.random.Generator,
    best_seen: NDArray[np.float64] | None = None,
) -> int:
    """Crossover then mutation inside each group of indices (a species, or everything for
    GMCL); one likelihood call per operator for all groups together. ``best_seen``: see
    :func:`ceamcl.filters.particles.evolve`. Returns evaluations."""
    first, second = random_pairs(groups, rng)
    evals = crossover(
        poses,
        loglik,
        first,
        second,
        config.p_crossover,
        evaluate,
        rng,
        config.selection,
        best_seen,
    )
    everyone = np.concatenate(groups).astype(np.intp) if groups else np.zeros(0, np.intp)
    sigma = np.array(
        [config.mutation_sigma_xy_m, config.mutation_sigma_xy_m, config.mutation_sigma_theta_rad]
    )
    evals += mutation(
        poses,
        loglik,
        everyone,
        config.p_mutation,
        sigma,
        evaluate,
        rng,
        config.selection,
        best_seen,
    )
    return evals
