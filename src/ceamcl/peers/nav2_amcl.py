"""Nav2's AMCL as a peer, through the ``amcl`` wheel on PyPI (GPL-3.0, optional extra ``[peers]``).

The wheel (``amcl`` 0.1.2, https://github.com/damanikjosh/amcl_python) wraps Nav2's ``pf``
library, its differential odometry model and its *beam* laser model (the only laser model it
exposes). This module adapts it to :class:`~ceamcl.filters.base.LocalisationFilter` so that it
runs on the same maps, odometry and scans as our filters. It never imports the wheel at module
level: the GPL code is loaded only when a peer is built.

What we found out about the wheel (tests in ``tests/peers`` pin these down):

* **Map frame.** ``OccupancyGrid(data[row][col])`` is row-major with row 0 at the origin, as
  ``nav_msgs/OccupancyGrid``; values 0 free, 100 occupied, anything else unknown. Like ROS amcl,
  it takes the origin to be the *centre* of cell (0, 0), half a cell off the ROS convention (the
  corner). We hand it our grid frame with the origin moved by half a cell, so a pose comes back
  where it was; the wheel ignores a map yaw, so we convert poses to and from the grid frame.
* **No update thresholds.** Every ``update(scan, odom_pose)`` moves the particles by the
  odometry since the last call, weights them and resamples (Nav2's ``update_min_d``/``update_min_a``
  and ``resample_interval`` live in Nav2's node, not in the wheel). The first ``update`` after
  ``set_initial_pose`` only records the odometry pose.
* **Estimate.** ``get_pose_mean`` is the mean of *all* particles (after resampling), not the
  heaviest cluster as Nav2's node publishes; in a symmetric world it can fall between modes.
* **No global localisation** in the Python API, no access to the particles, their number or
  the weights. See :meth:`Nav2AMCL.initialise_global` and :meth:`Nav2AMCL.particles`.
* **Seeding.** There is no seed argument. The filter draws from glibc's process-wide
  ``drand48``: ``pf_alloc`` seeds it with the wall clock, and every ``set_initial_pose``
  reseeds it with ``srand48(++k)``, ``k`` a counter private to the library that counts the
  Gaussians allocated so far in the process; random recovery poses come from
  ``std::random_device``. Where glibc is available we give every :class:`Nav2AMCL` its own
  ``drand48`` state, drawn from our generator and swapped in around each call into the wheel
  (``seed48``). So with recovery off everything after the initial particle cloud is ours, and
  the cloud depends on ``k``: a process making the same calls in the same order (one CLI run
  with a fixed seed) reproduces a run bit for bit, two peers in one process do not.
* **Hang.** The wheel's beam model steps through the beams with ``(count - 1) // (max_beams -
  1)``, which is 0 when a scan has fewer beams than ``max_beams``, and then loops forever. We
  never hand it such a scan (see :meth:`Nav2AMCL._update`).
* **Sensor model.** Nav2's beam model combines beams as ``1 + sum p^3`` (an ad-hoc heuristic,
  not the product of likelihoods) and drops the Gaussian's normaliser; with the same
  parameters it therefore weights particles differently from our :class:`BeamModel`.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from types import ModuleType, TracebackType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl import peers
from ceamcl.angles import wrap
from ceamcl.errors import ConfigError, check_rng
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
from ceamcl.filters.particles import check_increment, check_pose_and_covariance
from ceamcl.filters.state import LocalisationState, initialising, read_covariance
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryNoise, apply_increment
from ceamcl.sensors.base import fitness
from ceamcl.sensors.beam_model import BeamModel, BeamModelConfig
from ceamcl.sensors.scan import LaserScan, select_beam_indices

INSTALL_HINT = "pip install 'ceamcl[peers]'"

#: Nav2's defaults (nav2_amcl parameters ``min_particles``/``max_particles``).
NAV2_MIN_PARTICLES = 500
NAV2_MAX_PARTICLES = 2000
#: Augmented-MCL rates when recovery is on (ROS amcl's recommended values; Nav2 default is 0/0).
RECOVERY_ALPHA_SLOW = 0.001
RECOVERY_ALPHA_FAST = 0.1

_THETA_VAR_UNIFORM = math.pi**2 / 3.0  # variance of a heading uniform on [-pi, pi)


def _amcl() -> ModuleType:
    """The wheel's module, or a :class:`ConfigError` saying how to install it."""
    try:
        return importlib.import_module("amcl")
    except ImportError as exc:
        raise ConfigError(
            f"peer nav2-amcl: the Nav2 AMCL wheel (module 'amcl') is not installed; {INSTALL_HINT}"
        ) from exc


