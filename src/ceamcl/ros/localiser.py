"""What the node does with its inputs, without ROS: Nav2 AMCL's behaviour around any filter.

The node (:mod:`ceamcl.ros.node`) converts messages and hands them here; tests drive this class
directly with the same converted inputs to check that the node adds nothing but transport.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np

from ceamcl.demo import seeded_generators
from ceamcl.errors import CeamclError
from ceamcl.filters import registry
from ceamcl.filters.base import LocalisationFilter, PoseEstimate
from ceamcl.filters.ceamcl import CEAMCL
from ceamcl.filters.policies import Context, on_motion
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryNoise, increment_between
from ceamcl.ros.params import NodeParams, laser_config
from ceamcl.ros.transforms import Pose2
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.beam_model import BeamModel, BeamModelConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.sensors.scan import LaserScan

#: Nav2's covariance for an initial pose set without one (its init_cov defaults).
DEFAULT_INIT_COV = np.diag([0.5**2, 0.5**2, (math.pi / 12.0) ** 2])


class MotionGate:
    """Nav2's update trigger: update when the odometry moved more than ``update_min_d``
    along x or y, or turned more than ``update_min_a``, since the last update (the core's
    :func:`~ceamcl.filters.policies.on_motion`, as ``ceamcl run`` paces real logs), or when
    forced (a new map, an initial pose, ``request_nomotion_update``)."""

    def __init__(self, min_d: float, min_a: float) -> None:
        self.policy = on_motion(min_d, min_a)
        self.reference: Pose2 | None = None
        self.force = False

    def due(self, odom: Pose2) -> bool:
        if self.reference is None or self.force:
            return True
        motion = np.subtract(odom, self.reference)
        return self.policy(Context(motion=motion))

    def updated(self, odom: Pose2) -> None:
        self.reference = odom
        self.force = False


def sensor_model(params: NodeParams, grid: OccupancyGrid) -> SensorModel:
    """The laser model Nav2's parameters ask for, built on ``grid``."""
    config = laser_config(params.nav2, params.sensor, params.laser_temper)
    if isinstance(config, BeamModelConfig):
        return BeamModel(grid, config)
    return LikelihoodFieldModel(grid, config)


def particle_budget(params: NodeParams) -> int | None:
    """The particle budget Nav2's ``max_particles`` gives the filter, or ``None`` where the
    algorithm's own count stands: the one its ``<algorithm>.n_particles`` or
    ``.max_particles`` sets, or a tuned preset's when the parameters do not set
    ``max_particles`` (Nav2's default 2,000 would replace the count the sweep chose)."""
    if any(k in params.algorithm_overrides for k in ("n_particles", "max_particles")):
        return None
    if params.algorithm in registry.PRESETS and "max_particles" not in params.given:
        return None
    return int(params["max_particles"])


def cap_notice(f: LocalisationFilter | None) -> str | None:
    """A line for the log after an update of ``f`` at which CEAMCL's search (the first global
    localisation, or a recovery's) asked for as many samples as its cap allows: eq. 5 sized
    the initial species beyond ``max_samples``, so only the likeliest were kept (docs/ros.md:
    on a large map, a global search needs more than Nav2's 2,000). ``None`` otherwise, and
    for the other filters."""
    if not isinstance(f, CEAMCL) or f.events.n0 < f.config.max_samples:
        return None
    return (
        f"CEAMCL's search wanted more samples than its cap of {f.config.max_samples:,} "
        "(max_particles, or ceamcl.max_samples) and kept the likeliest; on a large map a "
        "higher cap localises more reliably (docs/ros.md)"
    )


def chosen_sensor_settings(params: NodeParams) -> dict[str, Any]:
    """The laser settings the parameters set, which win over a preset's tuned ones
    (``max_beams``, ``laser_temper``); the rest are the preset's or the model's defaults."""
    chosen: dict[str, Any] = {}
    if "max_beams" in params.given:
        chosen["max_beams"] = params["max_beams"]
    if params.laser_temper is not None:
        chosen["temper"] = params.laser_temper
    return chosen


