"""``pose.inside_ellipse``: the calibration measure of docs/sensor-models.md."""

from __future__ import annotations

import numpy as np

from ceamcl.pose import inside_ellipse


def test_a_calibrated_gaussian_lands_inside_its_2_sigma_ellipse_865_percent_of_the_time() -> None:
    rng = np.random.default_rng(0)
    cov = np.array([[0.04, 0.015, 0.0], [0.015, 0.01, 0.0], [0.0, 0.0, 0.01]])
    n = 20_000
    truth = rng.multivariate_normal(np.zeros(3), cov, n)
    inside = inside_ellipse(np.zeros((n, 3)), np.broadcast_to(cov, (n, 3, 3)), truth)
    assert abs(inside.mean() - (1 - np.exp(-2))) < 0.01  # 86.5 %
    # overconfident by a factor 4 in variance: far fewer
    tight = inside_ellipse(np.zeros((n, 3)), np.broadcast_to(cov / 4, (n, 3, 3)), truth)
    assert tight.mean() < 0.45


def test_singular_or_nan_covariances_count_as_outside_unless_exact() -> None:
    est = np.zeros((3, 3))
    truth = np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.0]])
    covs = np.stack([np.zeros((3, 3)), np.full((3, 3), np.nan), np.zeros((3, 3))])
    assert inside_ellipse(est, covs, truth).tolist() == [False, False, True]
