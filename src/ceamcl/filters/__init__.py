"""Localisation filters behind one interface (:class:`LocalisationFilter`), built by name."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ceamcl.errors import ConfigError
from ceamcl.filters.base import (
    Hypothesis,
    LocalisationFilter,
    ParticleSnapshot,
    PoseEstimate,
    SpeciesDiagnostics,
    StepDiagnostics,
)
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.gmcl import GMCL, GMCLConfig
from ceamcl.filters.kld_amcl import KLDAMCL, KLDAMCLConfig
from ceamcl.filters.mcl import MCL, MCLConfig
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryMotionModel, OdometryNoise
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.beam_model import BeamModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel

ALGORITHMS: tuple[str, ...] = ("ceamcl", "gmcl", "mcl", "kld-amcl", "kld-amcl-recovery")
SENSOR_MODELS: tuple[str, ...] = ("likelihood-field", "beam")


def make_sensor(name: str, grid: OccupancyGrid) -> SensorModel:
    """A sensor model by name, with its default (ROS amcl) parameters."""
    if name == "likelihood-field":
        return LikelihoodFieldModel(grid)
    if name == "beam":
        return BeamModel(grid)
    raise ConfigError(
        f"sensor: unknown sensor model {name!r}; expected one of {', '.join(SENSOR_MODELS)}"
    )


def make_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    *,
    sensor: str | SensorModel = "likelihood-field",
    odometry_noise: OdometryNoise | None = None,
    n_particles: int | None = None,
    config: FilterConfig | None = None,
) -> LocalisationFilter:
    """A filter by name (see :data:`ALGORITHMS`), with its default settings or ``config``
    (the algorithm's own config class, e.g. ``CEAMCLConfig(delta_per_m2=40)``).

    ``n_particles`` sets the sample size of fixed-size filters (MCL, GMCL); CEAMCL chooses its
    own (eq. 5) and ignores it; for KLD-AMCL it is the upper bound ``max_particles``.
    """
    if algorithm not in ALGORITHMS:
        raise ConfigError(
            f"algorithm: unknown algorithm {algorithm!r}; expected one of {', '.join(ALGORITHMS)}"
        )
    if n_particles is not None and n_particles < 1:
        raise ConfigError(f"particles: expected a positive count, got {n_particles}")
    cfg = config if config is not None else _default_config(algorithm)
    if type(cfg) is not _CONFIG_TYPES[algorithm]:
        raise ConfigError(
            f"config: {algorithm} takes a {_CONFIG_TYPES[algorithm].__name__}, "
            f"got {type(cfg).__name__}"
        )
    if n_particles is not None:
        if isinstance(cfg, KLDAMCLConfig):  # KLD-sampling's upper bound (max_particles)
            cfg = replace(
                cfg, max_particles=n_particles, min_particles=min(cfg.min_particles, n_particles)
            )
        elif isinstance(cfg, MCLConfig | GMCLConfig):
            cfg = replace(cfg, n_particles=n_particles)
    sensor_model = make_sensor(sensor, grid) if isinstance(sensor, str) else sensor
    motion = OdometryMotionModel(odometry_noise or OdometryNoise())
    if isinstance(cfg, CEAMCLConfig):
        return CEAMCL(grid, motion, sensor_model, cfg, rng=rng)
    if isinstance(cfg, KLDAMCLConfig):
        return KLDAMCL(grid, motion, sensor_model, cfg, rng=rng)
    if isinstance(cfg, GMCLConfig):  # checked before MCLConfig, its base class
        return GMCL(grid, motion, sensor_model, cfg, rng=rng)
    return MCL(grid, motion, sensor_model, cfg, rng=rng)


FilterConfig = MCLConfig | GMCLConfig | KLDAMCLConfig | CEAMCLConfig

_CONFIG_TYPES: dict[str, type] = {
    "ceamcl": CEAMCLConfig,
    "gmcl": GMCLConfig,
    "mcl": MCLConfig,
    "kld-amcl": KLDAMCLConfig,
    "kld-amcl-recovery": KLDAMCLConfig,
}


def _default_config(algorithm: str) -> FilterConfig:
    if algorithm == "kld-amcl-recovery":
        return KLDAMCLConfig(alpha_slow=0.001, alpha_fast=0.1)
    default: FilterConfig = _CONFIG_TYPES[algorithm]()
    return default


__all__ = [
    "ALGORITHMS",
    "CEAMCL",
    "GMCL",
    "KLDAMCL",
    "MCL",
    "SENSOR_MODELS",
    "CEAMCLConfig",
    "GMCLConfig",
    "Hypothesis",
    "KLDAMCLConfig",
    "LocalisationFilter",
    "MCLConfig",
    "ParticleSnapshot",
    "PoseEstimate",
    "SpeciesDiagnostics",
    "StepDiagnostics",
    "make_filter",
    "make_sensor",
]
