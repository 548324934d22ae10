"""Scenarios: a world, a route and the simulator settings, reproducible from a seed.

``paper`` (section 4 of the paper): start at the centre of one room of the hall, drive through
a doorway into the neighbouring room clockwise and on to a corner of it, where it turns to face
the room, as a robot parking there would. Written for room 0 (south-west), which drives north
through the doorway into room 3 (north-west) and on to that room's north-east corner; the
routes from the other rooms are the same route rotated about the hall's centre, so every start
sees the same geometry. Only the route from room 0 ends in room 3, where marked-hall's mark is.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ceamcl.errors import ConfigError, check_rng
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.worlds import (
    HALL_SIZE_M,
    WORLD_NAMES,
    get_world,
    rotate_about_centre,
    rotate_poses_about_centre,
)
from ceamcl.simulation.simulator import SimulatedLog, SimulationConfig, Simulator, drive_waypoints

HALL_WORLDS = ("symmetric-hall", "marked-hall")

# Route from room 0: centre (3.75, 3.75) facing north, through the doorway at (3.75, 7.5),
# to the north-east corner of room 3 (0.9 m from both walls), then turn to face room 3's centre.
_GOAL_ROOM0 = (HALL_SIZE_M / 2 - 0.9, HALL_SIZE_M - 0.9)
_ROUTE_ROOM0 = [
    np.array([3.75, 6.6]),
    np.array([3.75, 8.4]),
    np.array([*_GOAL_ROOM0, np.arctan2(11.25 - _GOAL_ROOM0[1], 3.75 - _GOAL_ROOM0[0])]),
]
_START_ROOM0 = np.array([3.75, 3.75, np.pi / 2])

_OFFICE_START = np.array([1.5, 4.25, 0.0])
_OFFICE_ROUTE = [np.array(p) for p in ([3.8, 4.25], [3.8, 2.2], [7.5, 2.3], [8.5, 1.2])]


@dataclass(frozen=True)
class Kidnap:
    """At ``at_s`` seconds the robot is carried to ``pose`` (the odometry does not see it) and
    then drives ``waypoints`` from there."""

    at_s: float
    pose: NDArray[np.float64]
    waypoints: list[NDArray[np.float64]]


@dataclass(frozen=True)
class Scenario:
    """A world and a route: ``start`` pose and the waypoints driven after it, optionally
    interrupted by a kidnap."""

    name: str
    world: str
    start: NDArray[np.float64]
    waypoints: list[NDArray[np.float64]]
    start_room: int | None = None
    goal_room: int | None = None
    config: SimulationConfig = field(default_factory=SimulationConfig)
    kidnap: Kidnap | None = None

    def grid(self) -> OccupancyGrid:
        return get_world(self.world)

    def _drive(self) -> tuple[NDArray[np.float64], int | None]:
        """The true path and the step at which the truth jumps (``None`` without a kidnap)."""
        path = drive_waypoints(self.start, self.waypoints, self.config)
        if self.kidnap is None:
            return path, None
        k = round(self.kidnap.at_s * self.config.rate_hz)
        if not 0 < k < path.shape[0]:
            raise ConfigError(
                f"kidnap.at_s: expected a time within the first route (0 to "
                f"{(path.shape[0] - 1) / self.config.rate_hz:.1f} s), got {self.kidnap.at_s}"
            )
        after = drive_waypoints(self.kidnap.pose, self.kidnap.waypoints, self.config)
        return np.vstack([path[:k], after]), k

    def true_path(self) -> NDArray[np.float64]:
        return self._drive()[0]

    def simulate(self, rng: np.random.Generator, grid: OccupancyGrid | None = None) -> SimulatedLog:
        """Run the simulator along the route (truth is deterministic; noise comes from ``rng``)."""
        check_rng(rng)
        g = grid if grid is not None else self.grid()
        path, k = self._drive()
        return Simulator(g, self.config).run(path, rng, kidnapped_at=() if k is None else (k,))


def paper_scenario(
    start_room: int = 0,
    world: str = "symmetric-hall",
    config: SimulationConfig | None = None,
) -> Scenario:
    """The paper's run: centre of room ``start_room`` to a corner of the next room clockwise."""
    if world not in HALL_WORLDS:
        raise ConfigError(f"world: the paper scenario needs one of {HALL_WORLDS}, got {world!r}")
    if start_room not in range(4):
        raise ConfigError(f"start_room: expected 0, 1, 2 or 3, got {start_room}")
    start = rotate_poses_about_centre(_START_ROOM0, start_room)[0]
    route = [
        rotate_poses_about_centre(w, start_room)[0]
        if w.size == 3
        else rotate_about_centre(w, start_room)[0]
        for w in _ROUTE_ROOM0
    ]
    return Scenario(
        name="paper",
        world=world,
        start=start,
        waypoints=route,
        start_room=start_room,
        goal_room=(start_room + 3) % 4,
        config=config or SimulationConfig(),
    )


def office_scenario(config: SimulationConfig | None = None) -> Scenario:
    """A tour of ``small-office`` from the corridor into the south rooms."""
    return Scenario(
        "office", "small-office", _OFFICE_START, _OFFICE_ROUTE, config=config or SimulationConfig()
    )


# Kidnapped robot on small-office (one answer, so relocalisation is well defined): the office
# tour until 25 s (by then the robot is localised, in the corridor heading south into the
# south rooms), then carried to the north-east room, from where it drives back through the
# corridor into the north-west room.
_KIDNAP_AT_S = 25.0
_KIDNAP_POSE = np.array([5.5, 6.5, 0.0])
_KIDNAP_ROUTE = [np.array(p) for p in ([7.6, 6.5], [7.6, 4.25], [1.5, 4.25], [1.5, 6.8])]


def kidnapped_scenario(
    config: SimulationConfig | None = None, at_s: float = _KIDNAP_AT_S
) -> Scenario:
    """The office tour, kidnapped at ``at_s`` into the north-east room (see above)."""
    return Scenario(
        "kidnapped",
        "small-office",
        _OFFICE_START,
        _OFFICE_ROUTE,
        config=config or SimulationConfig(),
        kidnap=Kidnap(at_s, _KIDNAP_POSE, _KIDNAP_ROUTE),
    )


SCENARIO_NAMES = ("paper", "office", "kidnapped")


def get_scenario(name: str, world: str | None = None, start_room: int = 0) -> Scenario:
    """A scenario by name; ``world`` overrides the default world where the route allows."""
    if world is not None and world not in WORLD_NAMES:
        raise ConfigError(
            f"world: unknown world {world!r}; expected one of {', '.join(WORLD_NAMES)}"
        )
    if name == "paper":
        return paper_scenario(start_room, world or "symmetric-hall")
    if name == "office":
        if world not in (None, "small-office"):
            raise ConfigError(f"world: the office scenario runs on small-office, got {world!r}")
        return office_scenario()
    if name == "kidnapped":
        if world not in (None, "small-office"):
            raise ConfigError(f"world: the kidnapped scenario runs on small-office, got {world!r}")
        return kidnapped_scenario()
    raise ConfigError(
        f"scenario: unknown scenario {name!r}; expected one of {', '.join(SCENARIO_NAMES)}"
    )
