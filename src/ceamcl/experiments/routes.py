"""What an experiment drives: a map, start poses with their routes, and the symmetric images.

A :class:`Course` is either built in (the paper's four start rooms on a hall world, or the
kidnapped office tour) or read from a small YAML *route file* next to any ROS map, so the
experiments run on a user's own building::

    # my-building-routes.yaml
    map: my-building.yaml           # ROS map_server YAML; relative to this file
    routes:
      - name: lobby                 # optional; default route0, route1, ...
        start: [1.0, 2.0, 0.0]      # x (m), y (m), heading (rad)
        waypoints:                  # [x, y] to drive to, or [x, y, heading] to turn to there
          - [4.0, 2.0]
          - [4.0, 6.0, 1.57]
        kidnap:                     # optional, for `ceamcl experiment kidnapped`
          at_s: 20.0                # the robot is carried away at this time ...
          pose: [8.0, 1.0, 3.14]    # ... to this pose ...
          waypoints: [[8.0, 4.0]]   # ... and drives on from there
    symmetry:                       # optional: the poses that look the same as the truth
      rotations: 4                  # n-fold rotation about `centre` ...
      centre: [7.5, 7.5]
      # transforms: [[tx, ty, angle]]   ... or rigid maps p -> R(angle) p + (tx, ty)
    simulation:                     # optional SimulationConfig fields
      rate_hz: 10
      speed_mps: 0.3
      turn_rate_rps: 0.6

The symmetric images are what "converged" and "expired" are measured against (docs/
experiments.md); without ``symmetry`` a pose has one image, itself.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ceamcl import budget
from ceamcl.angles import diff, wrap
from ceamcl.errors import ConfigError
from ceamcl.io.safe_yaml import load_yaml_file
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.ros_io import load_map
from ceamcl.maps.worlds import HALL_SIZE_M, WORLD_NAMES, get_world
from ceamcl.simulation.scenarios import (
    HALL_WORLDS,
    Kidnap,
    Scenario,
    kidnapped_scenario,
    paper_scenario,
)
from ceamcl.simulation.simulator import SimulationConfig


@dataclass(frozen=True, eq=False)
class Route:
    """A start pose and the waypoints driven from it, optionally interrupted by a kidnap."""

    name: str
    start: NDArray[np.float64]
    waypoints: tuple[NDArray[np.float64], ...]
    kidnap: Kidnap | None = None


def rotation_transforms(n: int, centre: tuple[float, float]) -> NDArray[np.float64]:
    """``(n, 3)`` rigid transforms ``(tx, ty, angle)``: rotations by ``2 pi k / n`` about
    ``centre`` (identity first)."""
    cx, cy = centre
    out = np.zeros((n, 3))
    for k in range(n):
        a = 2.0 * math.pi * k / n
        c, s = math.cos(a), math.sin(a)
        out[k] = (cx - (c * cx - s * cy), cy - (s * cx + c * cy), a)
    return out


def apply_transforms(
    pose: NDArray[np.float64], transforms: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The images ``(K, 3)`` of one pose under ``transforms`` ``(K, 3)``."""
    x, y, th = (float(v) for v in pose[:3])
    c, s = np.cos(transforms[:, 2]), np.sin(transforms[:, 2])
    out = np.empty((transforms.shape[0], 3))
    out[:, 0] = c * x - s * y + transforms[:, 0]
    out[:, 1] = s * x + c * y + transforms[:, 1]
    out[:, 2] = wrap(th + transforms[:, 2])
    return out


#: A route name the tables keep for their row over every route (``marked``'s "all").
RESERVED_ROUTE_NAME = "all"


