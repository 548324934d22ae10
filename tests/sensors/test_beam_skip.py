"""Beam skipping (ceamcl.sensors.beam_skip): short readings no hypothesis explains are left out;
readings through a wall of the map, and scans nothing explains, always count."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.maps.grid import FREE, OCCUPIED, OccupancyGrid
from ceamcl.sensors.beam_skip import (
    BeamSkipConfig,
    keep_beams,
    near_obstacle,
    near_obstacle_reference,
    skip_unexplained_beams,
)
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.sensors.raycast import cast_fan
from ceamcl.sensors.scan import LaserGeometry, PreparedScan, laser_poses

RES = 0.05
LASER = LaserGeometry.covering(np.pi, 61, 8.0)


def room(box: bool) -> OccupancyGrid:
    """A 10 m x 6 m room; with ``box``, a 0.6 m crate 2 m in front of (1.5, 3) facing +x."""
    data = np.full((120, 200), FREE, dtype=np.int8)
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = OCCUPIED
    if box:
        data[54:66, 70:82] = OCCUPIED  # x 3.5-4.1 m, y 2.7-3.3 m
    return OccupancyGrid(data, RES, (0.0, 0.0, 0.0), name="room")


POSE = np.array([1.5, 3.0, 0.0])


def scan_in(grid: OccupancyGrid, pose: np.ndarray = POSE):  # type: ignore[no-untyped-def]
    sensor = laser_poses(pose[None, :], LASER.pose)
    return LASER.scan(cast_fan(grid, sensor, LASER.angles, LASER.range_max)[0])


def test_the_readings_of_an_unmapped_obstacle_are_left_out() -> None:
    mapped = room(box=False)
    prepared = LikelihoodFieldModel(mapped).prepare(scan_in(room(box=True)))
    kept, skipped = skip_unexplained_beams(mapped, [POSE[None, :]], prepared, BeamSkipConfig())
    on_box = scan_in(room(box=True)).ranges < scan_in(mapped).ranges - 0.5
    assert 0 < skipped == prepared.n_beams - kept.n_beams
    assert skipped <= int(on_box.sum())  # only beams that hit the crate can go
    assert skipped >= int(on_box.sum()) - 2  # and all but its edge beams do
    # what is left fits the map as a clean scan does
    lf = LikelihoodFieldModel(mapped)
    fit = lf.log_likelihood(POSE[None, :], kept)[0] / kept.n_beams
    clean = lf.prepare(scan_in(mapped))
    assert fit >= lf.log_likelihood(POSE[None, :], clean)[0] / clean.n_beams - 0.05


def test_a_scan_the_map_explains_loses_no_beam() -> None:
    grid = room(box=False)
    prepared = LikelihoodFieldModel(grid).prepare(scan_in(grid))
    kept, skipped = skip_unexplained_beams(grid, [POSE[None, :]], prepared, BeamSkipConfig())
    assert skipped == 0 and kept is prepared


def test_readings_through_a_wall_always_count() -> None:
    """Seen from the wrong place (1 m from the right wall, facing it), the readings of the real
    scan run far beyond that wall: they are not clutter, and none of them is left out."""
    grid = room(box=False)
    prepared = LikelihoodFieldModel(grid).prepare(scan_in(grid))
    wrong = np.array([[8.9, 3.0, 0.0]])
    kept, _ = skip_unexplained_beams(grid, [wrong], prepared, BeamSkipConfig())
    sensor = laser_poses(wrong, LASER.pose)
    expected = cast_fan(grid, sensor, prepared.bearings, LASER.range_max)[0]
    through = prepared.ranges > expected + 0.5
    assert through.any()
    dropped = ~np.isin(prepared.bearings, kept.bearings)
    assert not (dropped & through).any()


def test_when_nothing_is_explained_every_beam_counts() -> None:
    grid = room(box=False)
    crowd = scan_in(grid).ranges.copy()
    crowd[:] = 0.4  # people all round the laser
    prepared = LikelihoodFieldModel(grid).prepare(LASER.scan(crowd))
    kept, skipped = skip_unexplained_beams(grid, [POSE[None, :]], prepared, BeamSkipConfig())
    assert skipped == 0 and kept.n_beams == prepared.n_beams


def crowded_scan(grid: OccupancyGrid, crowded: int) -> PreparedScan:
    """Ten beams from POSE, the first ``crowded`` of them on people 0.4 m away."""
    ten = LaserGeometry.covering(np.pi, 10, 8.0)
    true = cast_fan(grid, laser_poses(POSE[None, :], ten.pose), ten.angles, ten.range_max)[0]
    ranges = true.copy()
    ranges[:crowded] = 0.4  # people close in front, nowhere near a wall
    prepared = LikelihoodFieldModel(grid).prepare(ten.scan(ranges))
    assert prepared.n_beams == 10
    return prepared


def test_the_error_threshold_counts_as_amcls_at_the_boundary() -> None:
    # amcl: every beam counts once skipped >= beams x beam_skip_error_threshold (ours was >)
    grid = room(box=False)
    amcl = BeamSkipConfig(error_threshold=0.9)
    for crowded, expect in ((9, 0), (8, 8)):
        prepared = crowded_scan(grid, crowded)
        _, skipped = skip_unexplained_beams(grid, [POSE[None, :]], prepared, amcl)
        assert skipped == expect


def test_by_default_a_view_blocked_but_for_one_beam_still_skips() -> None:
    """CEAMCL's default (1.0, departure 34): the one reading the map explains is what the
    species is weighed by while people block the rest; only a view blocked everywhere counts
    every beam."""
    grid = room(box=False)
    for crowded, expect in ((9, 9), (10, 0)):
        prepared = crowded_scan(grid, crowded)
        kept, skipped = skip_unexplained_beams(grid, [POSE[None, :]], prepared, BeamSkipConfig())
        assert skipped == expect and kept.n_beams == 10 - expect


def test_any_hypothesis_that_explains_a_beam_keeps_it() -> None:
    """Two hypotheses: the crate's readings (about 2 m straight ahead) end on the right-hand
    wall seen from 2 m in front of it, so with that hypothesis alive they stay, and the
    hypothesis at the crate pays for them: beams are left out only when no hypothesis
    explains them."""
    mapped = room(box=False)
    prepared = LikelihoodFieldModel(mapped).prepare(scan_in(room(box=True)))
    _, n_alone = skip_unexplained_beams(mapped, [POSE[None, :]], prepared, BeamSkipConfig())
    near_wall = np.array([[7.9, 3.0, 0.0]])
    _, n_both = skip_unexplained_beams(
        mapped, [POSE[None, :], near_wall], prepared, BeamSkipConfig()
    )
    assert n_alone > 0
    assert n_both < n_alone


def test_keep_beams_is_consistent() -> None:
    grid = room(box=False)
    prepared = LikelihoodFieldModel(grid).prepare(scan_in(grid))
    keep = np.arange(prepared.n_beams) % 3 != 0
    kept = keep_beams(prepared, keep)
    assert kept.n_beams == int(keep.sum()) == kept.ranges.size == kept.bearings.size
    np.testing.assert_array_equal(kept.ranges, prepared.ranges[keep])


def test_a_trailing_cloud_keeps_the_readings_that_would_correct_it() -> None:
    """The robot at x = 6 m faces the right-hand wall; its tracked cloud is spread along x from
    4.8 to 6.2 m, so its centre trails by 0.5 m. Seen from the centre, the readings that hit
    that wall end short of it: with the centre alone they are left out as an obstacle the map
    lacks, and nothing pulls the cloud forward. Five of the 15 poses (33 %, more than amcl's
    30 %) explain them: the vote (off by default) keeps them."""
    grid = room(box=False)
    truth = np.array([6.0, 3.0, 0.0])
    prepared = LikelihoodFieldModel(grid).prepare(scan_in(grid, truth))
    cloud = np.column_stack([np.linspace(4.8, 6.2, 15), np.full(15, 3.0), np.zeros(15)])
    # beams that end on the right-hand wall (its inner face at x = 9.9 m)
    ahead = truth[0] + prepared.ranges * np.cos(prepared.bearings) > 9.5
    kept, skipped = skip_unexplained_beams(grid, [cloud], prepared, BeamSkipConfig())
    dropped = ~np.isin(prepared.bearings, kept.bearings)
    assert skipped > 0 and np.all(ahead[dropped])
    kept, skipped = skip_unexplained_beams(grid, [cloud], prepared, BeamSkipConfig(threshold=0.3))
    assert skipped == 0 and kept is prepared
    # a vote that asks for more than the 33 % leaves them out again
    _, skipped = skip_unexplained_beams(grid, [cloud], prepared, BeamSkipConfig(threshold=0.5))
    assert skipped > 0


def test_the_vote_does_not_keep_an_unmapped_obstacle() -> None:
    """A cloud spread 0.3 m about the true pose in front of the crate: no share of its poses
    puts the crate's readings near a wall, and they are still left out."""
    mapped = room(box=False)
    prepared = LikelihoodFieldModel(mapped).prepare(scan_in(room(box=True)))
    cloud = POSE[None, :] + np.column_stack(
        [np.linspace(-0.3, 0.3, 13), np.linspace(0.3, -0.3, 13), np.linspace(-0.05, 0.05, 13)]
    )
    _, centre_only = skip_unexplained_beams(mapped, [cloud], prepared, BeamSkipConfig())
    _, with_vote = skip_unexplained_beams(mapped, [cloud], prepared, BeamSkipConfig(threshold=0.3))
    assert centre_only > 0
    assert with_vote == centre_only


