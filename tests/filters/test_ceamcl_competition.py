"""Inter-species competition (paper sections 3.2 and 3.3; claim 4 of NOTES.md).

The four outcomes of the paper's Fig. 1 follow from eq. 7-8 with fixed ``K`` and ``alpha``;
with the paper's own ``alpha_ij = w_j / w_i`` and ``K_i = exp(1 - w_i) R`` (eq. 16) the fitter
of two species wins and species of equal fitness coexist.

The iteration is eq. 9 with ``dt = 1`` (one filter step). For a logistic map
``N <- N + r N (1 - N / K)`` the equilibrium is stable for ``0 < r < 2``; the growth rates used
here (0.05-0.2, the paper's 0.2 included) are well inside, and the iteration converges
geometrically, so a few hundred to a thousand steps reach the equilibria to ~1e-9.
"""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters.ceamcl.competition import (
    carrying_capacity,
    competition_coefficients,
    living_domain,
    lotka_volterra_increments,
    resources,
    simulate_competition,
    step_increments,
)


def alpha2(a12: float, a21: float) -> np.ndarray:
    return np.array([[0.0, a12], [a21, 0.0]])


# ---------------------------------------------------------------- Fig. 1, fixed K and alpha
def test_fig1a_species_one_wins() -> None:
    k = np.array([100.0, 80.0])
    a12, a21 = 0.5, 1.5
    assert k[1] / a21 < k[0] and k[0] / a12 > k[1]  # case (a)
    traj = simulate_competition([10.0, 60.0], k, alpha2(a12, a21), 0.1, 1000)
    n1, n2 = traj[-1]
    # Balance point N1 = K1, N2 = 0. Near it N2 shrinks by r (1 - a21 K1 / K2) = -0.0875 per
    # step, so after 1000 steps it is ~e^-90 of its size: far below 1e-9.
    assert n1 == pytest.approx(k[0], rel=1e-9)
    assert n2 < 1e-9
    assert np.all(traj >= 0.0) and np.all(np.isfinite(traj))


def test_fig1b_species_two_wins() -> None:
    k = np.array([80.0, 100.0])
    a12, a21 = 1.5, 0.5
    assert k[1] / a21 > k[0] and k[0] / a12 < k[1]  # case (b), the mirror of (a)
    traj = simulate_competition([60.0, 10.0], k, alpha2(a12, a21), 0.1, 1000)
    n1, n2 = traj[-1]
    assert n1 < 1e-9
    assert n2 == pytest.approx(k[1], rel=1e-9)


def test_fig1c_initial_populations_decide_the_winner() -> None:
    k = np.array([100.0, 100.0])
    a12, a21 = 1.5, 1.5
    assert k[1] / a21 < k[0] and k[0] / a12 < k[1]  # case (c)
    # The interior equilibrium (40, 40) is a saddle; its stable manifold is N1 = N2 here.
    saddle = (k[0] - a12 * k[1]) / (1 - a12 * a21)
    assert saddle == pytest.approx(40.0)
    alpha = alpha2(a12, a21)
    first = simulate_competition([60.0, 20.0], k, alpha, 0.1, 1000)[-1]
    second = simulate_competition([20.0, 60.0], k, alpha, 0.1, 1000)[-1]
    assert first[0] == pytest.approx(k[0], rel=1e-9) and first[1] < 1e-9
    assert second[1] == pytest.approx(k[1], rel=1e-9) and second[0] < 1e-9
    # Even a small head start decides it.
    close = simulate_competition([41.0, 39.0], k, alpha, 0.1, 2000)[-1]
    assert close[0] == pytest.approx(k[0], rel=1e-6) and close[1] < 1e-6


@pytest.mark.parametrize("r", [0.05, 0.2])
def test_fig1d_coexistence_at_the_interior_equilibrium(r: float) -> None:
    k = np.array([100.0, 80.0])
    a12, a21 = 0.5, 0.4
    assert k[1] / a21 > k[0] and k[0] / a12 > k[1]  # case (d)
    n1_star = (k[0] - a12 * k[1]) / (1 - a12 * a21)
    n2_star = (k[1] - a21 * k[0]) / (1 - a12 * a21)
    assert (n1_star, n2_star) == pytest.approx((75.0, 50.0))
    for start in ([5.0, 5.0], [150.0, 2.0], [1.0, 120.0]):
        traj = simulate_competition(start, k, alpha2(a12, a21), r, 2000)
        np.testing.assert_allclose(traj[-1], [n1_star, n2_star], rtol=1e-9)
        # The increments vanish there.
        np.testing.assert_allclose(
            lotka_volterra_increments(traj[-1], k, alpha2(a12, a21), r), 0.0, atol=1e-7
        )


