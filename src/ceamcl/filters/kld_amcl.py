"""KLD-AMCL: the adaptive particle filter of ROS and Nav2 ``amcl`` (Fox 2003; Thrun et al. 2005).

Written after the behaviour of amcl's ``pf`` library and node, with the project's motion and
sensor models:

* **Update thresholds.** Odometry accumulates between filter updates; a scan triggers an
  update only once the odometry pose has moved more than ``update_min_d`` along x or y, or
  turned more than ``update_min_a``, since the last update (amcl tests each axis of the
  odometry frame). The first scan after an initialisation always updates. An update moves
  the particles by the whole accumulated motion, then weights them.
* **Sensor update** in log space. NaN and +inf likelihoods count as impossible; a scan with no
  usable beam changes nothing. If every particle is impossible the filter re-initialises
  globally (``max_particles`` poses uniform over free space, the next scan updates at once)
  and the step's :class:`StepDiagnostics` says ``reinitialised=True``, as MCL's does. (amcl
  only makes the weights uniform, which keeps a cloud no pose of which explains the scan.)
* **Augmented MCL** (Probabilistic Robotics Table 8.3): running averages ``w_slow`` and
  ``w_fast`` of the average weight, and at resampling each new particle is drawn uniformly
  over free space with probability ``max(0, 1 - w_fast / w_slow)``. Three deviations from
  amcl, all needed for recovery to fire after a kidnap (docs/baselines.md): the average
  weight is the per-beam marginal likelihood (:func:`average_weight`); the averages are
  bias-corrected running means (:func:`running_average`) rather than started at the first
  value; and they are *not* reset to 0 after an injection (the book's algorithm; amcl's reset
  restarts ``w_slow`` at the lost level and stops the recovery after one burst).
* **KLD-sampling** at resampling: particles are drawn one by one (multinomial, as amcl's
  roulette wheel) and dropped into a histogram of ``0.5 m x 0.5 m x 10 deg`` bins; drawing stops
  as soon as the count exceeds :func:`kld_sample_size` of the number of occupied bins, and
  never goes above ``max_particles``. Resampling happens every ``resample_interval``-th update.
* **Estimate** as amcl: the particles are grouped into clusters of connected occupied bins,
  and the estimate is the weighted mean of the heaviest cluster. Between updates it is carried
  along by the odometry since the last update, as amcl's map -> odom transform carries the
  robot. (Unlike amcl's kd-tree, our bins join across the +-pi heading seam.)
* **Global localisation**: ``max_particles`` poses uniform over free space.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.errors import ConfigError
from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    ParticleSnapshot,
    PoseEstimate,
    StepDiagnostics,
)
from ceamcl.filters.clustering import pose_cluster_labels
from ceamcl.filters.mcl import check_increment, cluster_hypotheses, gaussian_poses
from ceamcl.filters.resampling import (
    effective_sample_size,
    normalise_log_weights,
    sanitise_log_likelihood,
)
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import (
    OdometryIncrement,
    OdometryMotionModel,
    apply_increment,
    increment_between,
)
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.scan import LaserScan, PreparedScan

#: Upper standard-normal quantile for 1 - delta = 0.99 (amcl's ``kld_z`` default is 0.99 in the
#: ROS 1 wiki and Nav2's ``pf_z`` passes 0.99 itself, where the formula needs this quantile).
Z_099 = 2.33


def kld_sample_size(k: int, err: float, z: float, n_min: int, n_max: int) -> int:
    """KLD-sampling bound (Fox 2003, eq. 13) for ``k`` occupied bins, clamped to ``[n_min, n_max]``.

    ``n = (k - 1) / (2 err) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z)^3`` rounded up;
    with at most one occupied bin the bound is undefined and amcl, like this function, returns
    ``n_max``.
    """
    if k <= 1:
        return n_max
    b = 2.0 / (9.0 * (k - 1))
    x = 1.0 - b + math.sqrt(b) * z
    n = math.ceil((k - 1) / (2.0 * err) * x**3)
    return int(min(max(n, n_min), n_max))


def histogram_bins(
    poses: NDArray[np.float64], bin_xy_m: float, bin_theta_rad: float
) -> NDArray[np.int64]:
    """Integer bin keys ``(N, 3)`` of poses: ``floor(x / bin_xy)``, ``floor(y / bin_xy)``,
    ``floor(theta / bin_theta)`` (amcl's kd-tree keys)."""
    return np.column_stack(
        [
            np.floor(poses[:, 0] / bin_xy_m),
            np.floor(poses[:, 1] / bin_xy_m),
            np.floor(poses[:, 2] / bin_theta_rad),
        ]
    ).astype(np.int64)


def occupied_bins_prefix(keys: NDArray[np.int64]) -> NDArray[np.int64]:
    """``out[m - 1]``: number of distinct bins among the first ``m`` keys (rows)."""
    if keys.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    new = np.zeros(keys.shape[0], dtype=np.int64)
    new[first] = 1
    return np.cumsum(new)


@dataclass(frozen=True)
class KLDAMCLConfig:
    """KLD-AMCL settings; defaults are Nav2 amcl's (``kld_z`` see :data:`Z_099`).

    min_particles, max_particles: bounds of the sample size (Nav2: 500, 2000).
    kld_err, kld_z: KLD-sampling error bound and upper standard-normal quantile.
    bin_xy_m, bin_theta_rad: histogram bins of KLD-sampling and of the clusters.
    alpha_slow, alpha_fast: augmented-MCL decay rates; 0 and 0 (Nav2's default) turns it off.
    resample_interval: resample at every k-th filter update.
    update_min_d, update_min_a: odometry motion (per axis, m; rad) that triggers an update.
    """

    min_particles: int = 500
    max_particles: int = 2000
    kld_err: float = 0.05
    kld_z: float = Z_099
    bin_xy_m: float = 0.5
    bin_theta_rad: float = math.radians(10.0)
    alpha_slow: float = 0.0
    alpha_fast: float = 0.0
    resample_interval: int = 1
    update_min_d: float = 0.25
    update_min_a: float = 0.2

    def __post_init__(self) -> None:
        if self.min_particles < 1:
            raise ConfigError(f"min_particles: expected >= 1, got {self.min_particles}")
        if self.max_particles < self.min_particles:
            raise ConfigError(
                f"max_particles: expected >= min_particles ({self.min_particles}), "
                f"got {self.max_particles}"
            )
        if not (math.isfinite(self.kld_err) and 0.0 < self.kld_err < 1.0):
            raise ConfigError(f"kld_err: expected a number in (0, 1), got {self.kld_err}")
        if not (math.isfinite(self.kld_z) and self.kld_z > 0.0):
            raise ConfigError(f"kld_z: expected a positive quantile, got {self.kld_z}")
        for name in ("bin_xy_m", "bin_theta_rad"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ConfigError(f"{name}: expected a positive number, got {v}")
        for name in ("alpha_slow", "alpha_fast"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise ConfigError(f"{name}: expected a number in [0, 1], got {v}")
        if self.resample_interval < 1:
            raise ConfigError(f"resample_interval: expected >= 1, got {self.resample_interval}")
        for name in ("update_min_d", "update_min_a"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ConfigError(f"{name}: expected a non-negative number, got {v}")

    @property
    def recovery(self) -> bool:
        """Whether augmented-MCL recovery can inject random particles."""
        return self.alpha_slow > 0.0 and self.alpha_fast > 0.0


def average_weight(
    prior_log_weights: NDArray[np.float64],
    log_likelihood: NDArray[np.float64],
    prepared: PreparedScan,
    sensor: SensorModel,
) -> float:
    """The "average weight" that ``w_slow`` and ``w_fast`` follow: the per-beam marginal
    likelihood ``(sum_i w_i p(z | x_i))^(1 / n_beams) / p_max``, in [0, 1].

    ``sum_i w_i p(z | x_i)`` (prior weights ``w_i``) is what Probabilistic Robotics' average
    weight estimates: the likelihood of the scan given the past, ``p(z_t | z_1:t-1, u_1:t)``.
    Our likelihoods are products of beam likelihoods, so its magnitude swings by many orders with
    the number of usable beams alone; its ``n_beams``-th root over the largest one-beam
    likelihood ``p_max`` does not (1: a perfect match). Equivalently, a power mean of order
    ``n_beams`` of the per-beam fitness (:func:`~ceamcl.sensors.base.fitness`): it follows the
    best-placed particles, so it stays near 1 while the cloud tracks (however far the motion
    noise spreads it) and drops when no particle explains the scan. The plain weighted mean of
    the fitness (order 1) does not separate the two (docs/baselines.md). 0 when every particle
    is impossible.
    """
    x = prior_log_weights + log_likelihood
    top = float(np.max(x)) if x.size else -math.inf
    if not math.isfinite(top):
        return 0.0
    log_marginal = top + math.log(float(np.sum(np.exp(x - top))))
    per_beam = log_marginal / prepared.n_beams - sensor.max_log_beam_likelihood(prepared)
    return float(math.exp(min(per_beam, 0.0)))


def running_average(average: float, value: float, alpha: float, count: int) -> float:
    """Exponential running average with decay ``alpha``, bias-corrected at the start: the
    ``count``-th value (from 1) enters with weight ``max(alpha, 1 / count)``, so for the first
    ``1 / alpha`` values it is their plain mean, then the usual exponential average.

    amcl instead starts an average at its first value, which then counts as if it were the
    whole history: with ``alpha_slow = 0.001`` the average weight of the first (global, uniform)
    cloud would stand for ``w_slow`` for a thousand updates.
    """
    return average + max(alpha, 1.0 / count) * (value - average)


class KLDAMCL:
    """ROS/Nav2 amcl's adaptive particle filter (see the module docstring)."""

    name = "kld-amcl"

    def __init__(
        self,
        grid: OccupancyGrid,
        motion: OdometryMotionModel,
        sensor: SensorModel,
        config: KLDAMCLConfig | None = None,
        *,
        rng: np.random.Generator,
    ) -> None:
        self.grid = grid
        self.motion = motion
        self.sensor = sensor
        self.config = config or KLDAMCLConfig()
        self.rng = rng
        if self.config.recovery:
            self.name = "kld-amcl-recovery"
        n = self.config.max_particles
        self.poses: NDArray[np.float64] = np.zeros((n, 3))
        self.log_weights: NDArray[np.float64] = np.full(n, -math.log(n))
        self.fitness: NDArray[np.float64] = np.ones(n)
        self.w_slow = 0.0
        self.w_fast = 0.0
        self._n_averaged = 0  # values folded into w_slow and w_fast since the initialisation
        self.t = 0
        self.odom = np.zeros(3)  # odometry pose accumulated from the increments
        self.odom_at_update = np.zeros(3)  # odometry pose of the last filter update
        self._force_update = True
        self._resample_count = 0
        self._kld_target = n
        self._injected = 0
        self._w_diff = 0.0
        self._evaluations = 0

    # ------------------------------------------------------------------ initialisation
    def _reset(self, poses: NDArray[np.float64]) -> None:
        n = poses.shape[0]
        self.poses = poses
        self.log_weights = np.full(n, -math.log(n))
        self.fitness = np.ones(n)
        self.w_slow = self.w_fast = 0.0
        self._n_averaged = 0
        self.t = 0
        self.odom = np.zeros(3)
        self.odom_at_update = np.zeros(3)
        self._force_update = True
        self._resample_count = 0
        self._kld_target = n

    def initialise_global(self, scan: LaserScan) -> StepDiagnostics:
        """``max_particles`` poses uniform over free space, then a (forced) update with ``scan``."""
        start = time.perf_counter()
        self._reset(self.grid.sample_free_poses(self.config.max_particles, self.rng))
        self._evaluations = 0
        resampled, reinit = self._update(scan)
        return self._diagnostics(start, updated=True, resampled=resampled, reinitialised=reinit)

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """``max_particles`` poses from ``N(pose, covariance)`` (amcl's ``pf_init``)."""
        self._reset(gaussian_poses(pose, covariance, self.config.max_particles, self.rng))

    # ------------------------------------------------------------------ one step
    def _motion_since_update(self) -> OdometryIncrement:
        return increment_between(self.odom_at_update, self.odom)

    def _threshold_reached(self) -> bool:
        d = self.odom - self.odom_at_update
        da = math.remainder(float(d[2]), 2.0 * math.pi)
        cfg = self.config
        return (
            abs(d[0]) > cfg.update_min_d
            or abs(d[1]) > cfg.update_min_d
            or (abs(da) > cfg.update_min_a)
        )

    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepDiagnostics:
        start = time.perf_counter()
        check_increment(increment)
        self.t += 1
        self._evaluations = 0
        self.odom = apply_increment(self.odom, increment.rot1, increment.trans, increment.rot2)[0]
        if scan is None or not (self._force_update or self._threshold_reached()):
            return self._diagnostics(start, updated=False, resampled=False)
        self.poses = self.motion.sample(self.poses, self._motion_since_update(), self.rng)
        self.odom_at_update = self.odom.copy()
        resampled, reinit = self._update(scan)
        return self._diagnostics(start, updated=True, resampled=resampled, reinitialised=reinit)

    def _update(self, scan: LaserScan) -> tuple[bool, bool]:
        """Sensor update with ``scan``, then resampling when its interval comes; returns whether
        it resampled and whether it had to re-initialise globally."""
        self._force_update = False
        self._injected = 0
        prepared = self.sensor.prepare(scan)
        if prepared.n_beams == 0:
            return False, False  # the scan says nothing: weights and averages stay as they are
        ll = sanitise_log_likelihood(self.sensor.log_likelihood(self.poses, prepared))
        self._evaluations += self.poses.shape[0]
        prior_log_w = normalise_log_weights(self.log_weights)[0]
        log_w, _, ok = normalise_log_weights(prior_log_w + ll)
        if not ok:
            # Every particle impossible (or the model returned NaN): start again globally. The
            # averages skip this scan (it measured a cloud that is gone).
            n = self.config.max_particles
            self.poses = self.grid.sample_free_poses(n, self.rng)
            self.log_weights = np.full(n, -math.log(n))
            self.fitness = np.ones(n)
            self._kld_target = n
            self._force_update = True
            return False, True
        self.log_weights = log_w
        self.fitness = fitness(ll, prepared, self.sensor)
        cfg = self.config
        if cfg.recovery:
            w_avg = average_weight(prior_log_w, ll, prepared, self.sensor)
            self._n_averaged += 1
            self.w_slow = running_average(self.w_slow, w_avg, cfg.alpha_slow, self._n_averaged)
            self.w_fast = running_average(self.w_fast, w_avg, cfg.alpha_fast, self._n_averaged)
        self._resample_count += 1
        if self._resample_count % cfg.resample_interval != 0:
            return False, False
        self._resample(prepared)
        return True, False

    def random_probability(self) -> float:
        """``max(0, 1 - w_fast / w_slow)``: the chance that a resampled particle is random."""
        if not self.config.recovery or self.w_slow <= 0.0:
            return 0.0
        return max(0.0, 1.0 - self.w_fast / self.w_slow)

    def _resample(self, prepared: PreparedScan) -> None:
        """KLD-sampling with random injection (amcl's ``pf_update_resample``)."""
        cfg = self.config
        n_max = cfg.max_particles
        w_diff = self.random_probability()
        self._w_diff = w_diff
        weights = normalise_log_weights(self.log_weights)[1]
        # Draw n_max candidates in order; amcl draws them one by one and stops early, which
        # takes the same prefix of the same sequence of independent draws.
        is_random = self.rng.random(n_max) < w_diff
        cdf = np.cumsum(weights)
        cdf /= cdf[-1]
        idx = np.minimum(np.searchsorted(cdf, self.rng.random(n_max), side="right"), cdf.size - 1)
        n_random = int(is_random.sum())
        candidates = self.poses[idx]
        cand_fitness = self.fitness[idx]
        if n_random:
            candidates[is_random] = self.grid.sample_free_poses(n_random, self.rng)
        keys = histogram_bins(candidates, cfg.bin_xy_m, cfg.bin_theta_rad)
        k = occupied_bins_prefix(keys)
        limits = kld_sample_sizes(k, cfg.kld_err, cfg.kld_z, cfg.min_particles, n_max)
        counts = np.arange(1, n_max + 1)
        stop = np.flatnonzero(counts > limits)
        m = int(stop[0]) + 1 if stop.size else n_max
        self.poses = candidates[:m]
        self.fitness = cand_fitness[:m]
        self._kld_target = int(limits[m - 1])
        injected = is_random[:m]
        self._injected = int(injected.sum())
        if self._injected:
            ll = sanitise_log_likelihood(self.sensor.log_likelihood(self.poses[injected], prepared))
            self._evaluations += self._injected
            self.fitness[injected] = fitness(ll, prepared, self.sensor)
        self.log_weights = np.full(m, -math.log(m))

    def _diagnostics(
        self, start: float, *, updated: bool, resampled: bool, reinitialised: bool = False
    ) -> StepDiagnostics:
        w = self.weights
        return StepDiagnostics(
            step=self.t,
            n_particles=int(self.poses.shape[0]),
            ess=effective_sample_size(w),
            resampled=resampled,
            likelihood_evaluations=self._evaluations,
            step_ms=(time.perf_counter() - start) * 1e3,
            reinitialised=reinitialised,
            extra={
                "updated": float(updated),
                "w_slow": self.w_slow,
                "w_fast": self.w_fast,
                "random_probability": self._w_diff if resampled else 0.0,
                "injected": float(self._injected if resampled else 0),
                "kld_target": float(self._kld_target),
            },
        )

    # ------------------------------------------------------------------ queries
    @property
    def weights(self) -> NDArray[np.float64]:
        return normalise_log_weights(self.log_weights)[1]

    def _carried(self, poses: NDArray[np.float64]) -> NDArray[np.float64]:
        """Poses moved (noise-free) by the odometry since the last filter update."""
        inc = self._motion_since_update()
        if inc.is_zero:
            return poses
        return apply_increment(poses, inc.rot1, inc.trans, inc.rot2)

    def _labels(self) -> tuple[NDArray[np.int64], int]:
        return pose_cluster_labels(self.poses, self.config.bin_xy_m, self.config.bin_theta_rad)

    def hypotheses(self, limit: int | None = None) -> list[Hypothesis]:
        """Clusters of connected occupied bins, heaviest first (amcl's hypotheses), their poses
        carried by the odometry since the last update; only the ``limit`` heaviest when given."""
        hyps = cluster_hypotheses(self.poses, self.weights, self.fitness, *self._labels(), limit)
        return [replace(h, pose=self._carried(h.pose[None, :])[0]) for h in hyps]

    def estimate(self) -> PoseEstimate:
        """The heaviest cluster's weighted mean and covariance (as amcl publishes)."""
        best = self.hypotheses(limit=1)[0]
        return PoseEstimate(best.pose, best.covariance)

    def particles(self) -> ParticleSnapshot:
        """The particles, carried by the odometry since the last update; labels are clusters."""
        labels, _ = self._labels()
        return ParticleSnapshot(self._carried(self.poses.copy()), self.weights, labels)


def kld_sample_sizes(
    k: NDArray[np.int64], err: float, z: float, n_min: int, n_max: int
) -> NDArray[np.int64]:
    """:func:`kld_sample_size` for an array of bin counts (the same arithmetic, vectorised)."""
    kf = k.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = 2.0 / (9.0 * (kf - 1.0))
        x = 1.0 - b + np.sqrt(b) * z
        n = np.ceil((kf - 1.0) / (2.0 * err) * x**3)
    n = np.where(k <= 1, n_max, np.clip(n, n_min, n_max))
    return n.astype(np.int64)


def _with_particles(cfg: KLDAMCLConfig, n: int) -> KLDAMCLConfig:
    """A budget of ``n`` particles is KLD-sampling's upper bound ``max_particles``."""
    return replace(cfg, max_particles=n, min_particles=min(cfg.min_particles, n))


ALGORITHM = Algorithm(
    "kld-amcl",
    KLDAMCLConfig,
    KLDAMCL,
    with_particles=_with_particles,
    summary="KLD-sampling adaptive MCL as in ROS/Nav2 amcl, recovery off (Nav2's default)",
)
RECOVERY_ALGORITHM = Algorithm(
    "kld-amcl-recovery",
    KLDAMCLConfig,
    KLDAMCL,
    default_config=lambda: KLDAMCLConfig(alpha_slow=0.001, alpha_fast=0.1),
    with_particles=_with_particles,
    summary="KLD-AMCL with augmented-MCL recovery (alpha_slow 0.001, alpha_fast 0.1)",
)


__all__ = [
    "ALGORITHM",
    "KLDAMCL",
    "RECOVERY_ALGORITHM",
    "Z_099",
    "KLDAMCLConfig",
    "average_weight",
    "histogram_bins",
    "kld_sample_size",
    "kld_sample_sizes",
    "occupied_bins_prefix",
    "running_average",
]
