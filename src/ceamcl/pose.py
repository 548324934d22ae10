"""Statistics of weighted pose sets ``(N, 3)``: mean with a circular mean heading, covariance;
errors between poses and poses in another pose's frame."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import circular_mean, diff

#: Poses beyond these are not of a building (and overflow the motion model's squares): a
#: position further than 10,000 km from the origin, a heading of more than 10^6 rad (a log's
#: headings may run on unwrapped, a few hundred turns at most). Log poses
#: (:func:`ceamcl.io.recorded.check_pose_values`) and a map's origin are bounded by them.
POSE_LIMIT_M = 1e7
HEADING_LIMIT_RAD = 1e6


def normalised(weights: ArrayLike | None, n: int) -> NDArray[np.float64]:
    """Weights summing to 1; uniform when absent, empty, or not positive/finite in total."""
    if weights is None:
        return np.full(n, 1.0 / max(n, 1))
    w = np.asarray(weights, dtype=np.float64)
    w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
    total = float(w.sum())
    if total <= 0.0:
        return np.full(n, 1.0 / max(n, 1))
    return w / total


def pose_mean(poses: ArrayLike, weights: ArrayLike | None = None) -> NDArray[np.float64]:
    """Weighted mean ``(x, y, theta)``; the heading is the circular mean."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        raise ValueError("pose_mean: no poses")
    w = normalised(weights, p.shape[0])
    # NumPy's own sums, not BLAS (``w @ x``): OpenBLAS picks its kernel by CPU, and the last
    # bits of a dot product differ between them, so a seed would not give the same run on
    # another machine (docs/architecture.md, "Bits that do not depend on the machine").
    return np.array([np.sum(w * p[:, 0]), np.sum(w * p[:, 1]), circular_mean(p[:, 2], w)])


def pose_covariance(
    poses: ArrayLike, weights: ArrayLike | None = None, mean: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Weighted ``3 x 3`` covariance; heading deviations are wrapped differences from the mean."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    w = normalised(weights, p.shape[0])
    m = pose_mean(p, w) if mean is None else np.asarray(mean, dtype=np.float64)
    d = np.column_stack([p[:, 0] - m[0], p[:, 1] - m[1], diff(p[:, 2], m[2])])
    wd = d * w[:, None]
    cov = np.empty((3, 3))
    for i in range(3):  # NumPy's sums, not BLAS: see pose_mean
        for j in range(i, 3):
            cov[i, j] = cov[j, i] = np.sum(wd[:, i] * d[:, j])
    return cov


def position_error(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Euclidean distance between the x-y parts of poses."""
    a_ = np.asarray(a, dtype=np.float64)
    b_ = np.asarray(b, dtype=np.float64)
    return np.hypot(a_[..., 0] - b_[..., 0], a_[..., 1] - b_[..., 1])


def heading_error(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Absolute wrapped heading difference."""
    return np.abs(
        diff(np.asarray(a, dtype=np.float64)[..., 2], np.asarray(b, dtype=np.float64)[..., 2])
    )


def inside_ellipse(
    estimates: ArrayLike, covariances: ArrayLike, truth: ArrayLike, n_sigma: float = 2.0
) -> NDArray[np.bool_]:
    """Per row: does the true position lie inside the ``n_sigma`` ellipse of the estimate's x-y
    covariance (squared Mahalanobis distance <= ``n_sigma^2``)? A Gaussian puts 86.5 % of its
    mass inside its 2-sigma ellipse, so a calibrated filter scores near that share of its
    steps; far below is overconfident. A singular or non-finite covariance counts as outside
    (unless the error is exactly 0)."""
    est = np.asarray(estimates, dtype=np.float64)
    e = np.asarray(truth, dtype=np.float64)[..., :2] - est[..., :2]
    c = np.asarray(covariances, dtype=np.float64)[..., :2, :2]
    a, b, d = c[..., 0, 0], c[..., 0, 1], c[..., 1, 1]
    det = a * d - b * b
    ex, ey = e[..., 0], e[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        m2 = (d * ex * ex - 2.0 * b * ex * ey + a * ey * ey) / det
    m2 = np.where(np.isfinite(m2) & (det > 0), m2, np.where((ex == 0) & (ey == 0), 0.0, np.inf))
    return np.asarray(m2 <= n_sigma * n_sigma, dtype=bool)


def relative_poses(base: ArrayLike, other: ArrayLike) -> NDArray[np.float64]:
    """Pose of ``other`` in the frame of ``base`` (both world poses ``(N, 3)``): the laser's
    mount from its world pose and the robot's, an odometry increment in the robot's frame."""
    b = np.asarray(base, dtype=np.float64)
    o = np.asarray(other, dtype=np.float64)
    dx, dy = o[:, 0] - b[:, 0], o[:, 1] - b[:, 1]
    c, s = np.cos(b[:, 2]), np.sin(b[:, 2])
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, diff(o[:, 2], b[:, 2])])
