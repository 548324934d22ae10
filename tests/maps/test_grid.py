"""Tests of the occupancy grid (``ceamcl.maps.grid``)."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest
from scipy import stats

from ceamcl.errors import MapFormatError
from ceamcl.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid

ORIGIN = (1.5, -2.0, 0.6)


def random_grid(rng: np.random.Generator, shape: tuple[int, int] = (30, 40)) -> OccupancyGrid:
    data = np.full(shape, FREE, dtype=np.int8)
    u = rng.random(shape)
    data[u < 0.1] = OCCUPIED
    data[(u >= 0.1) & (u < 0.15)] = UNKNOWN
    return OccupancyGrid(data, 0.1, ORIGIN)


def test_cell_world_round_trip_with_origin_and_yaw() -> None:
    rng = np.random.default_rng(0)
    g = random_grid(rng)
    ix = rng.integers(-5, g.width + 5, 5000)
    iy = rng.integers(-5, g.height + 5, 5000)
    x, y = g.cell_to_world(ix, iy)
    jx, jy = g.world_to_cell(x, y)
    assert np.array_equal(jx, ix)
    assert np.array_equal(jy, iy)
    # Any point in a cell maps to that cell: offsets within the cell, rotated by the yaw.
    ox, oy, yaw = ORIGIN
    fx, fy = rng.uniform(0.01, 0.99, (2, 5000))
    mx, my = (ix + fx) * g.resolution, (iy + fy) * g.resolution
    px = ox + np.cos(yaw) * mx - np.sin(yaw) * my
    py = oy + np.sin(yaw) * mx + np.cos(yaw) * my
    kx, ky = g.world_to_cell(px, py)
    assert np.array_equal(kx, ix)
    assert np.array_equal(ky, iy)


def test_map_frame_transform_is_the_origin_pose() -> None:
    rng = np.random.default_rng(1)
    g = random_grid(rng)
    ox, oy, yaw = ORIGIN
    x0, y0 = g.map_to_world(0.0, 0.0)
    assert (float(x0), float(y0)) == pytest.approx((ox, oy))
    x1, y1 = g.map_to_world(1.0, 0.0)  # the grid's x axis points along the origin's yaw
    assert (float(x1 - x0), float(y1 - y0)) == pytest.approx((np.cos(yaw), np.sin(yaw)))
    x, y = rng.uniform(-10, 10, (2, 1000))
    bx, by = g.map_to_world(*g.world_to_map(x, y))
    np.testing.assert_allclose(bx, x, atol=1e-12)
    np.testing.assert_allclose(by, y, atol=1e-12)
    poses = np.column_stack([x, y, rng.uniform(-np.pi, np.pi, 1000)])
    mp = g.poses_to_map(poses)
    np.testing.assert_allclose(np.cos(mp[:, 2]), np.cos(poses[:, 2] - yaw), atol=1e-12)
    np.testing.assert_allclose(np.sin(mp[:, 2]), np.sin(poses[:, 2] - yaw), atol=1e-12)


def test_bounds_cover_the_rotated_corners() -> None:
    g = OccupancyGrid(np.zeros((10, 20), np.int8), 0.5, (0.0, 0.0, np.pi / 2))
    xmin, xmax, ymin, ymax = g.bounds
    # 10 m along the grid's x (world +y), 5 m along its y (world -x).
    assert (xmin, xmax, ymin, ymax) == pytest.approx((-5.0, 0.0, 0.0, 10.0), abs=1e-9)
    assert g.size_m == (10.0, 5.0)


def test_is_free_by_cell_class_and_off_the_map() -> None:
    rng = np.random.default_rng(2)
    g = random_grid(rng)
    iy, ix = np.indices(g.data.shape)
    x, y = g.cell_to_world(ix.ravel(), iy.ravel())
    free = g.is_free(x, y)
    assert np.array_equal(free, g.data.ravel() == FREE)
    assert np.any(free) and not np.all(free)
    ox, oy = g.cell_to_world(np.array([-1, g.width, 3]), np.array([3, 3, g.height]))
    assert not np.any(g.is_free(ox, oy))


def test_cell_classes_follow_ros_thresholds() -> None:
    values = np.array([[0, 19, 20, 64, 65, 100, -1]], dtype=np.int8)
    g = OccupancyGrid(values, 1.0)
    assert g.free_mask.tolist() == [[True, True, False, False, False, False, False]]
    assert g.occupied_mask.tolist() == [[False, False, False, False, True, True, False]]
    assert g.unknown_mask.tolist() == [[False, False, True, True, False, False, True]]
    assert np.array_equal(g.blocking_mask, ~g.free_mask)


def two_region_grid() -> OccupancyGrid:
    """Free region A (10 x 20 cells) and B (30 x 20 cells), split by a wall and unknown."""
    data = np.full((24, 48), UNKNOWN, dtype=np.int8)
    data[2:22, 2:12] = FREE  # A: 200 cells
    data[:, 12:14] = OCCUPIED
    data[2:22, 15:45] = FREE  # B: 600 cells
    return OccupancyGrid(data, 0.05, (-3.0, 4.0, -1.1))


def test_sample_free_poses_only_in_free_cells_uniform_in_area_and_heading() -> None:
    g = two_region_grid()
    rng = np.random.default_rng(3)
    n = 200_000
    poses = g.sample_free_poses(n, rng)
    assert poses.shape == (n, 3)
    assert np.all(g.is_free(poses[:, 0], poses[:, 1]))
    ix, iy = g.world_to_cell(poses[:, 0], poses[:, 1])
    # Region A holds 200 of the 800 free cells: the share is a binomial proportion with
    # p = 0.25, SE = sqrt(p (1 - p) / n); allow 5 SE.
    in_a = ix < 12
    p = 200 / 800
    assert abs(in_a.mean() - p) < 5 * np.sqrt(p * (1 - p) / n)
    # Every free cell equally likely: Pearson's chi-square over the 800 cells has mean df and
    # standard deviation sqrt(2 df) under uniformity; allow 5 standard deviations.
    flat = iy * g.width + ix
    counts = np.bincount(flat, minlength=g.data.size)[g.free_cells]
    assert counts.size == 800 and counts.sum() == n
    expected = n / counts.size
    chi2 = float(np.sum((counts - expected) ** 2 / expected))
    df = counts.size - 1
    assert abs(chi2 - df) < 5 * np.sqrt(2 * df)
    # Uniform within each cell: the fractional position in the grid frame is U(0, 1).
    mp = g.poses_to_map(poses)
    frac_x = np.mod(mp[:, 0] / g.resolution, 1.0)
    frac_y = np.mod(mp[:, 1] / g.resolution, 1.0)
    # Kolmogorov-Smirnov: p-value below 1e-4 would be a 1-in-10,000 event for a uniform sample.
    assert stats.kstest(frac_x, "uniform").pvalue > 1e-4
    assert stats.kstest(frac_y, "uniform").pvalue > 1e-4
    # Headings uniform on (-pi, pi].
    assert np.all((poses[:, 2] > -np.pi) & (poses[:, 2] <= np.pi))
    assert stats.kstest(poses[:, 2], stats.uniform(loc=-np.pi, scale=2 * np.pi).cdf).pvalue > 1e-4


def test_sample_free_poses_is_reproducible_and_validates() -> None:
    g = two_region_grid()
    a = g.sample_free_poses(100, np.random.default_rng(7))
    b = g.sample_free_poses(100, np.random.default_rng(7))
    assert np.array_equal(a, b)
    assert g.sample_free_poses(0, np.random.default_rng(7)).shape == (0, 3)
    with pytest.raises(ValueError):
        g.sample_free_poses(-1, np.random.default_rng(7))
    walls = OccupancyGrid(np.full((3, 3), OCCUPIED, np.int8), 0.1)
    with pytest.raises(MapFormatError):
        walls.sample_free_poses(5, np.random.default_rng(7))


def brute_force_distance(mask: np.ndarray, resolution: float) -> np.ndarray:
    obstacles = np.argwhere(mask)
    cells = np.argwhere(np.ones_like(mask))
    d = np.sqrt(((cells[:, None, :] - obstacles[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    return d.reshape(mask.shape) * resolution


def test_distance_fields_match_brute_force() -> None:
    rng = np.random.default_rng(4)
    g = random_grid(rng, (23, 31))
    np.testing.assert_allclose(
        g.distance_to_occupied, brute_force_distance(g.occupied_mask, g.resolution), atol=1e-12
    )
    np.testing.assert_allclose(
        g.distance_to_blocking, brute_force_distance(g.blocking_mask, g.resolution), atol=1e-12
    )
    assert np.all(g.distance_to_occupied[g.occupied_mask] == 0.0)
    # Unknown cells block beams but are not obstacles for the likelihood field.
    assert np.all(g.distance_to_occupied[g.unknown_mask] > 0.0)


def test_distance_without_obstacles_is_infinite() -> None:
    g = OccupancyGrid(np.zeros((4, 5), np.int8), 0.1)
    assert np.all(np.isinf(g.distance_to_occupied))


def test_equality_and_validation() -> None:
    data = np.zeros((4, 5), np.int8)
    a = OccupancyGrid(data, 0.1, (1.0, 2.0, 0.3), name="a")
    b = OccupancyGrid(data.copy(), 0.1, (1.0, 2.0, 0.3), name="b")
    assert a == b  # the name does not count
    assert a != OccupancyGrid(data, 0.1, (1.0, 2.0, 0.4))
    assert a != a.with_data(np.where(data == 0, 100, 0))
    assert not a.data.flags.writeable
    with pytest.raises(MapFormatError):
        OccupancyGrid(np.zeros((0, 3), np.int8), 0.1)
    with pytest.raises(MapFormatError):
        OccupancyGrid(data, 0.0)
    with pytest.raises(MapFormatError):
        OccupancyGrid(data, 0.1, (0.0, float("nan"), 0.0))


@pytest.mark.parametrize(
    ("values", "says"),
    [
        ([[0, 254], [0, 0]], "got 254 at row 0, column 1"),  # a map_server image's grey levels
        ([[0, 101]], "got 101"),
        ([[-5, 0]], "got -5"),
        ([[0.5, 0.0]], "expected whole numbers"),
    ],
)
def test_cell_values_outside_minus_one_to_100_are_refused(
    values: list[list[float]], says: str
) -> None:
    """They were cast to int8 without a word: 255 became unknown, 200 became -56, 101 counted
    as occupied."""
    with pytest.raises(MapFormatError, match=says):
        OccupancyGrid(np.array(values), 0.05)


def test_a_grid_is_pickled_as_its_cells_and_a_process_reuses_the_one_it_holds() -> None:
    """A worker is sent the trial's map with every trial: the pickle holds the cells, not
    the distance fields derived from them (eight times their size), and a process given the
    same map again gets the grid it already built those layers for."""
    g = random_grid(np.random.default_rng(3), (200, 300))
    asked = (g.distance_to_occupied, g.free_cells, g.distance_to_blocking)  # a filter's layers
    layers = sum(v.nbytes for v in vars(g).values() if isinstance(v, np.ndarray))
    assert layers > sum(a.nbytes for a in asked)
    blob = pickle.dumps(g)
    assert len(blob) < g.data.nbytes + 1024 < layers / 8
    first = pickle.loads(blob)
    assert first is not g and first == g
    assert (first.resolution, first.origin, first.name) == (g.resolution, g.origin, g.name)
    assert "distance_to_occupied" not in vars(first)  # computed where it is needed
    np.testing.assert_array_equal(first.distance_to_occupied, g.distance_to_occupied)
    assert pickle.loads(blob) is first  # the same map again: the grid held, with its layers
    # another map, or the same cells under another name, is a grid of its own
    other = g.with_data(np.where(g.data == FREE, UNKNOWN, g.data))
    assert pickle.loads(pickle.dumps(other)) == other
    renamed = pickle.loads(pickle.dumps(g.with_data(g.data, name="elsewhere")))
    assert renamed.name == "elsewhere" and renamed is not first
    again = pickle.loads(blob)  # the process kept only the last one
    assert again == g and again is not first
    # a copy is the grid itself (it is immutable), and is not kept as an unpickled one
    assert copy.deepcopy(g) is g and copy.copy(g) is g
    assert pickle.loads(blob) is again