# ---------------------------------------------------------------------------------- conversions
def amcl_cell_values(grid: OccupancyGrid) -> NDArray[np.int64]:
    """Our cells as the wheel's values: 0 free, 100 occupied, -1 unknown (same thresholds)."""
    return np.where(grid.free_mask, 0, np.where(grid.occupied_mask, 100, -1)).astype(np.int64)


def to_amcl_grid(grid: OccupancyGrid) -> Any:
    """The map as an ``amcl.OccupancyGrid`` in our *grid frame*.

    The wheel's frame is the grid frame of :meth:`OccupancyGrid.world_to_map` (corner of cell
    (0, 0) at the origin, x along the rows); convert poses with :func:`to_amcl_pose` and
    :func:`from_amcl_pose`. The wheel's origin is given half a cell in, because it takes the
    origin to be the centre of cell (0, 0).
    """
    amcl = _amcl()
    half = 0.5 * grid.resolution
    return amcl.create_occupancy_grid_from_list(
        amcl_cell_values(grid).tolist(), grid.resolution, half, half
    )


def to_amcl_pose(grid: OccupancyGrid, pose: ArrayLike) -> NDArray[np.float64]:
    """A world pose ``(x, y, theta)`` in the wheel's frame (the grid frame)."""
    return grid.poses_to_map(pose)[0]


def from_amcl_pose(grid: OccupancyGrid, pose: ArrayLike) -> NDArray[np.float64]:
    """A pose in the wheel's frame back in the world frame."""
    p = np.asarray(pose, dtype=np.float64).reshape(3)
    x, y = grid.map_to_world(p[0], p[1])
    return np.array([float(x), float(y), math.remainder(p[2] + grid.origin[2], 2.0 * math.pi)])


def _rotate_covariance(cov: NDArray[np.float64], yaw: float) -> NDArray[np.float64]:
    if yaw == 0.0:
        return cov
    c, s = math.cos(yaw), math.sin(yaw)
    r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out: NDArray[np.float64] = r @ cov @ r.T
    return out


def amcl_ranges(scan: LaserScan, max_beams: int | None = None) -> NDArray[np.float64]:
    """The ``(M, 2)`` array of ``[range, bearing]`` rows the wheel is fed.

    Beams are selected as our sensor models select them (``max_beams`` evenly spread, first and
    last kept; all when None); NaN readings are dropped; readings at or below ``range_min``,
    at or above ``range_max`` and infinities become exactly ``range_max`` (Nav2's node maps
    short readings to max range, and its beam model recognises a max reading by equality).
    """
    idx = (
        np.arange(scan.n_beams, dtype=np.intp)
        if max_beams is None
        else select_beam_indices(scan.n_beams, max_beams)
    )
    r = scan.ranges[idx]
    bearings = scan.angles[idx]
    keep = ~np.isnan(r)
    r = np.where((r <= scan.range_min) | (r >= scan.range_max), scan.range_max, r)
    return np.column_stack([r[keep], bearings[keep]])


def to_amcl_scan(scan: LaserScan, max_beams: int | None = None) -> Any:
    """The scan as an ``amcl.LaserScan`` (see :func:`amcl_ranges`; the laser's mounting pose
    is not part of it: the filter is told with ``set_laser_pose``)."""
    amcl = _amcl()
    return amcl.create_laser_scan_from_list(
        amcl_ranges(scan, max_beams).tolist(), float(scan.range_max)
    )