def test_the_vote_threshold_is_checked() -> None:
    import pytest

    for bad in (0.0, -0.1, 1.5):
        with pytest.raises(ValueError, match="threshold"):
            BeamSkipConfig(threshold=bad)


@pytest.mark.filterwarnings("ignore:invalid value encountered in cast:RuntimeWarning")
def test_near_obstacle_equals_its_numpy_reference() -> None:
    """Grids with shifted and rotated origins, poses on and off the map, NaN poses, laser
    mounts off the centre: the compiled test gives the reference's answer for every beam."""
    rng = np.random.default_rng(4)
    for case in range(40):
        data = np.full((60, 90), FREE, dtype=np.int8)
        data[rng.random(data.shape) < 0.05] = OCCUPIED
        origin = (float(rng.normal(0, 3)), float(rng.normal(0, 3)),
                  0.0 if case % 2 else float(rng.uniform(-np.pi, np.pi)))  # fmt: skip
        grid = OccupancyGrid(data, 0.1, origin, name="random")
        mount = (float(rng.normal(0, 0.2)), float(rng.normal(0, 0.1)), float(rng.normal(0, 0.3)))
        laser = LaserGeometry.covering(np.pi, 31, 6.0, pose=mount)
        ranges = rng.uniform(0.1, 6.0, 31)
        prepared = LikelihoodFieldModel(grid).prepare(laser.scan(ranges))
        poses = np.column_stack([rng.uniform(-5, 15, 20), rng.uniform(-5, 10, 20),
                                 rng.uniform(-np.pi, np.pi, 20)])  # fmt: skip
        poses[0] = np.nan
        for d in (0.2, 0.5):
            got = near_obstacle(grid, poses, prepared, d)
            np.testing.assert_array_equal(got, near_obstacle_reference(grid, poses, prepared, d))
        assert not got[0].any()  # a NaN pose explains nothing