class Localiser:
    """A filter driven as Nav2 drives its particle filter: built on each new map, initialised
    globally or at a pose when asked, stepped on scans when the odometry has moved enough."""

    def __init__(self, params: NodeParams) -> None:
        self.params = params
        # the filter's stream of `ceamcl demo --seed S` (child 1 of SeedSequence(S)), so a
        # demo can be reproduced through the node (docs/ros.md)
        self.rng = seeded_generators(params.seed, 2)[1]
        self.gate = MotionGate(params["update_min_d"], params["update_min_a"])
        self.grid: OccupancyGrid | None = None
        self.filter: LocalisationFilter | None = None
        self.pending: Literal["global"] | tuple[Pose2, Any] | None = None
        self.last_estimate: Pose2 | None = None

    def set_map(self, grid: OccupancyGrid) -> str | None:
        """Use ``grid`` from now on; what happens next, in words (``None``: nothing changed)."""
        if self.grid is not None and self.params["first_map_only"]:
            return "a new map ignored (first_map_only)"
        if self.grid is not None and grid == self.grid:
            return None
        if grid.free_cells.size == 0:
            raise CeamclError("map: no free cell to localise in")
        p = self.params
        new_filter = registry.make_filter(
            p.algorithm,
            grid,
            self.rng,
            sensor=sensor_model(p, grid),
            odometry_noise=OdometryNoise(*(p[f"alpha{i}"] for i in range(1, 5))),
            n_particles=particle_budget(p),
            config=p.config,
            sensor_settings=chosen_sensor_settings(p),
        )
        changed = self.grid is not None
        self.grid, self.filter = grid, new_filter
        if self.pending is None:
            if changed and self.last_estimate is not None:
                self.pending = (self.last_estimate, DEFAULT_INIT_COV)
            else:
                self.pending = "global"
        start = (
            "localising globally"
            if self.pending == "global"
            else "starting at {:.3f} {:.3f} {:.3f}".format(*self.pending[0])
        )
        return (
            f"map {'changed' if changed else 'received'}: {grid.width} x {grid.height} cells "
            f"at {grid.resolution:g} m; {start}"
        )

    def set_pose(self, pose: Pose2, covariance: Any = DEFAULT_INIT_COV) -> None:
        """Track from ``pose`` at the next scan."""
        self.pending = (pose, covariance)

    def request_global(self) -> None:
        """Localise globally at the next scan."""
        self.pending = "global"

    def request_update(self) -> None:
        """Update at the next scan even without motion."""
        self.gate.force = True

    def scan(self, odom: Pose2, scan: LaserScan) -> PoseEstimate | None:
        """Initialise or step the filter with this scan (``odom``: odometry at its time); the
        new estimate, or ``None`` when the filter did not update. A non-finite estimate is an
        error and leaves the last one in place."""
        f = self.filter
        if f is None:
            return None
        if self.pending == "global":
            f.initialise_global(scan)
            self.pending = None
            self.gate.updated(odom)
        else:
            if self.pending is not None:
                pose, cov = self.pending
                f.initialise_pose(np.asarray(pose), cov)
                self.pending = None
                self.gate.reference = odom
                self.gate.force = True
            if not self.gate.due(odom):
                return None
            assert self.gate.reference is not None
            f.step(increment_between(self.gate.reference, odom), scan)
            self.gate.updated(odom)
        estimate = f.estimate()
        if not (np.all(np.isfinite(estimate.pose)) and np.all(np.isfinite(estimate.covariance))):
            raise CeamclError("the filter gave a non-finite pose; nothing published")
        self.last_estimate = (
            float(estimate.pose[0]),
            float(estimate.pose[1]),
            float(estimate.pose[2]),
        )
        return estimate
