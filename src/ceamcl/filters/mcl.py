"""MCL: the standard particle filter (Dellaert et al. 1999; Probabilistic Robotics Table 8.2).

One step: move every particle with the motion model (predict), multiply its weight by the
scan's likelihood (weight), and resample with the low-variance sampler when the effective
sample size falls below ``resample_ess_fraction * N`` (resample). Global localisation starts
from particles uniform over free space, weighted by the first scan.

Safeguards (docs/robustness.md): a missing scan, or one with no usable beam, leaves the weights
unchanged (no weighting, no genetic operators); NaN or +inf likelihoods count as impossible;
when every particle is impossible the filter re-initialises uniformly over free space and the
step's :class:`StepDiagnostics` says ``reinitialised=True``.

The estimate is the weighted mean of all particles with a circular mean heading; in a
symmetric world it can fall between modes, which is why :meth:`MCL.hypotheses` also reports
the particle clusters (as ROS amcl does), heaviest first.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import wrap
from ceamcl.errors import ConfigError, LogFormatError
from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    ParticleSnapshot,
    PoseEstimate,
    StepDiagnostics,
)
from ceamcl.filters.clustering import cluster_labels
from ceamcl.filters.resampling import (
    effective_sample_size,
    normalise_log_weights,
    sanitise_log_likelihood,
    systematic,
)
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel
from ceamcl.pose import pose_covariance, pose_mean
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.scan import LaserScan, PreparedScan


def check_increment(increment: OdometryIncrement) -> None:
    """Refuse an odometry increment with a NaN or infinite component (it would turn every
    particle into NaN)."""
    values = (increment.rot1, increment.trans, increment.rot2)
    if not all(math.isfinite(v) for v in values):
        raise LogFormatError(
            f"odometry increment: expected finite rot1, trans, rot2, got {values} "
            f"(is an odometry pose NaN or infinite?)"
        )


def gaussian_poses(
    pose: ArrayLike, covariance: ArrayLike, n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``n`` poses from ``N(pose, covariance)``, headings wrapped.

    Draws exactly what ``rng.multivariate_normal(..., method="cholesky")`` draws for a positive
    definite covariance; a positive semi-definite one (e.g. all zeros: every particle on the
    pose) is factored by its eigen-decomposition instead of failing.

    Raises:
        ConfigError: ``pose`` is not three finite numbers, or ``covariance`` not a finite,
            symmetric, positive semi-definite ``3 x 3`` matrix.
    """
    mean = np.asarray(pose, dtype=np.float64).reshape(-1)
    if mean.shape != (3,) or not np.all(np.isfinite(mean)):
        raise ConfigError(f"pose: expected three finite numbers (x, y, theta), got {pose!r}")
    cov = np.asarray(covariance, dtype=np.float64)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise ConfigError(f"covariance: expected a finite 3 x 3 matrix, got shape {cov.shape}")
    scale = max(float(np.abs(cov).max()), 1e-300)
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-12 * scale):
        raise ConfigError("covariance: expected a symmetric matrix")
    try:
        factor = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        d, u = np.linalg.eigh(0.5 * (cov + cov.T))
        if d.min() < -1e-9 * scale:
            raise ConfigError(
                f"covariance: expected a positive semi-definite matrix, eigenvalues {d.tolist()}"
            ) from None
        factor = u * np.sqrt(np.clip(d, 0.0, None))
    out = mean + np.dot(rng.standard_normal((n, 3)), factor.T)
    out[:, 2] = wrap(out[:, 2])
    return np.asarray(out, dtype=np.float64)


def cluster_hypotheses(
    poses: NDArray[np.float64],
    weights: NDArray[np.float64],
    fitness: NDArray[np.float64],
    labels: NDArray[np.int64],
    count: int,
    limit: int | None = None,
) -> list[Hypothesis]:
    """The particle clusters ``labels`` (in ``0..count-1``) as hypotheses, heaviest first
    (equal masses: lower label first); only the ``limit`` heaviest when given. Each has its
    members' weighted mean pose and covariance, its share of the weight and mean fitness."""
    mass = np.bincount(labels, weights=weights, minlength=count)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(count + 1))
    out = []
    for k in np.argsort(-mass, kind="stable")[:limit]:
        members = order[bounds[k] : bounds[k + 1]]
        wk = weights[members]
        mean = pose_mean(poses[members], wk)
        out.append(
            Hypothesis(
                pose=mean,
                covariance=pose_covariance(poses[members], wk, mean),
                n_particles=int(members.size),
                weight=float(mass[k]),
                fitness=float(np.mean(fitness[members])),
                label=int(k),
            )
        )
    return out


@dataclass(frozen=True)
class MCLConfig:
    """MCL settings.

    n_particles: fixed sample size.
    resample_ess_fraction: resample when ESS < fraction x N (1.0 resamples every step).
    cluster_cell_m: cell size of the x-y grid whose connected regions are the hypotheses.
    """

    n_particles: int = 5000
    resample_ess_fraction: float = 0.5
    cluster_cell_m: float = 0.5

    def __post_init__(self) -> None:
        if self.n_particles < 1:
            raise ValueError(f"n_particles: expected >= 1, got {self.n_particles}")
        if not 0.0 <= self.resample_ess_fraction <= 1.0:
            raise ValueError(
                f"resample_ess_fraction: expected in [0, 1], got {self.resample_ess_fraction}"
            )
        if not self.cluster_cell_m > 0:
            raise ValueError(f"cluster_cell_m: expected > 0, got {self.cluster_cell_m}")


