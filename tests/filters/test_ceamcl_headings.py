"""Test poses' headings from the scan's geometry (filters/ceamcl/headings.py, docs/ceamcl.md
departure 27): the map's and the scan's surface normals, their correlation, and the first
round of test poses drawn from it."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.experiments.routes import paper_course
from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl.config import CEAMCLConfig
from ceamcl.filters.ceamcl.initialisation import heading_proposal, sample_test_poses
from ceamcl.filters.headings import (
    HeadingPrior,
    _map_normals,
    _map_normals_reference,
    facing_length,
    facing_length_reference,
    heading_density,
    map_normal_histogram,
    sample_headings,
    scan_normal_histogram,
)
from ceamcl.filters.registry import with_config
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.scan import LaserScan
from ceamcl.simulation import get_scenario
from tests.box_room import BOX, box_ranges

PRIOR = HeadingPrior()


def _bin_of(angle: float) -> int:
    return int(np.floor(np.mod(angle, 2 * np.pi) / (2 * np.pi) * PRIOR.bins)) % PRIOR.bins


def _mass_near(hist: np.ndarray, angle: float, deg: float = 6.0) -> float:
    w = round(deg / 360 * PRIOR.bins)
    b = _bin_of(angle)
    return float(sum(hist[(b + o) % PRIOR.bins] for o in range(-w, w + 1)))


def _box_grid(res: float = 0.05) -> OccupancyGrid:
    x0, x1, y0, y1 = BOX
    nx, ny = round((x1 - x0) / res) + 2, round((y1 - y0) / res) + 2
    data = np.zeros((ny, nx), dtype=np.int8)
    data[0, :] = data[-1, :] = 100
    data[:, 0] = data[:, -1] = 100
    return OccupancyGrid(data, res, (x0 - res, y0 - res, 0.0))


def test_the_maps_normals_point_from_each_wall_into_the_room() -> None:
    hist = map_normal_histogram(_box_grid(), PRIOR)
    total = hist.sum()
    # the four walls face +x (the wall at x_min), -x, +y and -y; their lengths 3, 3, 4, 4 m
    near = {a: _mass_near(hist, a) / total for a in (0.0, np.pi, np.pi / 2, -np.pi / 2)}
    assert sum(near.values()) > 0.85, near  # the rest: the four corners
    assert near[np.pi / 2] > near[0.0] and near[-np.pi / 2] > near[np.pi]
    assert _mass_near(hist, np.pi / 4) / total < 0.05


def test_the_scans_normals_point_back_at_the_laser() -> None:
    ranges = box_ranges(1.0, 0.0, beams=361)
    scan = LaserScan(np.asarray(ranges), -np.pi / 2, np.pi / 360, 0.02, 30.0)
    hist = scan_normal_histogram(scan, PRIOR)
    total = hist.sum()
    # facing +x: the wall ahead faces back (pi), the walls left and right face -y and +y;
    # the wall behind is out of a 180-degree scan's view
    ahead, left, right = (_mass_near(hist, a) / total for a in (np.pi, -np.pi / 2, np.pi / 2))
    assert ahead + left + right > 0.9
    assert min(ahead, left, right) > 0.15
    assert _mass_near(hist, 0.0) / total < 0.02


def test_the_surfaces_facing_along_the_track_are_the_wall_ahead() -> None:
    """Departure 44 counts the metres of surface that face along the robot's axis: in the box,
    facing +x from x = 1 m, the wall ahead (3 m long, all in view) faces back at the laser and
    the side walls face across; a corridor far longer than the laser's reach shows only side
    walls."""
    ranges = box_ranges(1.0, 0.0, beams=361)
    scan = LaserScan(np.asarray(ranges), -np.pi / 2, np.pi / 360, 0.02, 30.0)
    ahead = facing_length(scan, PRIOR, np.pi / 4)
    assert 2.5 < ahead < 3.1  # the wall ahead, less a chord at its corners
    # the same room with the laser's reach short of the wall ahead: side walls only
    short = LaserScan(np.minimum(np.asarray(ranges), 1.9), -np.pi / 2, np.pi / 360, 0.02, 1.9)
    assert facing_length(short, PRIOR, np.pi / 4) < 0.05
    # nothing to face: a scan without end points
    empty = LaserScan(np.full(361, 30.0), -np.pi / 2, np.pi / 360, 0.02, 30.0)
    assert facing_length(empty, PRIOR, np.pi / 4) == 0.0


def test_the_compiled_facing_length_equals_its_reference_on_simulated_and_noisy_scans() -> None:
    sc = get_scenario("office")
    log = sc.simulate(np.random.default_rng(3))
    rng = np.random.default_rng(4)
    for k in range(0, len(log), 25):
        scan = log.scan(k)
        ranges = scan.ranges.copy()
        ranges[rng.random(ranges.size) < 0.05] = np.nan  # gaps and invalid readings too
        ranges[rng.random(ranges.size) < 0.05] = np.inf
        noisy = LaserScan(ranges, scan.angle_min, scan.angle_increment, scan.range_min, 8.0)
        for s in (scan, noisy):
            for half in (np.pi / 4, np.pi / 8):
                got = facing_length(s, PRIOR, half)
                assert got == pytest.approx(facing_length_reference(s, PRIOR, half), abs=1e-9)


def test_the_density_peaks_at_the_true_heading_and_its_quarter_turns_in_a_box() -> None:
    grid = _box_grid()
    maph = map_normal_histogram(grid, PRIOR)
    ranges = box_ranges(1.0, 0.3, beams=361)
    scan = LaserScan(np.asarray(ranges), -np.pi / 2, np.pi / 360, 0.02, 30.0)
    d = heading_density(maph, scan_normal_histogram(scan, PRIOR), PRIOR)
    assert d.sum() == pytest.approx(1.0)
    assert d.min() >= PRIOR.uniform_share / PRIOR.bins - 1e-12
    ratio = d * PRIOR.bins
    # the true heading 0 is among the peaks (a box cannot tell its quarter turns apart)
    assert ratio[_bin_of(0.0)] > 5 * ratio[_bin_of(np.pi / 4)]
    assert ratio[_bin_of(0.0)] > 3.0


def test_the_density_favours_the_true_heading_in_a_simulated_office() -> None:
    sc = get_scenario("office")
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(11), grid)
    maph = map_normal_histogram(grid, PRIOR)
    ratios = []
    for k in range(0, len(log), max(1, len(log) // 40)):
        d = heading_density(maph, scan_normal_histogram(log.scan(k), PRIOR), PRIOR)
        ratios.append(d[_bin_of(float(log.true_poses[k][2]))] * PRIOR.bins)
    ratios_a = np.asarray(ratios)
    # uniform headings give 1 everywhere
    assert np.median(ratios_a) > 2.0, ratios_a
    assert np.mean(ratios_a > 1.0) >= 0.8, ratios_a


def test_a_scan_without_surfaces_leaves_the_headings_uniform() -> None:
    maph = map_normal_histogram(_box_grid(), PRIOR)
    blank = LaserScan(np.full(181, 30.0), -np.pi / 2, np.pi / 180, 0.02, 30.0)
    d = heading_density(maph, scan_normal_histogram(blank, PRIOR), PRIOR)
    assert np.allclose(d, 1.0 / PRIOR.bins)
    nan_scan = LaserScan(np.full(181, np.nan), -np.pi / 2, np.pi / 180, 0.02, 30.0)
    assert np.allclose(heading_density(maph, scan_normal_histogram(nan_scan, PRIOR), PRIOR), d)
    # uniform_share=1: the paper's uniform headings whatever the scan
    ranges = np.asarray(box_ranges(1.0, 0.0, beams=361))
    scan = LaserScan(ranges, -np.pi / 2, np.pi / 360, 0.02, 30.0)
    flat = HeadingPrior(uniform_share=1.0)
    assert np.allclose(heading_density(maph, scan_normal_histogram(scan, flat), flat), d)


def test_headings_are_drawn_from_the_density_and_reproduce_from_a_seed() -> None:
    d = np.zeros(PRIOR.bins)
    d[_bin_of(1.0)] = 1.0
    a = sample_headings(d, 1000, np.random.default_rng(3))
    assert np.array_equal(a, sample_headings(d, 1000, np.random.default_rng(3)))
    assert np.all((a >= -np.pi) & (a < np.pi))
    assert np.all(np.abs(a - 1.0) < 2 * np.pi / PRIOR.bins)


def test_the_first_round_puts_more_test_poses_near_the_true_heading() -> None:
    sc = get_scenario("office")
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(12), grid)
    truth = float(log.true_poses[0][2])
    uniform = CEAMCLConfig(test_pose_headings=None).initialisation  # the paper's
    guided = CEAMCLConfig().initialisation  # the default since departure 27
    assert guided.headings == PRIOR
    # a recovery's search draws them so too (departure 28), or uniformly when asked
    assert CEAMCLConfig().recovery_initialisation.headings == PRIOR
    assert CEAMCLConfig(recovery_test_pose_headings=False).recovery_initialisation.headings is None
    density = heading_proposal(grid, log.scan(0), guided)
    assert density is not None
    assert heading_proposal(grid, log.scan(0), uniform) is None
    assert heading_proposal(grid, None, guided) is None

    def near_truth(poses: np.ndarray) -> float:
        err = np.abs(np.angle(np.exp(1j * (poses[:, 2] - truth))))
        return float(np.mean(err < np.radians(5)))

    plain = sample_test_poses(grid, uniform, np.random.default_rng(1))
    drawn = sample_test_poses(grid, guided, np.random.default_rng(1), density)
    assert plain.shape == drawn.shape
    assert np.array_equal(plain[:, :2], drawn[:, :2])  # the positions are section 3.1's
    assert near_truth(drawn) > 2.0 * near_truth(plain)


def test_a_baselines_guided_start_keeps_every_image_of_the_hall_with_fewer_test_poses() -> None:
    """``init_headings`` in MCL's importance start: the headings drawn from the scan's
    geometry, each weight divided by its density; the particles still gather at each of
    the hall's four images, and more of them point the right way than from uniform
    headings with the same budget."""
    course = paper_course()
    grid = course.grid()
    log = course.scenario(0).simulate(np.random.default_rng(3), grid)
    images = course.images(log.true_poses[0])

    def start(headings: HeadingPrior | None) -> np.ndarray:
        cfg = with_config("mcl", init_test_poses=100_000, init_headings=headings)
        f = make_filter("mcl", grid, np.random.default_rng(4), config=cfg, n_particles=1000)
        first = f.initialise_global(log.scan(0))
        assert first.likelihood_evaluations == 100_000
        return f.particles().poses

    def at_images(poses: np.ndarray) -> list[int]:
        counts = []
        for image in images:
            near = np.hypot(poses[:, 0] - image[0], poses[:, 1] - image[1]) < 0.5
            turn = np.abs(np.angle(np.exp(1j * (poses[:, 2] - image[2])))) < 0.2
            counts.append(int(np.sum(near & turn)))
        return counts

    guided, plain = at_images(start(PRIOR)), at_images(start(None))
    # when written: guided 126, 136, 184, 27; uniform 12, 172, 139, 14 (of 1000)
    assert min(guided) >= 20, guided
    assert min(guided) > min(plain) and sum(guided) > sum(plain), (guided, plain)


def test_the_maps_normals_are_computed_once_per_map_and_kept_read_only() -> None:
    grid = _box_grid()
    first = map_normal_histogram(grid, PRIOR)
    assert map_normal_histogram(grid, PRIOR) is first
    assert not first.flags.writeable
    # another histogram setting is another entry; an equal but separate grid computes its own
    other = map_normal_histogram(grid, HeadingPrior(bins=180))
    assert other.size == 180
    again = map_normal_histogram(_box_grid(), PRIOR)
    assert again is not first and np.array_equal(again, first)


def test_a_rotated_maps_normals_turn_with_its_origin() -> None:
    """A map whose origin is turned by a yaw: its normals (world frame) turn by that yaw."""
    plain = _box_grid()
    turned = OccupancyGrid(plain.data, plain.resolution, (0.0, 0.0, np.pi / 6))
    a, b = map_normal_histogram(plain, PRIOR), map_normal_histogram(turned, PRIOR)
    shift = round(PRIOR.bins / 12)  # 30 degrees
    corr = [float(np.dot(np.roll(a, k), b)) for k in range(PRIOR.bins)]
    assert int(np.argmax(corr)) == shift
    assert a.sum() == pytest.approx(b.sum())


def test_the_maps_normals_tile_by_tile_equal_the_filters_over_the_whole_map() -> None:
    """The normals are smoothed and differentiated only in tiles around the boundary cells:
    the histogram is the one SciPy's filters over the whole map give, bin for bin, on the
    paper's hall, on maps with walls across tile edges and along the map's own edge, and on
    clutter scattered over a map several tiles wide."""
    grids = [get_scenario("paper").grid(), get_scenario("office").grid(), _box_grid()]
    rng = np.random.default_rng(46)
    for trial in range(4):
        h, w = 150 + 37 * trial, 210 - 23 * trial
        data = np.full((h, w), -1, dtype=np.int8)
        data[5 : h - 5, 5 : w - 5] = 0
        data[rng.random((h, w)) < 0.02 * (trial + 1)] = 100
        data[:, 63:66] = 100  # a wall along a tile edge
        data[0, :] = 100  # walls on the map's own edge
        data[:, -1] = 100
        grids.append(OccupancyGrid(data, 0.05, (0.0, 0.0, 0.3 * trial)))
    for grid in grids:
        for prior in (PRIOR, HeadingPrior(bins=180)):
            got = _map_normals(grid, prior)
            want = _map_normals_reference(grid, prior)
            assert got.sum() > 0
            assert np.array_equal(got, want)
