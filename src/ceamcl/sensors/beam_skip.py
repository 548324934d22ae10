"""Beam skipping: leave out the short readings that no hypothesis explains (unmapped obstacles).

A person, a trolley or a new wall in front of the laser gives readings the map does not hold.
Under the likelihood field each such beam costs a pose up to about 8 nats (before tempering)
wherever its end point lies far from the map's walls, and a wrong place where the clutter
happens to fall near a wall is paid for explaining it. On real logs this is what makes filters
leave the truth (docs/real-data.md, "Why the filters lose track"): on intel the log-likelihood
at the true pose falls by about 25 (tempered) under clutter, places elsewhere explain the scan
better, and CEAMCL's kidnap recovery fires on a robot that was never kidnapped.

ROS amcl's answer is ``do_beamskip`` (likelihood field; ``beam_skip_distance`` 0.5 m,
``beam_skip_threshold`` 0.3, ``beam_skip_error_threshold`` 0.9): a beam counts when more than
30 % of the particles put its end point within 0.5 m of an obstacle; when 90 % of the beams or
more would go, the robot is lost rather than surrounded by clutter, and every beam counts.
:func:`skip_unexplained_beams` asks it for groups of poses (hypotheses: CEAMCL's species):

* a beam is *explained* when, seen from the centre of **any** group of poses (a species: its
  mean position and circular mean heading), it ends within ``distance_m`` of an obstacle (one
  pose per hypothesis instead of a 30 % vote: a tracked cloud spread by the motion put a share
  of its end points near a wall for beams that end 0.6-1 m from it at its centre, on intel).
  With ``threshold`` set, a beam is also explained when more than that share of the poses of
  a group (amcl's vote) put its end point near an obstacle: it keeps the readings that pin the
  pose when the centre trails the robot along a corridor, but lets more clutter count, and on
  the real logs it left the truth at more steps than it saved (docs/state.md, "amcl's vote,
  measured"), so it is off by default;
* an unexplained beam is left out only when it is **short** at every centre: shorter, by more
  than ``distance_m``, than the range to the first occupied cell along it (unknown cells let
  the ray through). A reading that passes through a wall of the map says the hypothesis is
  wrong, and keeps counting, so a kidnapped robot is still noticed;
* when ``error_threshold`` of the beams or more would go, none does. amcl's default is 0.9
  (``beam_skip_error_threshold``): a filter that sees almost nothing it expects is lost rather
  than surrounded by clutter. Ours is 1.0: only when *every* reading would go do they all
  count. The readings that can prove a pose wrong, those through a wall, are never left out
  here, so a view blocked by people says nothing against the pose; on fhw a crowd blocking 90 %
  or more of the view for a few scans made every reading count, slid the track 1.6-2.6 m and
  set off a global recovery (docs/ceamcl.md, departure 34).

Every group is then scored on the same beams, so likelihoods stay comparable between them.
CEAMCL skips beams only while a single species lives (tracking): with several, the beams one
hypothesis cannot explain are the ones that tell it from the others (docs/ceamcl.md).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

import numba
import numpy as np
from numpy.typing import NDArray

from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.raycast import cast_fan
from ceamcl.sensors.scan import PreparedScan, laser_poses


@dataclass(frozen=True)
class BeamSkipConfig:
    """amcl's ``beam_skip_distance`` (same default) and ``beam_skip_error_threshold`` (1.0
    here, amcl's 0.9: departure 34); ``threshold`` is amcl's ``beam_skip_threshold`` (its
    default is 0.3), a vote that explains a beam besides the centres, off (``None``) by default
    (module docstring)."""

    distance_m: float = 0.5  # beam_skip_distance
    error_threshold: float = 1.0  # beam_skip_error_threshold (amcl: 0.9)
    threshold: float | None = None  # beam_skip_threshold; None: the centres alone decide

    def __post_init__(self) -> None:
        if not self.distance_m > 0:
            raise ValueError(f"beam_skip distance_m: expected > 0, got {self.distance_m}")
        if self.threshold is not None and not 0 < self.threshold <= 1:
            raise ValueError(f"beam_skip threshold: expected in (0, 1], got {self.threshold}")
        if not 0 < self.error_threshold <= 1:
            raise ValueError(
                f"beam_skip error_threshold: expected in (0, 1], got {self.error_threshold}"
            )


def near_obstacle(
    grid: OccupancyGrid,
    poses: NDArray[np.float64],
    prepared: PreparedScan,
    distance_m: float,
) -> NDArray[np.bool_]:
    """``(N, M)``: whether beam ``m`` seen from pose ``n`` ends within ``distance_m`` of an
    obstacle of ``grid`` (end points off the map are near nothing). Compiled
    (:func:`_near_obstacle`), with the operations of :func:`near_obstacle_reference`, its
    NumPy form, which it equals."""
    p = np.ascontiguousarray(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
    result: NDArray[np.bool_] = _near_obstacle(
        p,
        np.asarray(prepared.laser_pose, dtype=np.float64).reshape(3),
        np.ascontiguousarray(prepared.bearings, dtype=np.float64),
        np.ascontiguousarray(prepared.ranges, dtype=np.float64),
        np.asarray(grid.origin, dtype=np.float64).reshape(3),
        float(grid.resolution),
        grid.distance_to_occupied,
        float(distance_m),
    )
    return result


@numba.njit(cache=True)
def _near_obstacle(  # type: ignore[no-untyped-def]  # pragma: no cover
    poses, laser, bearings, ranges, origin, res, dist, distance_m
):
    """Each beam's end point from each pose (``laser_poses``, then ``grid.world_to_cell``),
    operation for operation as the reference, and whether the map's distance there is below
    ``distance_m``."""
    n, m = poses.shape[0], bearings.size
    lx, ly, lyaw = laser[0], laser[1], laser[2]
    ox, oy, oyaw = origin[0], origin[1], origin[2]
    co, so = np.cos(oyaw), np.sin(oyaw)
    height, width = dist.shape
    out = np.zeros((n, m), dtype=np.bool_)
    for i in range(n):
        c, s = np.cos(poses[i, 2]), np.sin(poses[i, 2])
        x0 = poses[i, 0] + c * lx - s * ly
        y0 = poses[i, 1] + s * lx + c * ly
        heading = poses[i, 2] + lyaw
        for j in range(m):
            ang = heading + bearings[j]
            dx = x0 + ranges[j] * np.cos(ang) - ox
            dy = y0 + ranges[j] * np.sin(ang) - oy
            if oyaw != 0.0:
                dx, dy = co * dx + so * dy, -so * dx + co * dy
            fx, fy = np.floor(dx / res), np.floor(dy / res)
            if 0.0 <= fx < width and 0.0 <= fy < height:  # NaN and infinities fall outside
                out[i, j] = dist[int(fy), int(fx)] < distance_m
    return out


def near_obstacle_reference(
    grid: OccupancyGrid,
    poses: NDArray[np.float64],
    prepared: PreparedScan,
    distance_m: float,
) -> NDArray[np.bool_]:
    """:func:`near_obstacle` in NumPy."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    lp = laser_poses(p, prepared.laser_pose)
    ang = lp[:, 2:3] + prepared.bearings[None, :]
    ex = lp[:, 0:1] + prepared.ranges[None, :] * np.cos(ang)
    ey = lp[:, 1:2] + prepared.ranges[None, :] * np.sin(ang)
    ix, iy = grid.world_to_cell(ex, ey)
    inside = grid.in_bounds(ix, iy)
    near = np.zeros(ex.shape, dtype=bool)
    near[inside] = grid.distance_to_occupied[iy[inside], ix[inside]] < distance_m
    return near


