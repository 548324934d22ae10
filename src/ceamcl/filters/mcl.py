"""MCL: the standard particle filter (Dellaert et al. 1999; Probabilistic Robotics Table 8.2).

One step: move every particle with the motion model (:func:`~ceamcl.filters.particles.propagate`),
multiply its weight by the scan's likelihood (:func:`~ceamcl.filters.particles.reweight`), and
resample with the low-variance sampler when the effective sample size falls below
``resample_ess_fraction * N`` (the :func:`~ceamcl.filters.policies.ess_below` policy). Global
localisation starts from particles uniform over free space, weighted by the first scan.

Safeguards (docs/robustness.md): a missing scan, or one with no usable beam, leaves the weights
unchanged (no weighting, no genetic operators); NaN or +inf likelihoods count as impossible;
when every particle is impossible the filter re-initialises uniformly over free space and the
step's :class:`StepRecord` says ``reinitialised=True``.

The estimate is the weighted mean of all particles with a circular mean heading; in a
symmetric world it can fall between modes, which is why :meth:`MCL.hypotheses` also reports
the particle clusters (as ROS amcl does), heaviest first.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.errors import check_rng
from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    ParticleSnapshot,
    PoseEstimate,
    StepRecord,
    check_grid,
    check_scan,
    check_step_arguments,
    require_initialised,
)
from ceamcl.filters.clustering import cluster_hypotheses, cluster_labels
from ceamcl.filters.headings import HeadingPrior
from ceamcl.filters.particles import (
    INIT_BATCH,
    ParticleSet,
    gaussian,
    importance_start,
    propagate,
    resample,
    reweight,
    uniform,
    usable,
)
from ceamcl.filters.policies import Context, ess_below
from ceamcl.filters.state import MapAgreement, ParticleClusterState
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel
from ceamcl.pose import pose_covariance, pose_mean
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.scan import LaserScan, PreparedScan
from ceamcl.sensors.search import search_model


@dataclass(frozen=True)
class MCLConfig:
    """MCL settings.

    n_particles: fixed sample size.
    resample_ess_fraction: resample when ESS < fraction x N (1.0 resamples every step).
    cluster_cell_m: cell size of the x-y grid whose connected regions are the hypotheses.
    init_test_poses: global initialisation's budget of likelihood evaluations: 0 starts from
        ``n_particles`` uniform poses weighted by the first scan; N > 0 weighs N uniform test
        poses with it and resamples ``n_particles`` from them, as CEAMCL starts
        (:func:`~ceamcl.filters.particles.importance_start`).
    init_batch: test poses weighed per likelihood call (bounds memory).
    init_headings: with ``init_test_poses``, the test poses' headings drawn from the scan's
        geometry and their weights divided by that density, as CEAMCL's test poses may draw
        them (:mod:`~ceamcl.filters.headings`); ``None``: uniform headings.
    init_search_with_field: with ``init_test_poses`` and the beam model, the likelihood field
        of the same parameters scores the test poses and the beam model the best of them, as
        CEAMCL's search does (:func:`~ceamcl.sensors.search.search_model`, docs/baselines.md);
        ``False``: the beam model ray-casts every test pose. No effect with the field.
    """

    n_particles: int = 5000
    resample_ess_fraction: float = 0.5
    cluster_cell_m: float = 0.5
    init_test_poses: int = 0
    init_batch: int = INIT_BATCH
    init_headings: HeadingPrior | None = None
    init_search_with_field: bool = True

    def __post_init__(self) -> None:
        if self.n_particles < 1:
            raise ValueError(f"n_particles: expected >= 1, got {self.n_particles}")
        if self.init_test_poses < 0:
            raise ValueError(f"init_test_poses: expected >= 0, got {self.init_test_poses}")
        if self.init_batch < 1:
            raise ValueError(f"init_batch: expected >= 1, got {self.init_batch}")
        if not 0.0 <= self.resample_ess_fraction <= 1.0:
            raise ValueError(
                f"resample_ess_fraction: expected in [0, 1], got {self.resample_ess_fraction}"
            )
        if not self.cluster_cell_m > 0:
            raise ValueError(f"cluster_cell_m: expected > 0, got {self.cluster_cell_m}")


class MCL(ParticleClusterState):
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
        check_grid(grid)
        check_rng(rng)
        self.grid = grid
        self.motion = motion
        self.sensor = sensor
        self.config = config or MCLConfig()
        self.rng = rng
        self.particle_set = ParticleSet.from_poses(np.zeros((0, 3)))
        #: set by the first initialisation; stepping or asking before it is an error
        self._initialised = False
        self.resample_when = ess_below(self.config.resample_ess_fraction)
        self.t = 0
        #: the last scan received, for the state's wall-crossing test (docs/state.md)
        self.last_scan: LaserScan | None = None
        #: the state's memory of how well the map explains the scans (docs/state.md)
        self.map_agreement = MapAgreement(grid)

    # ------------------------------------------------------------------ initialisation
    def initialise_global(self, scan: LaserScan) -> StepRecord:
        """Particles uniform over free space, weighted by ``scan``; with ``init_test_poses``,
        resampled from that many test poses weighted by ``scan`` instead."""
        check_scan(scan)
        self.t = 0
        self.map_agreement.reset()
        self.last_scan = scan
        cfg = self.config
        prepared = usable(self.sensor, scan)
        if cfg.init_test_poses > 0:
            self.particle_set, evaluations = importance_start(
                self.grid,
                self.sensor,
                prepared,
                cfg.init_test_poses,
                cfg.n_particles,
                self.rng,
                batch=cfg.init_batch,
                headings=cfg.init_headings,
                scan=scan,
                search=search_model(self.sensor) if cfg.init_search_with_field else None,
            )
            self._initialised = True
            return StepRecord(resampled=evaluations > 0, likelihood_evaluations=evaluations)
        self.particle_set = uniform(self.grid, cfg.n_particles, self.rng)
        self._initialised = True
        return self.correct(prepared)

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """Particles from ``N(pose, covariance)``."""
        self.t = 0
        self.map_agreement.reset()
        self.particle_set = gaussian(pose, covariance, self.config.n_particles, self.rng)
        self._initialised = True

    # ------------------------------------------------------------------ one step
    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepRecord:
        """Predict with the odometry ``increment``, then :meth:`correct` with ``scan``."""
        require_initialised(self, "step")
        check_step_arguments(increment, scan)
        propagate(self.particle_set, self.motion, increment, self.rng)
        self.t += 1
        if scan is not None:
            self.last_scan = scan
        return self.correct(usable(self.sensor, scan))

    def correct(self, prepared: PreparedScan | None) -> StepRecord:
        """Weight with the scan (none: weights unchanged), then resample when due."""
        evaluations, reinitialised = self.reweight(prepared)
        return StepRecord(self.resample_if_due(), evaluations, reinitialised)

    def reweight(self, prepared: PreparedScan | None) -> tuple[int, bool]:
        """Importance weighting; when every particle is impossible, start again uniformly over
        free space. Returns the evaluations and whether it started again."""
        if prepared is None:
            return 0, False
        evaluations = self.particle_set.n
        if reweight(self.particle_set, self.sensor, prepared):
            return evaluations, False
        self.particle_set = uniform(self.grid, self.config.n_particles, self.rng)
        return evaluations, True

    def resample_if_due(self) -> bool:
        """Low-variance resampling of ``n_particles`` when the resampling policy says so."""
        if not self.resample_when(Context(particles=self.particle_set)):
            return False
        resample(self.particle_set, self.config.n_particles, self.rng, "systematic")
        return True

    # ------------------------------------------------------------------ queries
    @property
    def weights(self) -> NDArray[np.float64]:
        return self.particle_set.weights

    def particle_weights(self) -> NDArray[np.float64]:
        """The particles' normalised weights (:meth:`LocalisationFilter.particle_weights`)."""
        require_initialised(self, "particle_weights")
        return self.particle_set.weights

    def estimate(self) -> PoseEstimate:
        """The weighted mean of all particles (circular mean heading) and their weighted
        covariance; in a symmetric world it can fall between modes (:meth:`hypotheses`)."""
        require_initialised(self, "estimate")
        poses, w = self.particle_set.poses, self.weights
        mean = pose_mean(poses, w)
        return PoseEstimate(mean, pose_covariance(poses, w, mean))

    def _labels(self) -> tuple[NDArray[np.int64], int]:
        return cluster_labels(self.particle_set.poses[:, :2], self.config.cluster_cell_m)

    def hypotheses(self) -> list[Hypothesis]:
        """The particle clusters (connected cells of ``cluster_cell_m`` in x-y), heaviest
        first, each with its weighted mean, covariance, mass and mean fitness."""
        require_initialised(self, "hypotheses")
        ps = self.particle_set
        return cluster_hypotheses(ps.poses, ps.weights, ps.fitness, *self._labels())

    def particles(self) -> ParticleSnapshot:
        """A copy of the particles, their normalised weights and cluster labels."""
        require_initialised(self, "particles")
        labels, _ = self._labels()
        return ParticleSnapshot(self.particle_set.poses.copy(), self.weights, labels)


ALGORITHM = Algorithm(
    "mcl",
    MCLConfig,
    MCL,
    with_particles=lambda cfg, n: replace(cfg, n_particles=n),
    summary="Monte Carlo localisation with a fixed sample size (the paper's first baseline)",
)
#: MCL as the tuning sweep found it best on the symmetric hall (docs/tuning.md; a test holds
#: it to the best row of docs/tuning.csv).
TUNED_ALGORITHM = Algorithm(
    "mcl-tuned",
    MCLConfig,
    MCL,
    default_config=lambda: MCLConfig(
        n_particles=5000, init_test_poses=1_000_000, init_headings=HeadingPrior()
    ),
    with_particles=lambda cfg, n: replace(cfg, n_particles=n),
    sensor_settings={"max_beams": 60, "temper": 0.1},
    summary="MCL with the tuning sweep's best particles, start and sensor settings "
    "(docs/tuning.md)",
)