# ---------------------------------------------------------------- the paper's alpha and K
def paper_k_alpha(w: np.ndarray, total_resources: float) -> tuple[np.ndarray, np.ndarray]:
    return carrying_capacity(w, total_resources), competition_coefficients(w)


def test_paper_alpha_and_capacity_formulas() -> None:
    w = np.array([0.5, 0.95, 0.8])
    k, alpha = paper_k_alpha(w, 120.0)
    np.testing.assert_allclose(k, np.exp(1 - w) * 120.0)
    for i in range(3):
        for j in range(3):
            assert alpha[i, j] == pytest.approx(0.0 if i == j else w[j] / w[i])


def test_fitter_species_always_falls_in_case_a() -> None:
    """With alpha_ij = w_j / w_i and K_i = exp(1 - w_i) R, K1/a12 > K2 <=> f(w1) > f(w2) with
    f(w) = w exp(-w), increasing on (0, 1] (NOTES.md): the fitter species wins, whatever R
    (the paper's remark that scaling R by lambda does not change the outcome)."""
    grid = np.linspace(0.05, 1.0, 20)
    for w1 in grid:
        for w2 in grid[grid < w1]:
            for total in (40.0, 400.0, 4000.0):
                k, a = paper_k_alpha(np.array([w1, w2]), total)
                assert k[1] / a[1, 0] < k[0]
                assert k[0] / a[0, 1] > k[1]


def test_species_of_clearly_lower_fitness_dies_out() -> None:
    w = np.array([0.95, 0.5])
    total = 2 * 80.0 * 0.5  # two species at the minimum living domain (delta * epsilon each)
    k, alpha = paper_k_alpha(w, total)
    r = 0.2  # the paper's growth rate
    traj = simulate_competition([50.0, 50.0], k, alpha, r, 300)
    # Near (K1, 0) the weak species shrinks by r (1 - a21 K1 / K2) = -0.042 per step: from 50
    # to 1 in ~100 steps, so 300 steps (30 s at 10 Hz) are ample.
    rate = r * (1 - alpha[1, 0] * k[0] / k[1])
    assert rate < -0.04
    below = np.nonzero(traj[:, 1] < 1.0)[0]
    assert below.size and below[0] <= 300
    print(f"weak species below 1 after {below[0]} steps; final sizes {traj[-1]}")
    assert traj[-1, 0] == pytest.approx(k[0], rel=1e-3)
    assert np.all(np.diff(traj[20:, 1]) < 0)  # once the strong one has grown: steady decline


@pytest.mark.parametrize("w", [0.3, 0.8, 1.0])
def test_species_of_equal_fitness_coexist(w: float) -> None:
    fit = np.array([w, w])
    k, alpha = paper_k_alpha(fit, 80.0)
    assert np.all(alpha[~np.eye(2, dtype=bool)] == 1.0)
    traj = simulate_competition([30.0, 10.0], k, alpha, 0.2, 400)
    assert np.all(traj > 0.0)
    # Both species feel the same pressure N1 + N2: equal per-capita growth, so their ratio is
    # unchanged while the total approaches K.
    np.testing.assert_allclose(traj[:, 0] / traj[:, 1], 3.0, rtol=1e-12)
    assert traj[-1].sum() == pytest.approx(k[0], rel=1e-9)


def test_many_equal_species_keep_their_shares() -> None:
    fit = np.full(5, 0.9)
    k, alpha = paper_k_alpha(fit, 5 * 40.0)
    n0 = np.array([5.0, 20.0, 40.0, 80.0, 3.0])
    traj = simulate_competition(n0, k, alpha, 0.2, 400)
    shares = traj / traj.sum(axis=1, keepdims=True)
    np.testing.assert_allclose(shares, np.broadcast_to(n0 / n0.sum(), shares.shape), rtol=1e-12)
    assert traj[-1].sum() == pytest.approx(k[0], rel=1e-9)


