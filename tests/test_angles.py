"""Tests of angle wrapping, differences and circular statistics (``ceamcl.angles``)."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.angles import circular_mean, circular_variance, diff, interpolate, wrap


def test_wrap_lands_in_half_open_interval_and_keeps_direction() -> None:
    rng = np.random.default_rng(0)
    a = rng.uniform(-40.0, 40.0, 100_000)
    w = wrap(a)
    assert np.all(w > -np.pi)
    assert np.all(w <= np.pi)
    # Same direction: the shift is a whole number of turns.
    turns = (a - w) / (2.0 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    # Angles already inside the interval are left alone.
    inside = rng.uniform(-3.14, 3.14, 1000)
    np.testing.assert_allclose(wrap(inside), inside, atol=1e-12)


def test_wrap_of_pi_and_minus_pi_is_pi() -> None:
    assert float(wrap(np.pi)) == np.pi
    assert float(wrap(-np.pi)) == np.pi
    assert float(wrap(3.0 * np.pi)) == pytest.approx(np.pi, abs=1e-12)
    assert float(wrap(-3.0 * np.pi)) == pytest.approx(np.pi, abs=1e-12)
    assert float(wrap(0.0)) == 0.0
    # Just past -pi stays near -pi (it is inside the interval).
    assert float(wrap(-np.pi + 1e-6)) == pytest.approx(-np.pi + 1e-6, abs=1e-12)
    # One ulp above pi: np.mod rounds the tiny negative up to 2 pi, which gave -pi.
    from ceamcl.angles import wrap_one

    above = np.nextafter(np.pi, 4.0)
    assert float(wrap(above)) == np.pi and float(wrap(np.array([above]))[0]) == np.pi
    assert wrap_one(above) == np.pi


def test_diff_is_the_shortest_signed_difference() -> None:
    assert float(diff(0.1, -0.1)) == pytest.approx(0.2)
    # Across the +-pi seam the short way is 0.2, not -(2 pi - 0.2).
    assert float(diff(-np.pi + 0.1, np.pi - 0.1)) == pytest.approx(0.2)
    assert float(diff(np.pi - 0.1, -np.pi + 0.1)) == pytest.approx(-0.2)
    rng = np.random.default_rng(1)
    a, b = rng.uniform(-10, 10, (2, 10_000))
    d = diff(a, b)
    assert np.all(np.abs(d) <= np.pi)
    np.testing.assert_allclose(np.cos(d), np.cos(a - b), atol=1e-9)
    np.testing.assert_allclose(np.sin(d), np.sin(a - b), atol=1e-9)


def test_circular_mean_near_pi_is_pi_not_zero() -> None:
    angles = np.array([np.pi - 0.1, -np.pi + 0.1, np.pi - 0.05, -np.pi + 0.05])
    assert abs(float(np.mean(angles))) < 1e-12  # the plain mean is wrong: 0
    m = circular_mean(angles)
    assert abs(float(diff(m, np.pi))) < 1e-12


def test_circular_mean_weighted_and_of_samples() -> None:
    # Weights pull the mean towards the heavier angle, along the short arc across the seam.
    a, b = np.pi - 0.2, -np.pi + 0.2
    m = circular_mean([a, b], weights=[3.0, 1.0])
    expected = np.arctan2(3 * np.sin(a) + np.sin(b), 3 * np.cos(a) + np.cos(b))
    assert m == pytest.approx(float(expected), abs=1e-12)
    assert np.pi - 0.2 < m <= np.pi
    # Samples of a wrapped normal around 3.0 rad: the circular mean is 3.0 within 5 standard
    # errors (sigma / sqrt(n) for small sigma).
    rng = np.random.default_rng(2)
    sigma, n = 0.3, 100_000
    a = wrap(3.0 + sigma * rng.standard_normal(n))
    assert abs(float(diff(circular_mean(a), 3.0))) < 5 * sigma / np.sqrt(n)


def test_circular_mean_without_resultant_is_finite() -> None:
    # Round-off leaves a ~1e-16 resultant here, so the direction is arbitrary, but never NaN.
    m = circular_mean([0.0, np.pi / 2, np.pi, -np.pi / 2])
    assert np.isfinite(m)
    assert -np.pi <= m <= np.pi
    # An exactly vanishing resultant gives 0.
    assert circular_mean([]) == 0.0
    assert circular_mean([0.5, 0.5], weights=[0.0, 0.0]) == 0.0


def test_circular_variance_of_wrapped_normal_is_sigma_squared() -> None:
    # For a wrapped normal, R = exp(-sigma^2 / 2), so -2 ln R = sigma^2. The standard error of
    # the estimate: var(cos x) = (1 - e^{-s^2})^2 / 2 ~ 0.045 for s = 0.3, SE(R) = sqrt(0.045/n),
    # SE(-2 ln R) = 2 SE(R) / R ~ 1.4e-3 at n = 1e5; 5 SE = 7e-3.
    rng = np.random.default_rng(3)
    sigma, n = 0.3, 100_000
    a = wrap(np.pi + sigma * rng.standard_normal(n))
    assert circular_variance(a) == pytest.approx(sigma**2, abs=7e-3)
    assert circular_variance([1.0, 1.0, 1.0]) == pytest.approx(0.0, abs=1e-12)
    assert circular_variance([0.0, np.pi]) > 50.0  # no resultant: huge spread, finite
    assert np.isfinite(circular_variance([0.0, np.pi]))


def test_interpolate_takes_the_short_arc() -> None:
    # From 3.0 to -3.0 the short way crosses pi (0.28 rad), not 0 (6 rad).
    mid = interpolate(3.0, -3.0, 0.5)
    assert abs(float(diff(mid, np.pi))) < 1e-12
    assert float(interpolate(3.0, -3.0, 0.0)) == pytest.approx(3.0)
    assert float(diff(interpolate(3.0, -3.0, 1.0), -3.0)) == pytest.approx(0.0, abs=1e-12)
    quarter = interpolate(3.0, -3.0, 0.25)
    assert float(diff(quarter, 3.0)) == pytest.approx(0.25 * (2 * np.pi - 6.0), abs=1e-12)
    # Vectorised over fractions, results wrapped.
    fr = np.linspace(0.0, 1.0, 11)
    out = interpolate(-3.0, 3.0, fr)
    assert np.all((out > -np.pi) & (out <= np.pi))
    assert np.all(np.abs(diff(out, -3.0)) <= 2 * np.pi - 6.0 + 1e-12)
