"""Tests of the vectorised per-species helpers (``ceamcl.filters.ceamcl.species``) against the
same quantities computed one species at a time with the package's single-species functions."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from ceamcl.angles import circular_variance, wrap
from ceamcl.filters.ceamcl.competition import living_domain
from ceamcl.filters.ceamcl.species import (
    all_species_stats,
    all_species_stats_reference,
    compact_species,
    living_domains,
    living_domains_reference,
)
from ceamcl.filters.resampling import (
    label_groups,
    normalise_log_weights,
    systematic,
    systematic_within_labels,
)
from ceamcl.pose import pose_covariance, pose_mean


def population(
    rng: np.random.Generator, n_species: int = 6
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Species of uneven sizes, interleaved, with non-contiguous ids; log-likelihoods with
    impossible particles, and one species where every particle is impossible."""
    ids = np.arange(n_species) * 3 + 1
    sizes = rng.integers(1, 40, n_species)
    species = rng.permutation(np.repeat(ids, sizes)).astype(np.int64)
    centres = rng.uniform(0.0, 20.0, (n_species, 2))
    spread = rng.uniform(0.01, 1.5, n_species)
    k = np.searchsorted(ids, species)
    poses = np.column_stack(
        [
            centres[k] + rng.normal(0.0, 1.0, (species.size, 2)) * spread[k, None],
            wrap(rng.uniform(-np.pi, np.pi, n_species)[k] + rng.normal(0.0, 0.3, species.size)),
        ]
    )
    loglik = rng.normal(-40.0, 8.0, species.size)
    loglik[rng.random(species.size) < 0.1] = -np.inf
    loglik[species == ids[-1]] = -np.inf
    return species, poses, loglik


@pytest.mark.parametrize("seed", range(5))
def test_resample_species_draws_what_per_species_systematic_draws(seed: int) -> None:
    species, _, loglik = population(np.random.default_rng(seed))
    members = label_groups(species)
    sizes = np.random.default_rng(seed).integers(1, 60, len(members))
    targets = {sid: int(t) for sid, t in zip(members, sizes, strict=True)}
    del targets[next(iter(members))]  # a species without a target keeps its size
    rng_ref = np.random.default_rng(100 + seed)
    picks = [
        idx[systematic(normalise_log_weights(loglik[idx])[1], targets.get(sid, idx.size), rng_ref)]
        for sid, idx in members.items()
    ]
    rng = np.random.default_rng(100 + seed)
    sel, new_members = systematic_within_labels(species, loglik, targets, rng)
    np.testing.assert_array_equal(sel, np.concatenate(picks))
    assert list(new_members) == list(members)
    np.testing.assert_array_equal(np.isfinite(loglik[sel]) | (species[sel] == species.max()), True)
    # The returned members are those of the resampled particles.
    regrouped = label_groups(species[sel])
    assert list(regrouped) == list(new_members)
    for sid, idx in new_members.items():
        np.testing.assert_array_equal(idx, regrouped[sid])
        assert idx.size == targets.get(sid, members[sid].size)