# ---------------------------------------------------------------------------------- seeding
class _Drand48:
    """A private glibc ``drand48`` state, swapped in around calls into the wheel.

    ``seed48(s)`` installs ``s`` and returns the state it replaced, which lets us save the
    caller's state on entry and take ours back on exit. Unavailable (``ok`` False) without glibc.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self.state = (ctypes.c_ushort * 3)()
        self.reseed(rng)
        self._outer = (ctypes.c_ushort * 3)()
        self._seed48: Any = None
        name = ctypes.util.find_library("c")
        if name is None:
            return
        try:
            fn = ctypes.CDLL(name).seed48
        except (OSError, AttributeError):
            return
        fn.argtypes = [ctypes.POINTER(ctypes.c_ushort)]
        fn.restype = ctypes.POINTER(ctypes.c_ushort)
        self._seed48 = fn

    @property
    def ok(self) -> bool:
        return self._seed48 is not None

    def reseed(self, rng: np.random.Generator) -> None:
        """Our state from three 16-bit words of ``rng``."""
        for i, v in enumerate(rng.integers(0, 1 << 16, size=3)):
            self.state[i] = int(v)

    def __enter__(self) -> _Drand48:
        if self._seed48 is not None:
            prev = self._seed48(self.state)
            ctypes.memmove(self._outer, prev, ctypes.sizeof(self._outer))
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._seed48 is not None:
            prev = self._seed48(self._outer)
            ctypes.memmove(self.state, prev, ctypes.sizeof(self.state))


# ---------------------------------------------------------------------------------- the filter
@dataclass(frozen=True)
class Nav2AMCLRecord(StepRecord):
    """A step of the wheel: whether it updated with a scan; the particle count the runner
    records is the upper bound ``max_particles`` (the wheel hides its particles)."""

    updated: bool = False
    n_particles_is_upper_bound: bool = True
    likelihood_evaluations_counted: bool = False  # the wheel does not say how many it scores


@dataclass(frozen=True)
class Nav2AMCLConfig:
    """Settings of the peer (defaults: Nav2's, beam model parameters as our BeamModel's)."""

    min_particles: int = NAV2_MIN_PARTICLES
    max_particles: int = NAV2_MAX_PARTICLES
    alpha_slow: float = 0.0
    alpha_fast: float = 0.0
    odometry_noise: OdometryNoise = field(default_factory=OdometryNoise)
    beam: BeamModelConfig = field(default_factory=BeamModelConfig)
    snapshot_particles: int = 500

    def __post_init__(self) -> None:
        if self.min_particles < 1:
            raise ConfigError(f"min_particles: expected >= 1, got {self.min_particles}")
        if self.max_particles < self.min_particles:
            raise ConfigError(
                f"max_particles: expected >= min_particles ({self.min_particles}), "
                f"got {self.max_particles}"
            )
        for name in ("alpha_slow", "alpha_fast"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise ConfigError(f"{name}: expected a number in [0, 1], got {v}")
        if self.beam.max_beams < 2:
            # The wheel divides by max_beams - 1 when it spreads the beams.
            raise ConfigError(f"max_beams: the Nav2 peer needs >= 2, got {self.beam.max_beams}")
        if self.snapshot_particles < 1:
            raise ConfigError(f"snapshot_particles: expected >= 1, got {self.snapshot_particles}")


class Nav2AMCL:
    """Nav2's AMCL (KLD-sampling, beam model, optional augmented-MCL recovery) as a filter.

    It gets the same map, odometry and scans as our filters: our :class:`OdometryIncrement`s are
    accumulated into an odometry pose (starting at the origin) that is handed to the wheel with
    each scan. Steps without a scan only accumulate odometry, as Nav2 does between updates.

    Limits of the wheel's Python API, and what we do about them:

    * no global localisation: :meth:`initialise_global` seeds it with a Gaussian at the centroid
      of the map's free space whose covariance is that of free space (and a heading variance of
      a uniform heading), then weights it with the first scan;
    * no particles: :meth:`particles` returns *samples from the estimate's Gaussian*, drawn with
      our generator, not the wheel's particles;
    * no particle count or likelihood count: diagnostics report ``max_particles`` as
      ``n_particles`` (an upper bound, flagged in ``extra``) and 0 evaluations;
    * one estimate: :meth:`hypotheses` is that estimate, with its fitness under our beam model.
    """

    name = "nav2-amcl"

    def __init__(
        self,
        grid: OccupancyGrid,
        config: Nav2AMCLConfig | None = None,
        *,
        rng: np.random.Generator,
    ) -> None:
        check_grid(grid)
        check_rng(rng)
        amcl = _amcl()
        self._amcl = amcl
        self.grid = grid
        self.config = config or Nav2AMCLConfig()
        self.rng = rng
        cfg = self.config
        n = cfg.odometry_noise
        b = cfg.beam
        motion = amcl.MotionParameters(n.alpha1, n.alpha2, n.alpha3, n.alpha4, 0.0)
        laser = amcl.LaserParameters(
            b.z_hit, b.z_short, b.z_max, b.z_rand, b.sigma_hit_m, b.lambda_short, 0.0, b.max_beams
        )
        self._pf = amcl.AMCL(
            cfg.min_particles,
            cfg.max_particles,
            cfg.alpha_slow,
            cfg.alpha_fast,
            motion,
            laser,
            "differential",
        )
        self._pf.set_map(to_amcl_grid(grid))
        self._drand48 = _Drand48(rng)
        self._sensor = BeamModel(grid, b)
        self._laser_pose: tuple[float, float, float] | None = None
        self._odom = np.zeros(3)
        self._pending: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._fitness = 1.0
        self.t = 0
        #: set by the first initialisation; stepping or asking before it is an error
        self._initialised = False

    @property
    def seeded(self) -> bool:
        """Whether the wheel's random stream is ours (glibc found); see the module docstring."""
        return self._drand48.ok

    # ------------------------------------------------------------------ initialisation
    def _free_space_gaussian(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean and covariance (grid frame) of a pose uniform over free space."""
        g = self.grid
        iy, ix = np.divmod(g.free_cells, g.width)
        xy = (np.column_stack([ix, iy]).astype(np.float64) + 0.5) * g.resolution
        mean = xy.mean(axis=0)
        cov = np.zeros((3, 3))
        cov[:2, :2] = np.cov(xy.T, bias=True) + np.eye(2) * g.resolution**2 / 12.0
        cov[2, 2] = _THETA_VAR_UNIFORM
        return np.array([mean[0], mean[1], 0.0]), cov

    def _set_initial(self, pose_grid: NDArray[np.float64], cov_grid: NDArray[np.float64]) -> None:
        m = self._amcl.Matrix3D()
        m.from_list(np.asarray(cov_grid, dtype=np.float64).tolist())
        with self._drand48:
            self._pf.set_initial_pose(self._amcl.Vector3D(*(float(v) for v in pose_grid)), m)
        # set_initial_pose reseeded drand48 from the library's own counter: take ours back.
        self._drand48.reseed(self.rng)

    def initialise_global(self, scan: LaserScan) -> Nav2AMCLRecord:
        """Not global localisation proper (the wheel has none): a Gaussian spread over the map.

        The wheel's particles are drawn from ``N(centroid of free space, covariance of free
        space)`` with a uniform-heading variance, then weighted with ``scan`` and resampled.
        Particles can land in walls or off the map; the beam model then gives them little
        weight.
        """
        check_scan(scan)
        self.t = 0
        self._pending = None
        mean, cov = self._free_space_gaussian()
        self._set_initial(mean, cov)
        self._initialised = True
        updated = self._update(scan)
        return self._record(updated)

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """Pose tracking from ``pose`` (world frame) with ``covariance``.

        The wheel's first update after ``set_initial_pose`` ignores the odometry, so the pose is
        handed over with the first scan, moved by the odometry seen until then.
        """
        p, cov, _ = check_pose_and_covariance(pose, covariance)  # as every filter checks them
        self.t = 0
        self._pending = (p.copy(), cov.copy())
        self._initialised = True

    # ------------------------------------------------------------------ one step
    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> Nav2AMCLRecord:
        """Accumulate the odometry ``increment``; with ``scan``, one update of the wheel."""
        require_initialised(self, "step")
        check_step_arguments(increment, scan)
        check_increment(increment)  # NaN or kilometre jumps: refused as by every filter
        self.t += 1
        self._odom = apply_increment(self._odom, increment.rot1, increment.trans, increment.rot2)[0]
        if self._pending is not None:
            p, cov = self._pending
            moved = apply_increment(p, increment.rot1, increment.trans, increment.rot2)[0]
            self._pending = (moved, cov)
        updated = self._update(scan) if scan is not None else False
        return self._record(updated)

    def _update(self, scan: LaserScan) -> bool:
        """One wheel update with ``scan``; False (odometry kept for later) when no beam is usable.

        A scan with fewer usable beams than ``max_beams`` (NaN readings, a laser with fewer
        beams) would hang the wheel, so its beams are repeated, evenly, up to ``max_beams``.
        """
        max_beams = self.config.beam.max_beams
        beams = amcl_ranges(scan, max_beams)
        if beams.shape[0] == 0:
            return False
        if beams.shape[0] < max_beams:
            pick = np.floor(np.arange(max_beams) * beams.shape[0] / max_beams).astype(np.intp)
            beams = beams[pick]
        if self._pending is not None:
            p, cov = self._pending
            yaw = -self.grid.origin[2]
            self._set_initial(to_amcl_pose(self.grid, p), _rotate_covariance(cov, yaw))
            self._pending = None
        if self._laser_pose != tuple(scan.pose):
            self._laser_pose = (float(scan.pose[0]), float(scan.pose[1]), float(scan.pose[2]))
            self._pf.set_laser_pose(self._amcl.Vector3D(*self._laser_pose))
        amcl_scan = self._amcl.create_laser_scan_from_list(beams.tolist(), float(scan.range_max))
        with self._drand48:
            self._pf.update(amcl_scan, self._amcl.Vector3D(*(float(v) for v in self._odom)))
        prepared = self._sensor.prepare(scan)
        est = self.estimate().pose
        self._fitness = float(
            fitness(self._sensor.log_likelihood(est[None, :], prepared), prepared, self._sensor)[0]
        )
        return True

    def _record(self, updated: bool) -> Nav2AMCLRecord:
        # The wheel resamples on every update.
        return Nav2AMCLRecord(resampled=updated, updated=updated)

    def particle_weights(self) -> NDArray[np.float64]:
        """The wheel hides its particles: ``max_particles`` NaN weights (the runner records
        that upper bound as the particle count and ESS as unknown)."""
        require_initialised(self, "particle_weights")
        return np.full(self.config.max_particles, np.nan)

    # ------------------------------------------------------------------ queries
    def estimate(self) -> PoseEstimate:
        """The wheel's mean pose and covariance (world frame); the pending pose before the
        first scan of pose tracking."""
        require_initialised(self, "estimate")
        if self._pending is not None:
            p, cov = self._pending
            return PoseEstimate(p.copy(), cov.copy())
        v = self._pf.get_pose_mean()
        c = np.asarray(self._pf.get_pose_covariance().to_list(), dtype=np.float64)
        c = 0.5 * (c + c.T)
        pose = from_amcl_pose(self.grid, [v.x, v.y, v.theta])
        return PoseEstimate(pose, _rotate_covariance(c, self.grid.origin[2]))

    def hypotheses(self) -> list[Hypothesis]:
        """The estimate as the only hypothesis; fitness under our beam model for the last scan."""
        require_initialised(self, "hypotheses")
        est = self.estimate()
        return [
            Hypothesis(
                pose=est.pose,
                covariance=est.covariance,
                n_particles=self.config.max_particles,
                weight=1.0,
                fitness=self._fitness,
                label=0,
            )
        ]

    def state(self, hypotheses: Sequence[Hypothesis] | None = None) -> LocalisationState:
        """From the covariance, as Nav2's users read it today
        (:func:`ceamcl.filters.state.read_covariance`); INITIALISING until the first step."""
        require_initialised(self, "state")
        if self.t == 0:
            return initialising()
        if self._pending is not None:
            return initialising("the initial pose waits for its first scan")
        return read_covariance(self.estimate())

    def particles(self) -> ParticleSnapshot:
        """NOT the wheel's particles (its API hides them): ``snapshot_particles`` samples from
        the estimate's Gaussian, drawn with our generator, uniform weights, label 0."""
        require_initialised(self, "particles")
        est = self.estimate()
        n = self.config.snapshot_particles
        poses = self.rng.multivariate_normal(est.pose, est.covariance, size=n, method="eigh")
        poses[:, 2] = wrap(poses[:, 2])
        return ParticleSnapshot(poses, np.full(n, 1.0 / n), np.zeros(n, dtype=np.int64))


