"""CEAMCL tracking along a featureless corridor: 40 m long, 2.6 m wide, no door or niche, and
the paper's SICK (180 degrees forward, 8 m), so the far end is out of reach until the last
8 m and nothing in a scan says how far along the robot is. The odometry alone carries that
coordinate; a calibrated filter's ellipse then grows along the corridor.

CEAMCL keeps the track (with 120 samples about as well as `mcl-tuned` with 5,000:
docs/ceamcl.md, "A featureless corridor"), but its tracked species does not grow along the
corridor: eq. 17's crossover blends pairs of samples, which contracts a species wherever the
scans leave it free, so the ellipse is a few centimetres long while the error along the
corridor is a decimetre. Measured over seeds 0-7 (2026-12-03): the truth inside the 2-sigma
ellipse in 30 % of the steps (17-48 % a run; `mcl-tuned` with 5,000 particles 100 %, the Nav2
wheel 97 %). That is a known limit, kept here as an expected failure so that the suite says
when it changes.

At Nav2's pace (an update every 0.25 m or 0.2 rad, the ROS node's default) the species, 120
samples spread by the motion noise of a whole stride at each update, wanders 1-2 m along the
corridor, and when the far wall comes into reach its readings are shorter than the species
expects, end in free space, and so look like an unmapped obstacle in front of the laser: beam
skipping (docs/ceamcl.md, "Beam skipping while tracking") left them out, and the estimate stayed
1.0-2.1 m off to the end in 5 of seeds 0-7 and 4 of seeds 8-15. Departure 44 (docs/ceamcl.md)
counts the travel during which no surface of the scans faced along the track and, when one
does again, looks along the track as far as the odometry can have drifted: every one of seeds
0-15 then ends within 0.13 m.
Seeds 0 and 1 run here (the first ones, not picked; departure 44's settings were chosen on
seeds 0-7 and checked on 8-15)."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.demo import seeded_generators
from ceamcl.filters import make_filter
from ceamcl.filters.policies import on_motion
from ceamcl.filters.registry import with_config
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.pose import inside_ellipse
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation.simulator import SimulationConfig, Simulator, drive_waypoints

LENGTH_M, WIDTH_M, WALL_M, RES_M = 40.0, 2.6, 0.1, 0.05
SEEDS = (0, 1)


def corridor() -> OccupancyGrid:
    data = np.zeros((round(WIDTH_M / RES_M), round(LENGTH_M / RES_M)), dtype=np.int8)
    wall = round(WALL_M / RES_M)
    data[:wall, :] = data[-wall:, :] = data[:, :wall] = data[:, -wall:] = 100
    return OccupancyGrid(data, RES_M, (0.0, 0.0, 0.0), name="corridor")


def _runs(at_nav2_pace: bool, seeds: tuple[int, ...] = SEEDS, **changes: object) -> list[RunResult]:
    grid = corridor()
    config = SimulationConfig()
    path = drive_waypoints([2.0, WIDTH_M / 2, 0.0], [np.array([37.0, WIDTH_M / 2])], config)
    out = []
    for seed in seeds:
        sim_rng, filter_rng = seeded_generators(seed, 2)
        log = Simulator(grid, config).run(path, sim_rng)
        f = make_filter("ceamcl", grid, filter_rng, config=with_config("ceamcl", **changes))
        start = (log.true_poses[0], np.diag([0.01, 0.01, 0.005]))
        pace = on_motion(0.25, 0.2) if at_nav2_pace else None
        out.append(run_filter(f, log, initial_pose=start, update_when=pace))
    return out


@pytest.fixture(scope="module")
def runs() -> list[RunResult]:
    return _runs(at_nav2_pace=False)


def test_ceamcl_keeps_the_track_along_a_featureless_corridor(runs: list[RunResult]) -> None:
    for r in runs:
        assert r.truth is not None
        error = np.hypot(*(r.estimates[:, :2] - r.truth[:, :2]).T)
        print(f"error: max {error.max():.3f} m, at the end {error[-1]:.3f} m")
        assert np.all(np.isfinite(r.estimates))
        assert error.max() < 0.5  # the odometry's own drift, not a lost track (0.22-0.40 m)
        # the far wall in reach for the last 8 m pins the pose again
        assert error[-1] < 0.1


@pytest.mark.xfail(
    strict=True,
    reason="eq. 17's crossover contracts a species along the corridor, where the scans leave "
    "it free: the truth inside the 2-sigma ellipse in 30 % of the steps over seeds 0-7 "
    "(docs/ceamcl.md, 'A featureless corridor')",
)
def test_ceamcl_ellipse_covers_the_truth_along_a_featureless_corridor(
    runs: list[RunResult],
) -> None:
    parts = []
    for r in runs:
        assert r.truth is not None and r.covariances is not None
        parts.append(inside_ellipse(r.estimates, r.covariances, r.truth)[1:])
    inside = np.concatenate(parts)
    print(f"truth inside the 2-sigma ellipse in {inside.mean():.1%} of {inside.size} steps")
    assert inside.mean() >= 0.85


def _end_error(r: RunResult) -> float:
    assert r.truth is not None
    return float(np.hypot(*(r.estimates[-1, :2] - r.truth[-1, :2])))


def test_ceamcl_at_nav2s_pace_finds_the_far_end_of_a_featureless_corridor() -> None:
    for r in _runs(at_nav2_pace=True):
        error = _end_error(r)
        print(f"error at the end: {error:.3f} m")
        assert error < 0.1


def test_without_the_look_along_the_track_the_far_wall_is_taken_for_an_obstacle() -> None:
    """The contrast: seed 1 with departure 44 off ends where its species wandered to."""
    (r,) = _runs(at_nav2_pace=True, seeds=(1,), track_drift_sd=None)
    print(f"error at the end without departure 44: {_end_error(r):.3f} m")
    assert _end_error(r) > 1.0
