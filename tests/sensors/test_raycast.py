"""Tests of the ray caster (``ceamcl.sensors.raycast``) against brute force and geometry."""

from __future__ import annotations

import time

import numpy as np
import pytest

from ceamcl.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from ceamcl.maps.worlds import get_world
from ceamcl.sensors import raycast
from ceamcl.sensors.raycast import cast_fan, cast_rays, cast_rays_reference

MAX_RANGE = 8.0


def random_blocks_grid(seed: int = 0) -> OccupancyGrid:
    """Rectangles of obstacles, a sprinkle of unknown cells, a rotated and shifted origin."""
    rng = np.random.default_rng(seed)
    data = np.full((80, 100), FREE, dtype=np.int8)
    for _ in range(25):
        x, y = rng.integers(0, 95), rng.integers(0, 75)
        w, h = rng.integers(1, 8, 2)
        data[y : y + h, x : x + w] = OCCUPIED
    data[rng.random(data.shape) < 0.01] = UNKNOWN
    return OccupancyGrid(data, 0.1, (2.0, -3.0, 0.7), name="random-blocks")


def box_grid() -> OccupancyGrid:
    """10 x 10 m, 0.1 m cells, one-cell walls all round, origin shifted and rotated."""
    data = np.full((100, 100), FREE, dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = OCCUPIED
    return OccupancyGrid(data, 0.1, (-1.0, 2.0, 0.5))


GRIDS = {
    "symmetric-hall": lambda: get_world("symmetric-hall"),
    "small-office": lambda: get_world("small-office"),
    "random-blocks": random_blocks_grid,
}


@pytest.mark.parametrize("name", list(GRIDS))
def test_cast_rays_agrees_with_brute_force_within_one_cell(name: str) -> None:
    grid = GRIDS[name]()
    rng = np.random.default_rng(10)
    n = 2000
    rays = grid.sample_free_poses(n, rng)
    fast = cast_rays(grid, rays[:, :2], rays[:, 2], MAX_RANGE)
    ref = cast_rays_reference(grid, rays[:, :2], rays[:, 2], MAX_RANGE)
    assert fast.shape == (n,)
    assert np.all((fast >= 0.0) & (fast <= MAX_RANGE))
    off = np.abs(fast - ref) > grid.resolution
    # The reference samples each ray every 2% of a cell, so it can step over a blocking cell
    # whose corner the ray clips by less than that. For a ray hitting ~1 corner in its path
    # that happens with probability of order 0.02, so only a few percent of rays may disagree,
    # and each of them must agree with a reference 40 times finer (0.05% of a cell).
    assert off.mean() < 0.02
    if off.any():
        fine = cast_rays_reference(
            grid, rays[off, :2], rays[off, 2], MAX_RANGE, step_fraction=0.0005
        )
        np.testing.assert_allclose(fast[off], fine, atol=grid.resolution)
        # Stepping over a corner only ever makes the reference's ray longer.
        assert np.all(ref[off] > fast[off])
    # Sanity of the sample: most rays hit something, some do not (the office is fully
    # walled; the random-blocks map has open sides).
    assert np.mean(fast < MAX_RANGE) > 0.5


def test_exact_range_to_a_wall_in_a_rotated_box() -> None:
    g = box_grid()
    # Grid-frame point (5.0, 5.05) looking along the grid's +x axis: the wall cell ix = 99
    # starts at 9.9, so the range is 4.9 m. Other axis directions likewise.
    mx = np.array([5.0, 5.0, 5.0, 5.0])
    my = np.array([5.05, 5.05, 5.05, 5.05])
    yaw = g.origin[2]
    headings = yaw + np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])
    x, y = g.map_to_world(mx, my)
    r = cast_rays(g, np.column_stack([x, y]), headings, MAX_RANGE)
    np.testing.assert_allclose(r, [4.9, 4.85, 4.9, 4.95], atol=1e-6)
    # Diagonal to the corner region: compare with the analytic hit of the first wall plane.
    r45 = cast_rays(g, np.column_stack([x[:1], y[:1]]), [yaw + np.pi / 4], MAX_RANGE)
    assert r45[0] == pytest.approx((9.9 - 5.05) * np.sqrt(2.0), abs=1e-6)


def test_rays_starting_inside_obstacles_return_zero() -> None:
    for grid in (get_world("small-office"), random_blocks_grid()):
        blocked_y, blocked_x = np.nonzero(grid.blocking_mask)
        rng = np.random.default_rng(11)
        pick = rng.choice(blocked_x.size, 500, replace=False)
        x, y = grid.cell_to_world(blocked_x[pick], blocked_y[pick])
        angles = rng.uniform(-np.pi, np.pi, 500)
        r = cast_rays(grid, np.column_stack([x, y]), angles, MAX_RANGE)
        assert np.all(r == 0.0)


