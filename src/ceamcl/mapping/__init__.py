"""Occupancy grid mapping from a log with known poses (see :mod:`ceamcl.mapping.occupancy`)."""

from __future__ import annotations

from ceamcl.io.recorded import RecordedLog
from ceamcl.mapping.occupancy import MappingConfig, MapStats, build_map, classify, log_odds_map
from ceamcl.maps.grid import OccupancyGrid


def map_from_log(
    log: RecordedLog, config: MappingConfig | None = None
) -> tuple[OccupancyGrid, MapStats]:
    """The map of a recorded log from its poses (the true poses where known), named after it."""
    return build_map(log, log.laser_world_poses(), config, name=log.name)


__all__ = [
    "MapStats",
    "MappingConfig",
    "build_map",
    "classify",
    "log_odds_map",
    "map_from_log",
]