class MCL:
    """Monte Carlo localisation with a fixed number of particles."""

    name = "mcl"

    def __init__(
        self,
        grid: OccupancyGrid,
        motion: OdometryMotionModel,
        sensor: SensorModel,
        config: MCLConfig | None = None,
        *,
        rng: np.random.Generator,
    ) -> None:
        self.grid = grid
        self.motion = motion
        self.sensor = sensor
        self.config = config or MCLConfig()
        self.rng = rng
        n = self.config.n_particles
        self.poses: NDArray[np.float64] = np.zeros((n, 3))
        self.log_weights: NDArray[np.float64] = np.full(n, -np.log(n))
        self.fitness: NDArray[np.float64] = np.ones(n)
        self.loglik: NDArray[np.float64] = np.zeros(n)
        self.t = 0
        self._evaluations = 0
        self._prior_log_weights: NDArray[np.float64] = self.log_weights.copy()
        self._prepared: PreparedScan | None = None
        self._resampled = False

    # ------------------------------------------------------------------ initialisation
    def initialise_global(self, scan: LaserScan) -> StepDiagnostics:
        start = time.perf_counter()
        self.t = 0
        self.poses = self.grid.sample_free_poses(self.config.n_particles, self.rng)
        self.log_weights = np.full(self.poses.shape[0], -np.log(self.poses.shape[0]))
        self._evaluations = 0
        reinit = self._weight(scan)
        self._after_weighting()
        return self._diagnostics(start, reinit)

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        self.t = 0
        n = self.config.n_particles
        self.poses = gaussian_poses(pose, covariance, n, self.rng)
        self.log_weights = np.full(n, -np.log(n))
        self.fitness = np.ones(n)
        self.loglik = np.zeros(n)
        self._prepared = None

    # ------------------------------------------------------------------ one step
    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepDiagnostics:
        start = time.perf_counter()
        check_increment(increment)
        self.t += 1
        self._evaluations = 0
        self._prepared = None  # set by _weight when the scan has a usable beam
        self.poses = self.motion.sample(self.poses, increment, self.rng)
        reinit = self._weight(scan) if scan is not None else False
        self._after_weighting()
        return self._diagnostics(start, reinit)

    def _weight(self, scan: LaserScan) -> bool:
        """Importance weighting; returns True when the filter had to re-initialise.

        A scan with no usable beam leaves everything as it is (``self._prepared`` stays None,
        so no genetic operator runs either)."""
        self._prepared = None
        prepared = self.sensor.prepare(scan)
        if prepared.n_beams == 0:
            return False
        self._prepared = prepared
        ll = sanitise_log_likelihood(self.sensor.log_likelihood(self.poses, prepared))
        self._evaluations += self.poses.shape[0]
        self.loglik = ll
        self.fitness = fitness(ll, prepared, self.sensor)
        self._prior_log_weights = self.log_weights.copy()
        log_w, _, ok = normalise_log_weights(self.log_weights + ll)
        if not ok:
            # Every particle impossible (or the model returned NaN): start again from scratch.
            n = self.config.n_particles
            self.poses = self.grid.sample_free_poses(n, self.rng)
            self.log_weights = np.full(n, -np.log(n))
            self.fitness = np.ones(n)
            self.loglik = np.zeros(n)
            self._prior_log_weights = self.log_weights.copy()
            self._prepared = None
            return True
        self.log_weights = log_w
        return False

    def _after_weighting(self) -> None:
        """Hook for GMCL's genetic operators; then resample when the weights degenerate."""
        if self._prepared is not None:
            self._evolve()
        w = self.weights
        if effective_sample_size(w) < self.config.resample_ess_fraction * w.size:
            self._resample(w)

    def _evolve(self) -> None:
        """No evolution in plain MCL."""

    def _resample(self, w: NDArray[np.float64]) -> None:
        idx = systematic(w, self.config.n_particles, self.rng)
        self.poses = self.poses[idx]
        self.fitness = self.fitness[idx]
        self.loglik = self.loglik[idx]
        self.log_weights = np.full(idx.size, -np.log(idx.size))
        self._resampled = True

    def _diagnostics(self, start: float, reinitialised: bool) -> StepDiagnostics:
        resampled, self._resampled = self._resampled, False
        return StepDiagnostics(
            step=self.t,
            n_particles=int(self.poses.shape[0]),
            ess=effective_sample_size(self.weights),
            resampled=resampled,
            likelihood_evaluations=self._evaluations,
            step_ms=(time.perf_counter() - start) * 1e3,
            reinitialised=reinitialised,
        )

    # ------------------------------------------------------------------ queries
    @property
    def weights(self) -> NDArray[np.float64]:
        return normalise_log_weights(self.log_weights)[1]

    def estimate(self) -> PoseEstimate:
        w = self.weights
        mean = pose_mean(self.poses, w)
        return PoseEstimate(mean, pose_covariance(self.poses, w, mean))

    def _labels(self) -> tuple[NDArray[np.int64], int]:
        return cluster_labels(self.poses[:, :2], self.config.cluster_cell_m)

    def hypotheses(self) -> list[Hypothesis]:
        return cluster_hypotheses(self.poses, self.weights, self.fitness, *self._labels())

    def particles(self) -> ParticleSnapshot:
        labels, _ = self._labels()
        return ParticleSnapshot(self.poses.copy(), self.weights, labels)


ALGORITHM = Algorithm(
    "mcl",
    MCLConfig,
    MCL,
    with_particles=lambda cfg, n: replace(cfg, n_particles=n),
    summary="Monte Carlo localisation with a fixed sample size (the paper's first baseline)",
)