# ---------------------------------------------------------------- living domain, resources
@pytest.mark.parametrize("phi_deg", [0.0, 30.0, 117.0])
def test_living_domain_of_a_rotated_covariance(phi_deg: float) -> None:
    phi = np.deg2rad(phi_deg)
    rot = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    d1, d2 = 0.04, 0.25
    q = rot @ np.diag([d1, d2]) @ rot.T
    d, u, area = living_domain(q)
    np.testing.assert_allclose(np.sort(d), [d1, d2], rtol=1e-12)
    # eq. 14 corrected (NOTES.md error 1): radii 2 sqrt(d_j), area pi * 2 sqrt(d1) * 2 sqrt(d2).
    assert area == pytest.approx(4 * np.pi * np.sqrt(d1 * d2), rel=1e-12)
    # eigh sorts ascending: e_1 is along the rotated x axis (variance d1), e_2 along y.
    assert abs(u[:, 0] @ rot[:, 0]) == pytest.approx(1.0, abs=1e-12)
    assert abs(u[:, 1] @ rot[:, 1]) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(u @ np.diag(d) @ u.T, q, atol=1e-15)


def test_living_domain_degenerate_covariances() -> None:
    for q in (
        np.zeros((2, 2)),
        np.array([[1.0, 1.0], [1.0, 1.0]]),  # all samples on a line
        np.full((2, 2), np.nan),
        np.array([[np.inf, 0.0], [0.0, 1.0]]),
    ):
        d, u, area = living_domain(q)
        assert area == pytest.approx(0.0, abs=1e-6)
        assert np.all(np.isfinite(d)) and np.all(np.isfinite(u)) and np.isfinite(area)
        assert np.all(d >= 0.0)


def test_resources_have_a_floor() -> None:
    delta, eps = 80.0, 0.5
    area = np.array([0.0, 0.1, 0.5, 0.51, 3.0])
    np.testing.assert_allclose(resources(area, delta, eps), delta * np.maximum(area, eps))
    np.testing.assert_allclose(resources(area, delta, eps)[:3], delta * eps)


def test_increment_with_non_positive_capacity_shrinks_without_inf() -> None:
    n = np.array([10.0, 10.0, 0.0, 5.0])
    k = np.array([0.0, -5.0, 0.0, 50.0])
    alpha = np.zeros((4, 4))
    dn = lotka_volterra_increments(n, k, alpha, 0.2)
    assert np.all(np.isfinite(dn))
    assert np.all(dn[:3] <= 0.0)
    assert dn[0] < 0 and dn[1] < 0 and dn[2] == 0.0
    assert dn[3] == pytest.approx(0.2 * 5.0 * (1 - 5.0 / 50.0))
    traj = simulate_competition(n, k, alpha, 0.2, 200)
    assert np.all(np.isfinite(traj)) and np.all(traj >= 0.0)


def test_step_increments_never_overshoot_and_keep_the_direction() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        s = int(rng.integers(1, 6))
        n = rng.uniform(1.0, 2000.0, s)
        w = rng.uniform(0.01, 1.0, s)
        cap = carrying_capacity(w, float(rng.uniform(1.0, 3000.0)))
        euler = lotka_volterra_increments(n, cap, competition_coefficients(w), 0.2)
        dn = step_increments(n, cap, competition_coefficients(w), 0.2)
        assert np.all(n + dn >= 0)  # never a negative size
        # A decline follows the exact solution at eq. 9's per-capita rate over the step
        # (Euler would go below zero once that rate is below -1).
        rho = euler / n
        np.testing.assert_allclose(
            (n + dn)[rho < 0], (n * np.exp(rho))[rho < 0], rtol=1e-9, atol=1e-9
        )
        assert np.array_equal(np.sign(dn), np.sign(euler))  # Fig. 1's outcomes unchanged
        grow = euler >= 0
        assert np.array_equal(dn[grow], euler[grow])  # growth is eq. 9 as printed
        assert np.all(dn[~grow] >= euler[~grow])  # a decline is never steeper than Euler's


def test_step_increments_match_eq9_for_a_gentle_decline() -> None:
    n = np.array([100.0])
    cap = np.array([90.0])  # 10 % over capacity: per-capita rate -0.2 * 0.111
    euler = lotka_volterra_increments(n, cap, np.zeros((1, 1)), 0.2)
    assert step_increments(n, cap, np.zeros((1, 1)), 0.2) == pytest.approx(euler, rel=0.02)