def make_nav2_amcl(
    grid: OccupancyGrid,
    rng: np.random.Generator,
    *,
    odometry_noise: OdometryNoise | None = None,
    n_particles: int | None = None,
    max_beams: int = 60,
    beam: BeamModelConfig | None = None,
    recovery: bool = False,
) -> Nav2AMCL:
    """The Nav2 AMCL peer with Nav2's defaults and our models' parameters.

    ``odometry_noise`` -> the wheel's differential model alphas 1-4 (alpha5 = 0);
    ``beam`` (default :class:`BeamModelConfig`) -> its beam model, ``max_beams`` overriding;
    ``n_particles`` sets ``max_particles`` (``min_particles`` = min(500, n));
    ``recovery`` turns on augmented MCL with alpha_slow 0.001, alpha_fast 0.1 (Nav2's default
    is off). Raises :class:`ConfigError` when the wheel is not installed.
    """
    _amcl()
    if n_particles is not None and n_particles < 1:
        raise ConfigError(f"particles: expected a positive count, got {n_particles}")
    max_p = NAV2_MAX_PARTICLES if n_particles is None else n_particles
    try:
        beam_cfg = replace(beam or BeamModelConfig(), max_beams=max_beams)
    except ValueError as exc:
        raise ConfigError(f"max_beams: {exc}") from exc
    cfg = Nav2AMCLConfig(
        min_particles=min(NAV2_MIN_PARTICLES, max_p),
        max_particles=max_p,
        alpha_slow=RECOVERY_ALPHA_SLOW if recovery else 0.0,
        alpha_fast=RECOVERY_ALPHA_FAST if recovery else 0.0,
        odometry_noise=odometry_noise or OdometryNoise(),
        beam=beam_cfg,
    )
    return Nav2AMCL(grid, cfg, rng=rng)