def test_rays_leaving_the_map_return_max_range() -> None:
    rng = np.random.default_rng(12)
    empty = OccupancyGrid(np.zeros((40, 60), np.int8), 0.1, (1.0, 1.0, 0.3))
    poses = empty.sample_free_poses(1000, rng)
    for max_range in (3.0, 20.0):  # whether the map edge is nearer than max_range or not
        r = cast_rays(empty, poses[:, :2], poses[:, 2], max_range)
        assert np.all(r == max_range)
    # Rays from outside the map, even pointing at it, see nothing.
    outside = np.array([[-5.0, -5.0], [50.0, 50.0]])
    r = cast_rays(empty, outside, [0.7, 0.7 + np.pi], MAX_RANGE)
    assert np.all(r == MAX_RANGE)
    # In the walled box, a range shorter than the distance to the wall reports max_range.
    g = box_grid()
    x, y = g.map_to_world(5.0, 5.05)
    assert cast_rays(g, [[float(x), float(y)]], [g.origin[2]], 2.0)[0] == 2.0


@pytest.mark.parametrize("name", ["symmetric-hall", "random-blocks"])
def test_cast_fan_equals_cast_rays(name: str) -> None:
    grid = GRIDS[name]()
    rng = np.random.default_rng(13)
    poses = grid.sample_free_poses(200, rng)
    bearings = np.linspace(-np.pi / 2, np.pi / 2, 37)
    fan = cast_fan(grid, poses, bearings, MAX_RANGE)
    assert fan.shape == (200, 37)
    origins = np.repeat(poses[:, :2], bearings.size, axis=0)
    angles = (poses[:, 2:3] + bearings[None, :]).reshape(-1)
    rays = cast_rays(grid, origins, angles, MAX_RANGE).reshape(200, 37)
    # Same rays; the two paths only differ in how the heading is wrapped (round-off).
    np.testing.assert_allclose(fan, rays, rtol=0, atol=1e-9)


@pytest.mark.parametrize("n", [1, 4, 5, 200])
def test_cast_fan_gives_the_same_bits_on_one_thread_or_two(n: int) -> None:
    """Small fans (fewer than PARALLEL_MIN_RAYS rays) are cast on one thread; both variants
    give the same ranges, so the switch changes no result."""
    grid = GRIDS["random-blocks"]()
    poses = grid.sample_free_poses(n, np.random.default_rng(n))
    bearings = np.linspace(-np.pi, np.pi, 60, endpoint=False)
    mp = np.ascontiguousarray(grid.poses_to_map(poses))
    for blocking, dist in ((grid.occupied_mask, grid.distance_to_occupied),
                           (grid.blocking_mask, grid.distance_to_blocking)):  # fmt: skip
        args = (mp, bearings, blocking, dist, grid.resolution, MAX_RANGE)
        serial, parallel = raycast._cast_fan_serial(*args), raycast._cast_fan_parallel(*args)
        assert serial.tobytes() == parallel.tobytes()
    expected = raycast._cast_fan_serial(
        mp, bearings, grid.blocking_mask, grid.distance_to_blocking, grid.resolution, MAX_RANGE
    )
    assert cast_fan(grid, poses, bearings, MAX_RANGE).tobytes() == expected.tobytes()


def test_axis_aligned_rays_from_cell_boundaries_do_not_stall() -> None:
    """Regression: a ray running along a cell boundary used to advance by 1e-9 m per DDA step
    near walls (its step to the boundary it sat on was <= 0 after round-off), about 1 s per
    ray. The simulator hits this whenever a true pose sits on a 5 cm boundary."""
    grid = get_world("symmetric-hall")
    xs = np.array([11.15, 10.55, 9.95, 3.75, 3.85, 7.6])
    ys = np.array([3.75, 3.75, 3.75, 3.85, 3.75, 0.3])
    origins = np.repeat(np.column_stack([xs, ys]), 8, axis=0)
    quarter_turns = np.tile(np.arange(-4, 4), xs.size)
    angles = quarter_turns * (np.pi / 2)  # unwrapped, as the simulator passes them
    cast_rays(grid, origins[:1], angles[:1], MAX_RANGE)  # compile outside the timing
    start = time.perf_counter()
    fast = cast_rays(grid, origins, angles, MAX_RANGE)
    elapsed = time.perf_counter() - start
    # 48 rays take microseconds each; the stalled march took ~1 s for one.
    assert elapsed < 0.5
    ref = cast_rays_reference(grid, origins, angles, MAX_RANGE)
    np.testing.assert_allclose(fast, ref, atol=grid.resolution)