@pytest.mark.parametrize("seed", range(3))
def test_all_species_stats_agree_with_single_species_functions(seed: int) -> None:
    rng = np.random.default_rng(seed)
    species, poses, loglik = population(rng)
    fit = rng.uniform(0.0, 1.0, species.size)
    stats = all_species_stats(species, poses, loglik, fit)
    members = label_groups(species)
    assert list(stats) == list(members)
    for sid, idx in members.items():
        s = stats[sid]
        np.testing.assert_array_equal(s.members, idx)
        p = poses[idx]
        w = normalise_log_weights(loglik[idx])[1]
        np.testing.assert_allclose(s.weights, w, rtol=1e-12, atol=1e-300)
        mean = pose_mean(p, w)
        np.testing.assert_allclose(s.mean, mean, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(s.covariance, pose_covariance(p, w, mean), atol=1e-9)
        cov_xy = np.cov(p[:, :2], rowvar=False) if idx.size > 1 else np.zeros((2, 2))
        np.testing.assert_allclose(s.cov_xy, cov_xy, atol=1e-9)
        d, _, area = living_domain(cov_xy)
        np.testing.assert_allclose(s.domain_variances, d, atol=1e-9)
        assert s.area_m2 == pytest.approx(area, abs=1e-9)
        sd = np.sqrt(min(circular_variance(p[:, 2]), np.pi**2))
        assert s.heading_sd == pytest.approx(sd, abs=1e-9)
        assert s.fitness == pytest.approx(float(np.mean(fit[idx])))


def _hard_case(rng: np.random.Generator) -> tuple[NDArray[np.int64], ...]:
    """Species of 1 to 300 particles (the pairwise sum's branches at 8 and 128 and its halving
    above), ids unsorted and sparse, with NaN, -inf and equal log-likelihoods, species whose
    every log-likelihood is -inf or NaN, headings at +-pi and zero, negative zeros, NaN fitness."""
    sizes = rng.integers(1, 300, rng.integers(1, 7))
    ids = rng.choice(10_000, sizes.size, replace=False)
    species = rng.permutation(np.repeat(ids, sizes)).astype(np.int64)
    n = species.size
    scale = 10.0 ** rng.integers(-3, 2)
    poses = np.column_stack(
        [rng.normal(0, scale, n), rng.normal(0, 1, n), rng.uniform(-np.pi, np.pi, n)]
    )
    kind = rng.integers(0, 6)
    if kind == 1:
        poses[:, 2] = rng.choice([np.pi, -np.pi, 0.0, -0.0], n)
    elif kind == 2:
        poses[:, :2] = -0.0
    loglik = rng.normal(-50, 20, n)
    loglik[rng.random(n) < 0.1] = np.nan
    loglik[rng.random(n) < 0.1] = -np.inf
    if kind == 3:
        loglik[species == ids[0]] = -np.inf
    elif kind == 4:
        loglik[species == ids[0]] = np.nan
    elif kind == 5:
        loglik[:] = 0.0
    fit = rng.uniform(0.0, 1.0, n)
    if rng.random() < 0.2:
        fit[rng.integers(0, n)] = np.nan
    return species, poses, loglik, fit


def test_all_species_stats_equals_its_numpy_reference_bit_for_bit() -> None:
    rng = np.random.default_rng(11)
    fields = ("weights", "mean", "covariance", "cov_xy", "domain_variances", "domain_axes")
    for _ in range(400):
        species, poses, loglik, fit = _hard_case(rng)
        got = all_species_stats(species, poses, loglik, fit)
        want = all_species_stats_reference(species, poses, loglik, fit)
        assert list(got) == list(want)
        for sid, g in got.items():
            r = want[sid]
            np.testing.assert_array_equal(g.members, r.members)
            for name in fields:
                a, b = getattr(g, name), getattr(r, name)
                assert a.tobytes() == b.tobytes(), name  # same bits, signed zeros and NaN too
            for name in ("heading_sd", "fitness", "best_fitness", "area_m2"):
                a, b = np.float64(getattr(g, name)), np.float64(getattr(r, name))
                assert a.tobytes() == b.tobytes(), name


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the reference's, on inf and 1e160
def test_living_domains_equal_their_numpy_reference_bit_for_bit() -> None:
    """The compiled 2 x 2 eigen-decomposition follows LAPACK's path (species.py): the same
    bits as ``np.linalg.eigh`` for covariances of every scale, diagonal, equal-diagonal,
    nearly diagonal, zero, negative, asymmetric, NaN and infinite (1,000,000 matrices
    agreed when it was written; this checks 60,000)."""
    rng = np.random.default_rng(5)
    n = 20_000
    for low, high in ((-12.0, 6.0), (-160.0, 160.0), (-3.0, 1.0)):
        scale = 10.0 ** rng.uniform(low, high, n)
        draws = rng.standard_normal((n, 2, 30)) * scale[:, None, None]
        with np.errstate(over="ignore", invalid="ignore"):
            c = draws @ np.swapaxes(draws, 1, 2) / 29.0
        kind = rng.integers(0, 9, n)
        c[kind == 1, 1, 0] = 0.0
        c[kind == 2, 1, 1] = c[kind == 2, 0, 0]
        c[kind == 3, 0, 1] *= 1.0000001
        c[kind == 4] = 0.0
        c[kind == 5, 0, 0] = np.nan
        c[kind == 6, 1, 0] = np.inf
        c[kind == 7] *= -1.0
        c[kind == 8, 1, 0] *= 1e-12
        got = living_domains(c.copy())
        want = living_domains_reference(c.copy())
        for g, w in zip(got, want, strict=True):
            assert g.tobytes() == w.tobytes()


def test_compact_species_are_those_spanning_less_than_one_cell() -> None:
    rng = np.random.default_rng(4)
    species, poses, _ = population(rng, n_species=12)
    members = label_groups(species)
    cell_m, cell_rad = 0.8, 0.5
    # Shrink every other species towards its first member; one of them straddles +-pi.
    for k, idx in enumerate(list(members.values())[::2]):
        first = poses[idx[0]].copy()
        if k == 0:
            first[2] = np.pi - 0.01
        shrunk = first + rng.uniform(0.02, 0.3) * np.column_stack(
            [poses[idx, :2] - first[:2], wrap(poses[idx, 2] - poses[idx[0], 2])]
        )
        shrunk[:, 2] = wrap(shrunk[:, 2])
        poses[idx] = shrunk
    expected = set()
    for sid, idx in members.items():
        p = poses[idx]
        span_th = np.ptp(wrap(p[:, 2] - p[0, 2]))
        if np.ptp(p[:, 0]) < cell_m and np.ptp(p[:, 1]) < cell_m and span_th < cell_rad:
            expected.add(sid)
    assert 0 < len(expected) < len(members)  # both kinds present
    assert compact_species(members, poses, cell_m, cell_rad) == expected
    assert compact_species({}, poses, cell_m, cell_rad) == set()
