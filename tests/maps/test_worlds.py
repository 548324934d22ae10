"""Tests of the built-in worlds (``ceamcl.maps.worlds``) and the routes driven in them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from ceamcl.errors import ConfigError
from ceamcl.maps.worlds import (
    HALL_SIZE_M,
    WORLD_NAMES,
    get_world,
    room_centre,
    rotate_poses_about_centre,
    symmetric_images,
)
from ceamcl.simulation.scenarios import paper_scenario

HALL_WORLDS = ("symmetric-hall", "marked-hall")


def room_of(x: float, y: float) -> int:
    """Room number (0 SW, 1 SE, 2 NE, 3 NW) of a point of the hall."""
    c = HALL_SIZE_M / 2.0
    return {(False, False): 0, (True, False): 1, (True, True): 2, (False, True): 3}[(x > c, y > c)]


def test_world_names_and_shapes() -> None:
    assert set(WORLD_NAMES) == {"symmetric-hall", "marked-hall", "small-office"}
    for name in HALL_WORLDS:
        g = get_world(name)
        assert g.size_m == pytest.approx((HALL_SIZE_M, HALL_SIZE_M))
        assert g.origin == (0.0, 0.0, 0.0)
        assert g.name == name
    office = get_world("small-office")
    assert office.size_m == pytest.approx((10.0, 8.0))


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_symmetric_hall_is_invariant_under_quarter_turns(k: int) -> None:
    g = get_world("symmetric-hall")
    assert np.array_equal(np.rot90(g.data, k), g.data)


def test_symmetric_hall_is_not_mirror_symmetric() -> None:
    # The cabinets break the mirror symmetries, leaving exactly four images of each pose.
    data = get_world("symmetric-hall").data
    assert not np.array_equal(data, data.T)
    assert not np.array_equal(data, np.flipud(data))
    assert not np.array_equal(data, np.fliplr(data))


def test_symmetric_images_are_equally_plausible_poses() -> None:
    # The four images of a pose see the same cells: the map rotated about the centre.
    g = get_world("symmetric-hall")
    pose = np.array([2.025, 5.025, 0.3])  # a cell centre, clear of cell boundaries
    images = symmetric_images(pose)
    assert images.shape == (4, 3)
    np.testing.assert_allclose(images[0], pose, atol=1e-12)
    ix, iy = g.world_to_cell(images[:, 0], images[:, 1])
    assert np.all(g.distance_to_occupied[iy, ix] == g.distance_to_occupied[iy[0], ix[0]])
    assert {room_of(x, y) for x, y in images[:, :2]} == {0, 1, 2, 3}
    back = rotate_poses_about_centre(images[1:2], 3)[0]
    np.testing.assert_allclose(back, pose, atol=1e-9)


@pytest.mark.parametrize("name", WORLD_NAMES)
def test_free_space_is_one_connected_region(name: str) -> None:
    g = get_world(name)
    _, count = ndimage.label(g.free_mask)
    assert count == 1
    # A robot of 0.25 m radius can still drive everywhere: the cells with that clearance are
    # connected too (every doorway is wide enough).
    _, count_robot = ndimage.label(g.distance_to_occupied > 0.25)
    assert count_robot == 1
    # Every room has free space at its centre, hence all rooms are reachable from each other.
    if name in HALL_WORLDS:
        for room in range(4):
            assert g.is_free(*room_centre(room))


def test_hall_has_walls_all_round() -> None:
    g = get_world("symmetric-hall")
    assert g.occupied_mask[0, :].all() and g.occupied_mask[-1, :].all()
    assert g.occupied_mask[:, 0].all() and g.occupied_mask[:, -1].all()


def test_marked_hall_differs_only_by_a_small_box_in_room_3() -> None:
    sym = get_world("symmetric-hall")
    marked = get_world("marked-hall")
    changed = sym.data != marked.data
    assert changed.any()
    # Only free cells became occupied; nothing else moved.
    assert np.all(sym.free_mask[changed]) and np.all(marked.occupied_mask[changed])
    iy, ix = np.nonzero(changed)
    x, y = sym.cell_to_world(ix, iy)
    assert np.all(x < 7.5) and np.all(y > 7.5)  # room 3 (north-west)
    # A small mark: one compact blob within a 1 m x 1 m square, under 1% of room 3's area.
    _, blobs = ndimage.label(changed)
    assert blobs == 1
    assert x.max() - x.min() <= 1.0 and y.max() - y.min() <= 1.0
    assert changed.sum() * sym.resolution**2 < 0.01 * 7.5 * 7.5
    # ... which breaks the rotational symmetry.
    assert not np.array_equal(np.rot90(marked.data), marked.data)


def test_unknown_world_raises_config_error_naming_the_valid_ones() -> None:
    with pytest.raises(ConfigError) as info:
        get_world("no-such-world")
    message = str(info.value)
    assert "no-such-world" in message
    for name in WORLD_NAMES:
        assert name in message


@pytest.mark.parametrize("world", HALL_WORLDS)
@pytest.mark.parametrize("start_room", [0, 1, 2, 3])
def test_paper_route_keeps_clear_of_obstacles(world: str, start_room: int) -> None:
    sc = paper_scenario(start_room, world)
    g = sc.grid()
    path = sc.true_path()
    ix, iy = g.world_to_cell(path[:, 0], path[:, 1])
    assert np.all(g.in_bounds(ix, iy))
    assert np.all(g.free_mask[iy, ix])
    assert np.all(g.distance_to_occupied[iy, ix] > 0.3)
    # From the centre of the start room into the next room clockwise.
    np.testing.assert_allclose(path[0, :2], room_centre(start_room), atol=1e-9)
    assert room_of(*path[0, :2]) == start_room
    assert room_of(*path[-1, :2]) == sc.goal_room == (start_room + 3) % 4


def test_paper_routes_are_rotations_of_each_other() -> None:
    base = paper_scenario(0).true_path()
    for k in range(1, 4):
        path = paper_scenario(k).true_path()
        assert path.shape == base.shape
        rotated = rotate_poses_about_centre(base, k)
        np.testing.assert_allclose(path[:, :2], rotated[:, :2], atol=1e-9)
        np.testing.assert_allclose(np.cos(path[:, 2] - rotated[:, 2]), 1.0, atol=1e-9)