@dataclass(frozen=True, eq=False)
class Course:
    """A map (built-in ``world`` or a ROS ``map_path``), routes, images and simulator settings.

    ``transforms`` ``(K, 3)``: the rigid maps whose images of the true pose look the same
    (identity first); ``K = 1`` when the map has no symmetry.
    """

    name: str
    routes: tuple[Route, ...]
    transforms: NDArray[np.float64]
    world: str | None = None
    map_path: str | None = None
    config: SimulationConfig = field(default_factory=SimulationConfig)
    #: Each route's number in the whole course (empty: 0, 1, ...): its trials' seed key, so a
    #: route chosen with ``--start-routes`` runs as it does among all of them.
    numbers: tuple[int, ...] = ()

    def grid(self) -> OccupancyGrid:
        return load_grid(self.world, self.map_path)

    @property
    def n_images(self) -> int:
        return int(self.transforms.shape[0])

    def images(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        return apply_transforms(pose, self.transforms)

    def scenario(self, index: int) -> Scenario:
        r = self.routes[index]
        return Scenario(
            name=r.name,
            world=self.world or self.name,
            start=r.start,
            waypoints=list(r.waypoints),
            config=self.config,
            kidnap=r.kidnap,
        )

    def number(self, index: int) -> int:
        """The number of route ``index`` in the whole course (the seed key of its trials)."""
        return self.numbers[index] if self.numbers else index

    def select(self, indices: list[int] | None) -> Course:
        """The same course with only the routes at ``indices`` (all when ``None``); each keeps
        its number, so its trials draw what they draw among all the routes."""
        if indices is None:
            return self
        if not indices:  # an empty selection ran nothing and wrote empty tables
            raise ConfigError(
                f"start-routes: expected one or more route numbers; this course has routes "
                f"0..{len(self.routes) - 1}"
            )
        bad = [i for i in indices if not 0 <= i < len(self.routes)]
        if bad:
            raise ConfigError(
                f"start-routes: route {bad[0]} out of range; this course has routes "
                f"0..{len(self.routes) - 1}"
            )
        twice = sorted({i for i in indices if indices.count(i) > 1})
        if twice:
            raise ConfigError(f"start-routes: route {twice[0]} given twice; expected each once")
        return Course(
            self.name,
            tuple(self.routes[i] for i in indices),
            self.transforms,
            self.world,
            self.map_path,
            self.config,
            tuple(self.number(i) for i in indices),
        )


@functools.lru_cache(maxsize=8)
def load_grid(world: str | None, map_path: str | None) -> OccupancyGrid:
    """A built-in world (drawn) or a ROS map (read and checked), once per process: a trial
    asks for it twice (simulation and filter), and the trials a worker runs on one course share
    it, distance fields included (the last eight maps are kept)."""
    if map_path is not None:
        return load_map(map_path)
    if world is None:
        raise ConfigError("course: neither a built-in world nor a map file was given")
    return get_world(world)


HALL_TRANSFORMS = rotation_transforms(4, (HALL_SIZE_M / 2.0, HALL_SIZE_M / 2.0))


def paper_course(world: str = "symmetric-hall") -> Course:
    """The paper's protocol: one route from the centre of each of the four rooms."""
    if world not in HALL_WORLDS:
        raise ConfigError(
            f"world: the paper's protocol runs on {' or '.join(HALL_WORLDS)}, got {world!r}; "
            "use --routes FILE for another map"
        )
    routes = []
    for room in range(4):
        sc = paper_scenario(room, world)
        routes.append(Route(f"room{room}", sc.start, tuple(sc.waypoints)))
    return Course(world, tuple(routes), HALL_TRANSFORMS, world=world)


def kidnapped_course() -> Course:
    """The kidnapped office tour on small-office (no symmetry: one answer)."""
    sc = kidnapped_scenario()
    route = Route("office-kidnapped", sc.start, tuple(sc.waypoints), sc.kidnap)
    return Course(sc.world, (route,), np.zeros((1, 3)), world=sc.world, config=sc.config)


# ------------------------------------------------------------------ route files
#: Memory a simulated step holds in a trial (scan, odometry, estimate, diagnostics): a bound
#: used to refuse routes whose speed, rate or turn rate ask for too many steps.
STEP_BYTES = 16 * 1024


def moves(start: NDArray[np.float64], waypoints: tuple[NDArray[np.float64], ...]) -> bool:
    """Whether driving ``waypoints`` from ``start`` moves the robot at all (a waypoint away from
    the start, or a heading to turn to), with the tolerances of
    :func:`ceamcl.simulation.simulator.drive_waypoints`: until it moves the robot stays at
    ``start``."""
    for w in waypoints:
        if float(np.hypot(*(w[:2] - start[:2]))) > 1e-9:
            return True
        if w.size == 3 and abs(float(diff(w[2], start[2]))) > 1e-9:
            return True
    return False


def simulated_steps_bound(route: Route, config: SimulationConfig) -> float:
    """An upper bound on the steps :func:`ceamcl.simulation.simulator.drive_path` records for a
    route (each leg: at most two turns of pi, then the leg's length at ``speed_mps``)."""
    dt = 1.0 / config.rate_hz
    legs = [(route.start, route.waypoints)]
    if route.kidnap is not None:
        legs.append((route.kidnap.pose, tuple(route.kidnap.waypoints)))
    steps = 1.0
    for start, wps in legs:
        here = np.asarray(start[:2], dtype=np.float64)
        for w in wps:
            steps += float(np.hypot(*(w[:2] - here))) / (config.speed_mps * dt) + 1.0
            steps += 2.0 * (math.ceil(math.pi / (config.turn_rate_rps * dt)) + 1.0)
            here = w[:2]
    return steps


class _Reader:
    """Checks a parsed route file, naming the file and the field on every error."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, where: str, what: str) -> ConfigError:
        return ConfigError(f"{self.path}: {where}: {what}")

    def numbers(self, value: Any, where: str, lengths: tuple[int, ...]) -> NDArray[np.float64]:
        want = " or ".join(str(n) for n in lengths)
        if not isinstance(value, list) or len(value) not in lengths:
            raise self.fail(where, f"expected a list of {want} numbers, got {value!r}")
        if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
            raise self.fail(where, f"expected numbers, got {value!r}")
        arr = np.array(value, dtype=np.float64)
        if not np.all(np.isfinite(arr)):
            raise self.fail(where, f"expected finite numbers, got {value!r}")
        return arr

    def waypoints(self, value: Any, where: str) -> tuple[NDArray[np.float64], ...]:
        if not isinstance(value, list) or not value:
            raise self.fail(where, "expected a non-empty list of [x, y] or [x, y, heading]")
        return tuple(self.numbers(w, f"{where}[{i}]", (2, 3)) for i, w in enumerate(value))

    def mapping(self, value: Any, where: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, f"expected a mapping, got {type(value).__name__}")
        return value

    def check_free(self, grid: OccupancyGrid, xy: NDArray[np.float64], where: str) -> None:
        if not bool(np.asarray(grid.is_free(xy[0], xy[1]))):
            raise self.fail(where, f"({xy[0]:g}, {xy[1]:g}) is not in free space of the map")


def load_route_file(path: str | os.PathLike[str]) -> Course:
    """Read a route file (format in the module docstring) and check it against its map."""
    p = Path(path)
    doc = load_yaml_file(p, "route file", ConfigError)
    r = _Reader(p)
    doc = r.mapping(doc, "top level")
    allowed = {"map", "routes", "symmetry", "simulation"}
    extra = sorted(set(doc) - allowed)
    if extra:
        raise r.fail(extra[0], f"unknown field; expected some of {', '.join(sorted(allowed))}")
    map_ref = doc.get("map")
    if not isinstance(map_ref, str) or not map_ref:
        raise r.fail("map", "expected the path of a ROS map YAML file (or a built-in world)")
    world: str | None = None
    map_path: str | None = None
    if map_ref in WORLD_NAMES:
        world = map_ref
    else:
        mp = Path(map_ref)
        map_path = str(mp if mp.is_absolute() else (p.parent / mp).resolve())
    grid = load_grid(world, map_path)

    raw_routes = doc.get("routes")
    if not isinstance(raw_routes, list) or not raw_routes:
        raise r.fail("routes", "expected a non-empty list of routes")
    routes = []
    named: dict[str, int] = {}
    for i, raw in enumerate(raw_routes):
        where = f"routes[{i}]"
        item = r.mapping(raw, where)
        unknown = sorted(set(item) - {"name", "start", "waypoints", "kidnap"})
        if unknown:
            raise r.fail(f"{where}.{unknown[0]}", "unknown field")
        name = item.get("name", f"route{i}")
        if not isinstance(name, str):
            raise r.fail(f"{where}.name", f"expected a string, got {name!r}")
        # tables group runs by route name: two routes of one name would be pooled, and
        # "all" is the tables' row over every route
        if name in named:
            raise r.fail(
                f"{where}.name",
                f"{name!r} is routes[{named[name]}]'s name too; expected a name of its own",
            )
        if name == RESERVED_ROUTE_NAME:
            raise r.fail(f"{where}.name", f"{name!r} names the tables' row over every route")
        named[name] = i
        start = r.numbers(item.get("start"), f"{where}.start", (3,))
        r.check_free(grid, start, f"{where}.start")
        wps = r.waypoints(item.get("waypoints"), f"{where}.waypoints")
        for j, w in enumerate(wps):
            r.check_free(grid, w, f"{where}.waypoints[{j}]")
        if not moves(start, wps):
            # one step, the global initialisation, reported as the run's step time
            raise r.fail(
                f"{where}.waypoints",
                "the route does not move (every waypoint is its start); expected a waypoint "
                "away from the start or a heading to turn to",
            )
        kidnap = None
        if "kidnap" in item:
            kd = r.mapping(item["kidnap"], f"{where}.kidnap")
            at = kd.get("at_s")
            if not isinstance(at, int | float) or isinstance(at, bool) or not at > 0:
                raise r.fail(f"{where}.kidnap.at_s", f"expected a positive time, got {at!r}")
            pose = r.numbers(kd.get("pose"), f"{where}.kidnap.pose", (3,))
            r.check_free(grid, pose, f"{where}.kidnap.pose")
            kwps = r.waypoints(kd.get("waypoints"), f"{where}.kidnap.waypoints")
            for j, w in enumerate(kwps):
                r.check_free(grid, w, f"{where}.kidnap.waypoints[{j}]")
            kidnap = Kidnap(float(at), pose, list(kwps))
        routes.append(Route(name, start, wps, kidnap))

    transforms = np.zeros((1, 3))
    if "symmetry" in doc:
        sym = r.mapping(doc["symmetry"], "symmetry")
        if "transforms" in sym:
            raw_t = sym["transforms"]
            if not isinstance(raw_t, list) or not raw_t:
                raise r.fail("symmetry.transforms", "expected a list of [tx, ty, angle]")
            extra_t = [r.numbers(t, f"symmetry.transforms[{i}]", (3,)) for i, t in enumerate(raw_t)]
            transforms = np.vstack([np.zeros((1, 3)), *extra_t])
        elif "rotations" in sym:
            n = sym["rotations"]
            if not isinstance(n, int) or isinstance(n, bool) or n < 1:
                raise r.fail("symmetry.rotations", f"expected a whole number >= 1, got {n!r}")
            budget.require(f"{p}: symmetry.rotations", n, 1024, "symmetric images")
            centre = r.numbers(sym.get("centre"), "symmetry.centre", (2,))
            transforms = rotation_transforms(n, (float(centre[0]), float(centre[1])))
        else:
            raise r.fail("symmetry", "expected `rotations` (with `centre`) or `transforms`")

    config = SimulationConfig()
    if "simulation" in doc:
        sim = r.mapping(doc["simulation"], "simulation")
        simple = {"rate_hz", "speed_mps", "turn_rate_rps", "range_sigma_m", "random_reading_prob"}
        names = {f.name for f in fields(SimulationConfig)} & simple
        unknown = sorted(set(sim) - names)
        if unknown:
            raise r.fail(
                f"simulation.{unknown[0]}", f"unknown field; expected some of {sorted(names)}"
            )
        for k, v in sim.items():  # numbers only, as every other field (not "5" or true)
            if not isinstance(v, int | float) or isinstance(v, bool):
                raise r.fail(f"simulation.{k}", f"expected a number, got {v!r}")
        try:
            values: dict[str, Any] = {k: float(v) for k, v in sim.items()}
            config = SimulationConfig(**values)
        except (TypeError, ValueError) as exc:
            raise r.fail("simulation", str(exc)) from None
    for i, route in enumerate(routes):
        steps = simulated_steps_bound(route, config)
        budget.require(f"{p}: routes[{i}] with its simulation settings", steps, STEP_BYTES, "steps")
        if transforms.shape[0] > 1:
            budget.require(
                f"{p}: symmetry", steps * transforms.shape[0], 24, "pose images over the route"
            )
    return Course(p.stem, tuple(routes), transforms, world, map_path, config)


def resolve_course(
    experiment: str, world: str | None, routes_file: str | os.PathLike[str] | None
) -> Course:
    """The course of an experiment: a route file if given, else the built-in one."""
    if routes_file is not None:
        if world is not None:
            raise ConfigError("world: give either --world or --routes, not both")
        return load_route_file(routes_file)
    if experiment == "kidnapped":
        if world not in (None, "small-office"):
            raise ConfigError(
                f"world: the built-in kidnapped scenario runs on small-office, got {world!r}; "
                "use --routes FILE with a `kidnap` entry for another map"
            )
        return kidnapped_course()
    if experiment == "state" and world is not None:
        # its own scenarios (ceamcl.experiments.state.default_courses), one named by its world
        if world == "small-office":
            return kidnapped_course()
        if world not in HALL_WORLDS:
            raise ConfigError(
                f"world: the state experiment's scenarios run on small-office (the kidnapped "
                f"robot), {' or '.join(HALL_WORLDS)}, got {world!r}; use --routes FILE for "
                "another map"
            )
    default = "marked-hall" if experiment == "marked" else "symmetric-hall"
    return paper_course(world or default)
