"""Algorithm names -> filters for the experiments: a thin layer over the registry
(:mod:`ceamcl.filters.registry`), which lists the project's filters and the Nav2 peer."""

from __future__ import annotations

import numpy as np

from ceamcl.filters import registry
from ceamcl.filters.base import LocalisationFilter
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryNoise

NAV2_AMCL = "nav2-amcl"

#: Algorithms that report one pose, not several hypotheses: the experiments measure their
#: estimate instead of their hypotheses (docs/experiments.md).
SINGLE_ESTIMATE: frozenset[str] = frozenset({NAV2_AMCL})


def all_algorithms() -> tuple[str, ...]:
    """Every algorithm an experiment can run: the project's filters, then the Nav2 peer."""
    return registry.names()


def resolve_algorithms(names: list[str] | None) -> tuple[list[str], dict[str, str]]:
    """The algorithms to run (in the order given, default all) and those skipped with why."""
    return registry.resolve(names or None)


def build_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    *,
    delta_per_m2: float | None = None,
    odometry_noise: OdometryNoise | None = None,
) -> LocalisationFilter:
    """A filter by name with default settings; ``delta_per_m2`` overrides CEAMCL's delta."""
    config = None
    if delta_per_m2 is not None:
        config = registry.with_config(algorithm, delta_per_m2=delta_per_m2)
    return registry.make_filter(algorithm, grid, rng, odometry_noise=odometry_noise, config=config)