def _default_config() -> Nav2AMCLConfig:
    """Nav2's defaults, as :func:`make_nav2_amcl` builds them (beam model, 60 beams)."""
    return replace(Nav2AMCLConfig(), beam=replace(BeamModelConfig(), max_beams=60))


def _with_particles(cfg: Nav2AMCLConfig, n: int) -> Nav2AMCLConfig:
    return replace(cfg, max_particles=n, min_particles=min(NAV2_MIN_PARTICLES, n))


def _build(
    grid: OccupancyGrid,
    motion: Any,
    sensor: Any,
    config: Nav2AMCLConfig,
    *,
    rng: np.random.Generator,
) -> Nav2AMCL:
    """The registry's factory: the wheel brings its own beam model (``sensor`` is not used);
    the odometry noise is the motion model's."""
    _amcl()
    return Nav2AMCL(grid, replace(config, odometry_noise=motion.noise), rng=rng)


def _unavailable() -> str | None:
    return (
        None if peers.available() else "Nav2's AMCL is not installed (pip install 'ceamcl[peers]')"
    )


ALGORITHM = Algorithm(
    "nav2-amcl",
    Nav2AMCLConfig,
    _build,
    default_config=_default_config,
    with_particles=_with_particles,
    reports="estimate",
    unavailable=_unavailable,
    summary="Nav2's C++ AMCL through the amcl wheel (optional extra [peers]), a benchmark peer",
)


__all__ = [
    "ALGORITHM",
    "INSTALL_HINT",
    "Nav2AMCL",
    "Nav2AMCLConfig",
    "amcl_cell_values",
    "amcl_ranges",
    "from_amcl_pose",
    "make_nav2_amcl",
    "to_amcl_grid",
    "to_amcl_pose",
    "to_amcl_scan",
]