def keep_beams(prepared: PreparedScan, keep: NDArray[np.bool_]) -> PreparedScan:
    """``prepared`` with only the beams where ``keep`` is true."""
    return replace(
        prepared,
        ranges=prepared.ranges[keep],
        bearings=prepared.bearings[keep],
        is_max=prepared.is_max[keep],
        n_beams=int(np.count_nonzero(keep)),
        source_indices=(
            prepared.source_indices[keep]
            if prepared.source_indices.size == keep.size
            else prepared.source_indices
        ),
    )


def skip_unexplained_beams(
    grid: OccupancyGrid,
    groups: Iterable[NDArray[np.float64]],
    prepared: PreparedScan,
    config: BeamSkipConfig,
) -> tuple[PreparedScan, int]:
    """The beams that at least one group of poses explains (module docstring), and how many
    were left out. ``prepared`` itself when none is left out, or when ``error_threshold`` of
    them or more would be (with the default 1.0: every one of them; nothing of the map is in
    view, and every beam must count)."""
    if prepared.n_beams == 0:
        return prepared, 0
    poses = [p for p in (np.asarray(g, dtype=np.float64).reshape(-1, 3) for g in groups) if len(p)]
    if not poses:
        return prepared, 0
    centres = np.array([_centre(p) for p in poses])
    explained = np.any(near_obstacle(grid, centres, prepared, config.distance_m), axis=0)
    if explained.all():
        return prepared, 0
    loose = np.flatnonzero(~explained)
    if config.threshold is not None:
        # amcl's vote, asked only of the beams no centre explains
        sub = keep_beams(prepared, ~explained)
        voted = np.zeros(loose.size, dtype=bool)
        for p in poses:
            voted |= near_obstacle(grid, p, sub, config.distance_m).mean(axis=0) > config.threshold
        loose = loose[~voted]
        if loose.size == 0:
            return prepared, 0
    # Only readings *shorter* than the map allows can be an obstacle it lacks (unknown cells
    # allow anything); a reading that goes through a wall of the map at every hypothesis says
    # the hypotheses are wrong, and counts.
    sensors = laser_poses(centres, prepared.laser_pose)
    expected = cast_fan(
        grid, sensors, prepared.bearings[loose], prepared.range_max, through_unknown=True
    )
    short = np.all(prepared.ranges[loose][None, :] < expected - config.distance_m, axis=0)
    drop = np.zeros(prepared.n_beams, dtype=bool)
    drop[loose[short]] = True
    skipped = int(np.count_nonzero(drop))
    if skipped == 0 or skipped >= config.error_threshold * prepared.n_beams:  # amcl's >=
        return prepared, 0
    return keep_beams(prepared, ~drop), skipped


def _centre(poses: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean position and circular mean heading of a group of poses."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    heading = np.arctan2(np.mean(np.sin(p[:, 2])), np.mean(np.cos(p[:, 2])))
    return np.array([p[:, 0].mean(), p[:, 1].mean(), heading])


__all__ = ["BeamSkipConfig", "keep_beams", "near_obstacle", "skip_unexplained_beams"]
