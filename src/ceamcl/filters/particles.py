"""The particle core every filter composes: one container and the steps that act on it.

A filter step reads as a short list of these calls, as in Beluga's pipeline
``particles |= propagate(motion(u)) | reweight(sensor(z))``, then resampling::

    propagate(ps, motion, increment, rng)         # predict (Probabilistic Robotics Table 8.2, l. 4)
    if not reweight(ps, sensor, prepared):        # weight (l. 5); False: every particle impossible
        ps = uniform(grid, n, rng)                #   start again over free space
    evolve(ps, groups, config, sensor, prepared, rng)   # GMCL and CEAMCL only (section 3.4)
    if policy(Context(particles=ps)):
        resample(ps, n, rng)                      # (Table 4.4)

The container, :class:`ParticleSet`, holds the arrays of the particle set (poses ``(N, 3)``,
normalised log-weights, the last scan's log-likelihoods and fitness, an integer label per
particle such as CEAMCL's species). Steps change it in place; :func:`uniform` and
:func:`gaussian` build new ones. Every random step takes the filter's ``numpy.random.Generator``.
When to update or resample is a policy (:mod:`ceamcl.filters.policies`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl import budget
from ceamcl.angles import wrap
from ceamcl.errors import ConfigError, LogFormatError
from ceamcl.filters.evolution import EvolutionConfig, evolve_groups
from ceamcl.filters.headings import (
    HeadingPrior,
    heading_bins,
    sample_headings,
    scan_heading_density,
)
from ceamcl.filters.resampling import (
    normalise_log_weights,
    resampler,
    sanitise_log_likelihood,
    systematic_within_labels,
)
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.scan import LaserScan, PreparedScan
from ceamcl.sensors.search import judged


def uniform_log_weights(n: int) -> NDArray[np.float64]:
    """``n`` equal normalised log-weights, ``-log n`` each."""
    return np.full(n, -np.log(n)) if n > 0 else np.zeros(0)


@dataclass(eq=False)
class ParticleSet:
    """The particle set: ``N`` particles as parallel arrays.

    poses: ``(N, 3)`` poses ``(x, y, theta)``, headings within ``[-pi, pi]`` (every move
        wraps them to ``(-pi, pi]``).
    log_weights: ``(N,)`` normalised log importance weights (CEAMCL weighs inside species
        from ``loglik`` and leaves them uniform).
    loglik: ``(N,)`` log-likelihood ``log p(z | x)`` of the last scan (-inf: impossible).
    fitness: ``(N,)`` fitness in (0, 1] for the last scan (:func:`ceamcl.sensors.base.fitness`).
    labels: ``(N,)`` integer label (CEAMCL's species id; 0 for filters without groups).
    """

    poses: NDArray[np.float64]
    log_weights: NDArray[np.float64]
    loglik: NDArray[np.float64]
    fitness: NDArray[np.float64]
    labels: NDArray[np.int64]

    @classmethod
    def from_poses(
        cls, poses: NDArray[np.float64], labels: NDArray[np.int64] | None = None
    ) -> ParticleSet:
        """Particles at ``poses`` with equal weights, no evidence yet (log-likelihood 0,
        fitness 1) and ``labels`` (default 0)."""
        n = poses.shape[0]
        return cls(
            poses=poses,
            log_weights=uniform_log_weights(n),
            loglik=np.zeros(n),
            fitness=np.ones(n),
            labels=np.zeros(n, dtype=np.int64) if labels is None else labels,
        )

    @property
    def n(self) -> int:
        """The number of particles."""
        return int(self.poses.shape[0])

    @property
    def weights(self) -> NDArray[np.float64]:
        """Normalised importance weights, summing to 1 (uniform when none is finite)."""
        return normalise_log_weights(self.log_weights)[1]

    def take(self, index: NDArray[np.bool_] | NDArray[np.intp]) -> None:
        """Keep the particles a boolean mask or an index array (ancestors) selects."""
        self.poses = self.poses[index]
        self.log_weights = self.log_weights[index]
        self.loglik = self.loglik[index]
        self.fitness = self.fitness[index]
        self.labels = self.labels[index]

    def extend(self, other: ParticleSet) -> None:
        """Append the particles of ``other`` (their log-weights as they are)."""
        self.poses = np.vstack([self.poses, other.poses])
        self.log_weights = np.concatenate([self.log_weights, other.log_weights])
        self.loglik = np.concatenate([self.loglik, other.loglik])
        self.fitness = np.concatenate([self.fitness, other.fitness])
        self.labels = np.concatenate([self.labels, other.labels])


# ---------------------------------------------------------------------- initialisation
def check_pose_and_covariance(
    pose: ArrayLike, covariance: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """An initial pose and its covariance as arrays, and a factor ``L`` with ``L L^T`` the
    covariance (Cholesky; for a positive semi-definite one, e.g. all zeros, from its
    eigen-decomposition).

    Raises:
        ConfigError: ``pose`` is not three finite numbers, or ``covariance`` not a finite,
            symmetric, positive semi-definite ``3 x 3`` matrix.
    """
    mean = np.asarray(pose, dtype=np.float64).reshape(-1)
    if mean.shape != (3,) or not np.all(np.isfinite(mean)):
        shown = " ".join(repr(pose).split())  # one line, even for an array's repr
        raise ConfigError(f"pose: expected three finite numbers (x, y, theta), got {shown}")
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
    return mean, cov, np.asarray(factor, dtype=np.float64)


def gaussian_poses(
    pose: ArrayLike, covariance: ArrayLike, n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``n`` poses from ``N(pose, covariance)``, headings wrapped.

    Draws exactly what ``rng.multivariate_normal(..., method="cholesky")`` draws for a positive
    definite covariance; a positive semi-definite one (e.g. all zeros: every particle on the
    pose) is factored by its eigen-decomposition instead of failing.

    Raises:
        ConfigError: as :func:`check_pose_and_covariance`.
    """
    mean, _, factor = check_pose_and_covariance(pose, covariance)
    out = mean + np.dot(rng.standard_normal((n, 3)), factor.T)
    out[:, 2] = wrap(out[:, 2])
    return np.asarray(out, dtype=np.float64)


def uniform(grid: OccupancyGrid, n: int, rng: np.random.Generator) -> ParticleSet:
    """``n`` particles uniform over the free space of ``grid`` (global localisation, and the
    fresh start when every particle is impossible), equal weights."""
    return ParticleSet.from_poses(grid.sample_free_poses(n, rng))


def gaussian(
    pose: ArrayLike, covariance: ArrayLike, n: int, rng: np.random.Generator
) -> ParticleSet:
    """``n`` particles from ``N(pose, covariance)`` (pose tracking), equal weights."""
    return ParticleSet.from_poses(gaussian_poses(pose, covariance, n, rng))


#: Test poses weighed per likelihood call by :func:`importance_start` (bounds the sensor's work).
INIT_BATCH = 250_000
#: Memory per test pose of :func:`importance_start`: the pose, its log-likelihood and weights.
TEST_POSE_BYTES = 64


def importance_start(
    grid: OccupancyGrid,
    sensor: SensorModel,
    prepared: PreparedScan | None,
    n_test: int,
    n: int,
    rng: np.random.Generator,
    *,
    batch: int = INIT_BATCH,
    headings: HeadingPrior | None = None,
    scan: LaserScan | None = None,
    search: SensorModel | None = None,
) -> tuple[ParticleSet, int]:
    """Global initialisation with a budget of ``n_test`` likelihood evaluations, the start
    CEAMCL's section 3.1 makes for every baseline (``init_test_poses``): ``n_test`` poses
    uniform over free space, weighed by the first scan ``batch`` poses per call, and ``n``
    particles drawn from them by systematic resampling (equal weights; their log-likelihood
    and fitness kept). Returns the particles and the evaluations spent.

    Without a usable scan (``prepared`` None), or when every test pose is impossible, the
    particles are ``n`` poses uniform over free space (the scan said nothing to resample by).
    The test poses are checked against the memory budget before they are drawn.

    ``headings`` (with the step's ``scan``): the test poses' headings drawn from the scan's
    geometry as CEAMCL's may be (:mod:`ceamcl.filters.headings`), each weight divided
    by the density its heading was drawn with, so that the particles still sample the
    posterior of a uniform start.

    ``search`` (with the step's ``scan``): a cheaper model than ``sensor`` that scores the test
    poses (:func:`~ceamcl.sensors.search.search_model`: the likelihood field for the beam
    model); ``sensor`` then scores again the best of them under it
    (:func:`~ceamcl.sensors.search.judged`), and the particles are resampled from those alone,
    by ``sensor``'s weights (docs/baselines.md). Both models' evaluations are counted.
    """
    if n_test < 1 or n < 1 or batch < 1:
        raise ConfigError(f"init_test_poses: expected positive counts, got {n_test}, {n}, {batch}")
    if prepared is None or prepared.n_beams == 0:
        return uniform(grid, n, rng), 0
    budget.require("init_test_poses", n_test, TEST_POSE_BYTES, "test poses")
    poses = grid.sample_free_poses(n_test, rng)
    density = None
    if headings is not None and scan is not None:
        density = scan_heading_density(grid, scan, headings)
        poses[:, 2] = sample_headings(density, n_test, rng)
    searched = usable(search, scan) if search is not None and search is not sensor else None
    if search is not None and searched is not None:
        ll = _scored(search, searched, poses, batch)
    else:
        ll = _scored(sensor, prepared, poses, batch)
    # the proposal's density at each heading, relative to uniform's (1: uniform headings)
    rel = (
        np.ones(n_test)
        if density is None
        else density[heading_bins(poses[:, 2], density.size)] * density.size
    )
    evaluations = n_test
    if searched is not None:  # the best under the search model, judged by the filter's own
        best = judged(ll - np.log(rel))
        poses, rel = poses[best], rel[best]
        ll = _scored(sensor, prepared, poses, batch)
        evaluations += best.size
    # importance weights: likelihood over the proposal's density
    _, w, ok = normalise_log_weights(ll - np.log(rel))
    if not ok:
        return uniform(grid, n, rng), evaluations
    ancestors = resampler("systematic")(w, n, rng)
    chosen = ll[ancestors]
    ps = ParticleSet(
        poses=poses[ancestors],
        log_weights=uniform_log_weights(n),
        loglik=chosen,
        fitness=fitness(chosen, prepared, sensor),
        labels=np.zeros(n, dtype=np.int64),
    )
    return ps, evaluations


def _scored(
    sensor: SensorModel, prepared: PreparedScan, poses: NDArray[np.float64], batch: int
) -> NDArray[np.float64]:
    """``sensor``'s log-likelihood of ``poses``, ``batch`` poses per call (NaN and +inf as
    impossible)."""
    return np.concatenate(
        [
            sanitise_log_likelihood(sensor.log_likelihood(poses[i : i + batch], prepared))
            for i in range(0, poses.shape[0], batch)
        ]
    )


# ---------------------------------------------------------------------- prediction
#: The largest odometry increment a filter takes, in metres and radians: between two poses of
#: a log (at most 10^7 m from the origin, ceamcl.io.recorded.POSE_LIMIT_M) no step is longer;
#: a larger one (1e160) overflowed the motion model's squares after a filter had taken it.
INCREMENT_LIMIT = 1e8


def check_increment(increment: OdometryIncrement) -> None:
    """Refuse, before any state changes, an odometry increment with a NaN or infinite
    component (it would turn every particle into NaN) or one beyond :data:`INCREMENT_LIMIT`."""
    values = (increment.rot1, increment.trans, increment.rot2)
    if not all(math.isfinite(v) for v in values):
        raise LogFormatError(
            f"odometry increment: expected finite rot1, trans, rot2, got {values} "
            f"(is an odometry pose NaN or infinite?)"
        )
    if max(abs(v) for v in values) > INCREMENT_LIMIT:
        raise LogFormatError(
            f"odometry increment: expected |rot1|, |trans|, |rot2| <= {INCREMENT_LIMIT:g}, got "
            f"{values} (an odometry pose far outside any building?)"
        )


def propagate(
    ps: ParticleSet,
    motion: OdometryMotionModel,
    increment: OdometryIncrement,
    rng: np.random.Generator,
) -> None:
    """Prediction: move every particle by a sample of the motion model for ``increment``
    (Probabilistic Robotics Table 8.2, line 4; ``sample_motion_model_odometry``, Table 5.6)."""
    check_increment(increment)
    ps.poses = motion.sample(ps.poses, increment, rng)


# ---------------------------------------------------------------------- weighting
def usable(sensor: SensorModel, scan: LaserScan | None) -> PreparedScan | None:
    """The scan prepared for ``sensor``, or None when there is none or it has no usable beam
    (it then says nothing, and a filter leaves its weights as they are)."""
    if scan is None:
        return None
    prepared = sensor.prepare(scan)
    return prepared if prepared.n_beams > 0 else None


def weigh(ps: ParticleSet, sensor: SensorModel, prepared: PreparedScan) -> bool:
    """Store every particle's log-likelihood ``log p(z | x)`` of the scan (NaN and +inf count
    as impossible, -inf). Returns False when every particle is impossible. Costs ``ps.n``
    likelihood evaluations."""
    ps.loglik = sanitise_log_likelihood(sensor.log_likelihood(ps.poses, prepared))
    return bool(np.any(np.isfinite(ps.loglik)))


def importance_weights(ps: ParticleSet, prior_log_weights: NDArray[np.float64]) -> bool:
    """``log w_i = log w_i^prior + log p(z | x_i)``, normalised (Probabilistic Robotics Table
    4.3, line 4). Returns False, leaving the weights as they were, when every particle is
    impossible."""
    log_w, _, ok = normalise_log_weights(prior_log_weights + ps.loglik)
    if ok:
        ps.log_weights = log_w
    return ok


def reweight(ps: ParticleSet, sensor: SensorModel, prepared: PreparedScan) -> bool:
    """Importance weighting with a scan (Probabilistic Robotics Table 8.2, line 5): store the
    log-likelihoods and fitness, multiply the weights by the likelihoods. Returns False
    ("impossible") when every particle is impossible; the caller then starts again (e.g. with
    :func:`uniform`). Costs ``ps.n`` likelihood evaluations."""
    weigh(ps, sensor, prepared)
    ps.fitness = fitness(ps.loglik, prepared, sensor)
    return importance_weights(ps, ps.log_weights)


# ---------------------------------------------------------------------- evolution
def evolve(
    ps: ParticleSet,
    groups: list[NDArray[np.intp]],
    config: EvolutionConfig,
    sensor: SensorModel,
    prepared: PreparedScan,
    rng: np.random.Generator,
    best_seen: NDArray[np.float64] | None = None,
) -> int:
    """The genetic operators (paper section 3.4: crossover, eq. 17, then mutation, eq. 18)
    inside each group of particle indices (a species, or everyone for GMCL), in place; the
    log-likelihoods and fitness are those of the evolved poses afterwards. Weights are left
    to the caller. ``best_seen`` (per particle, in place): raised to the best log-likelihood
    of any child evaluated from that particle, kept or not. Returns the evaluations spent."""

    def evaluate(poses: NDArray[np.float64]) -> NDArray[np.float64]:
        return sensor.log_likelihood(poses, prepared)

    evaluations = evolve_groups(ps.poses, ps.loglik, groups, config, evaluate, rng, best_seen)
    ps.loglik = sanitise_log_likelihood(ps.loglik)
    ps.fitness = fitness(ps.loglik, prepared, sensor)
    return evaluations


# ---------------------------------------------------------------------- resampling
def resample(ps: ParticleSet, n: int, rng: np.random.Generator, scheme: str = "systematic") -> None:
    """Draw ``n`` particles from the weighted set with the resampling ``scheme`` (by name,
    :data:`~ceamcl.filters.resampling.RESAMPLERS`); the new set has equal weights."""
    ancestors = resampler(scheme)(ps.weights, n, rng)
    ps.take(ancestors)
    ps.log_weights = uniform_log_weights(ancestors.size)


def resample_within_labels(
    ps: ParticleSet, targets: dict[int, int], rng: np.random.Generator
) -> dict[int, NDArray[np.intp]]:
    """Systematic resampling inside each label (CEAMCL's species): ``targets.get(label,
    size)`` particles of each label, drawn with the in-label weights of the log-likelihoods
    (:func:`~ceamcl.filters.resampling.systematic_within_labels`). Returns each surviving
    label's members in the new set."""
    ancestors, members = systematic_within_labels(ps.labels, ps.loglik, targets, rng)
    ps.take(ancestors)
    return members


__all__ = [
    "ParticleSet",
    "check_increment",
    "evolve",
    "gaussian",
    "gaussian_poses",
    "importance_start",
    "importance_weights",
    "propagate",
    "resample",
    "resample_within_labels",
    "reweight",
    "uniform",
    "uniform_log_weights",
    "usable",
    "weigh",
]
