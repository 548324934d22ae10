"""Initial species generation (paper section 3.1): SKIZ, cell weights, and the species that
the first scan of the paper's run produces in the symmetric hall."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from ceamcl import angles
from ceamcl.experiments.metrics import covers, within
from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.ceamcl.initialisation import skiz_partition, top_k_mean_per_cell
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.worlds import symmetric_images
from ceamcl.motion.odometry import OdometryMotionModel
from ceamcl.sensors import LikelihoodFieldModel
from ceamcl.sensors.scan import LaserScan
from ceamcl.simulation import Simulator, paper_scenario
from tests.city_block import seed_distances

#: departure 20 (docs/ceamcl.md), the default from departure 24 to 26: 450 test poses per m^2
#: with uniform headings and ten more around each of the best 1 %
SECOND_ROUND = CEAMCLConfig(test_poses_per_m2=450.0, test_pose_headings=None)
#: the default until departure 24: 1,500 test poses per m^2 in one round
ONE_ROUND = CEAMCLConfig(test_poses_per_m2=1500.0, init_refine_share=0.0, test_pose_headings=None)
#: departure 27, the default: 150 a square metre, their headings drawn from the scan's geometry
GUIDED = CEAMCLConfig()


def _first_scan(room: int, seed: Any) -> tuple[OccupancyGrid, np.ndarray, LaserScan]:
    """The paper route from ``room``: its map, its true start pose and the first scan there,
    simulated with ``seed`` (anything ``np.random.default_rng`` takes)."""
    sc = paper_scenario(room)
    grid = sc.grid()
    start = sc.true_path()[:1]
    log = Simulator(grid, sc.config).run(start, np.random.default_rng(seed))
    return grid, start[0], log.scan(0)


# ---------------------------------------------------------------- SKIZ
def test_skiz_partition_city_block_influence_zones() -> None:
    seeds = np.zeros((9, 9), dtype=np.int32)
    seeds[0:2, 0:2] = 1  # a 2 x 2 block in the top-left corner
    seeds[6, 5:8] = 2  # a bar of three cells, lower right
    # Written by hand: a cell belongs to the seed at the smaller city-block distance; 0 marks
    # ties (equal distance), where either label is right. E.g. row 0, column 6: 5 steps to
    # seed 1's cell (0, 1), 6 steps to seed 2's (6, 6): seed 1; row 2, column 5: 5 to (1, 1),
    # 4 to (6, 5): seed 2; row 6, column 0: 5 to (1, 0) and 5 to (6, 5): a tie.
    expected = np.array(
        [
            [1, 1, 1, 1, 1, 1, 1, 0, 0],
            [1, 1, 1, 1, 1, 1, 0, 2, 2],
            [1, 1, 1, 1, 1, 2, 2, 2, 2],
            [1, 1, 1, 1, 2, 2, 2, 2, 2],
            [1, 1, 1, 2, 2, 2, 2, 2, 2],
            [1, 1, 2, 2, 2, 2, 2, 2, 2],
            [0, 2, 2, 2, 2, 2, 2, 2, 2],
            [0, 2, 2, 2, 2, 2, 2, 2, 2],
            [0, 2, 2, 2, 2, 2, 2, 2, 2],
        ]
    )
    part = skiz_partition(seeds)
    assert part.shape == seeds.shape
    decided = expected > 0
    np.testing.assert_array_equal(part[decided], expected[decided])
    assert set(np.unique(part[~decided])) <= {1, 2}
    # Seeds keep their own labels.
    np.testing.assert_array_equal(part[seeds > 0], seeds[seeds > 0])


def test_skiz_partition_matches_brute_force_on_random_seeds() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        seeds = np.zeros((15, 12), dtype=np.int32)
        for label in range(1, 4):
            y, x = rng.integers(0, 15), rng.integers(0, 12)
            seeds[y : y + rng.integers(1, 3), x : x + rng.integers(1, 3)] = label
        labels, dist = seed_distances(seeds)
        part = skiz_partition(seeds)
        best = dist.min(axis=0)
        # Every cell gets a label at the minimal city-block distance (any one of a tie).
        chosen = np.array(labels)[None, None, :] == part[..., None]
        assert np.all(np.any(chosen & (np.moveaxis(dist, 0, -1) == best[..., None]), axis=-1))


def test_skiz_partition_without_seeds_is_all_zero() -> None:
    np.testing.assert_array_equal(skiz_partition(np.zeros((4, 5), np.int32)), 0)


# ---------------------------------------------------------------- cell weights
@pytest.mark.parametrize("k", [1, 3, 10])
def test_top_k_mean_per_cell_against_brute_force(k: int) -> None:
    rng = np.random.default_rng(11 + k)
    n_cells = 40
    cell = rng.integers(0, n_cells - 5, 500)  # the last 5 cells stay empty
    value = rng.random(500)
    got = top_k_mean_per_cell(cell, value, n_cells, k)
    for c in range(n_cells):
        v = np.sort(value[cell == c])[::-1]
        if v.size == 0:
            assert np.isnan(got[c])
        else:
            assert got[c] == pytest.approx(np.mean(v[:k]), rel=1e-12)
    assert np.all(np.isnan(got[-5:]))


# ---------------------------------------------------------------- the paper's first scan
START_ROOMS = (0, 1, 2, 3)


@pytest.fixture(scope="module")
def initialised() -> dict[int, tuple[CEAMCL, np.ndarray, int]]:
    """CEAMCL after ``initialise_global`` on the first scan of the paper run from each room."""
    out = {}
    for room in START_ROOMS:
        sc = paper_scenario(room)
        grid = sc.grid()
        sim_seed, filter_seed = np.random.SeedSequence(200 + room).spawn(2)
        start = sc.true_path()[:1]
        log = Simulator(grid, sc.config).run(start, np.random.default_rng(sim_seed))
        f = make_filter("ceamcl", grid, np.random.default_rng(filter_seed))
        assert isinstance(f, CEAMCL)
        f.initialise_global(log.scan(0))
        out[room] = (f, start[0], f.particle_set.n)
    return out


@pytest.mark.parametrize("room", START_ROOMS)
def test_initial_species_cover_the_four_symmetric_images(
    initialised: dict[int, tuple[CEAMCL, np.ndarray, int]], room: int
) -> None:
    f, truth, total = initialised[room]
    assert f.initial is not None
    means = np.array([s.mean for s in f.stats.values()])
    sizes = sorted(s.n for s in f.stats.values())
    print(
        f"room {room}: {total} samples (N0 = {f.initial.n0}), {f.initial.n_species} regions, "
        f"{len(f.stats)} species, sizes {sizes}"
    )
    for image in symmetric_images(truth):
        dist = np.hypot(means[:, 0] - image[0], means[:, 1] - image[1])
        dth = np.abs(np.angle(np.exp(1j * (means[:, 2] - image[2]))))
        # A species at the image's place *and* heading (a species at the right place but
        # facing another way is not this image).
        assert np.any((dist < 0.5) & (dth < 0.3)), f"no species near image {image}"
    # The paper's Fig. 2: 537 and 961 initial samples for 4 and 8 species.
    assert 300 <= total <= 2500
    assert total == f.particle_set.n == sum(s.n for s in f.stats.values())


@pytest.mark.parametrize("room", START_ROOMS)
def test_initial_sizes_follow_eq5_and_eq6(
    initialised: dict[int, tuple[CEAMCL, np.ndarray, int]], room: int
) -> None:
    f, _, _ = initialised[room]
    init = f.initial
    assert init is not None
    cfg = f.config
    # eq. 5: N0 = eta |V| / mean weight of V.
    assert init.n0 == round(cfg.eta * init.v_size / init.v_mean_weight)
    assert 0.85 < init.v_mean_weight <= 1.0  # V holds the cells scaled above mu = 0.85
    # eq. 6: part i gets N0 wbar(i) / sum wbar(k); each share is rounded (and floored at the
    # minimum species size), so the total is N0 up to half a sample per part.
    counts = np.bincount(init.labels, minlength=init.n_species)
    weights = np.array(
        [init.cell_weight[init.seeds == s + 1].mean() for s in range(init.n_species)]
    )
    expected = np.maximum(np.round(init.n0 * weights / weights.sum()), cfg.min_species_size)
    np.testing.assert_array_equal(counts, expected)
    assert abs(int(counts.sum()) - init.n0) <= init.n_species
    # Every sample was taken from the test poses of its own part of the SKIZ partition.
    part = init.partition.reshape(-1)[init.cells.index(init.poses[:, :2])]
    np.testing.assert_array_equal(part, init.labels + 1)


def test_public_initialisation_phases_give_the_filters_species() -> None:
    """``ceamcl bench`` times section 3.1 phase by phase with the public functions; with the
    same generator they give exactly the species ``initialise_global`` starts from."""
    from ceamcl.filters.ceamcl.initialisation import (
        generate_initial_species,
        heading_proposal,
        sample_test_poses,
        score_test_poses,
    )

    sc = paper_scenario(0)
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(3), grid)
    # exactly n_test test poses, no second round and no polishing: the phases below are
    # section 3.1 alone (with the default's headings drawn from the scan, departure 27)
    cfg = CEAMCLConfig(
        n_test=20_000,
        test_batch=7_000,
        test_poses_per_m2=None,
        init_refine_share=0.0,
        init_polish_rounds=0,
    )
    f = CEAMCL(
        grid, OdometryMotionModel(), LikelihoodFieldModel(grid), cfg, rng=np.random.default_rng(4)
    )
    f.initialise_global(log.scan(0))
    assert f.initial is not None
    sensor = LikelihoodFieldModel(grid)
    init = cfg.initialisation
    assert init.headings is not None
    density = heading_proposal(grid, log.scan(0), init)
    test = sample_test_poses(grid, init, np.random.default_rng(4), density)
    ll, fit, evaluations = score_test_poses(test, sensor, sensor.prepare(log.scan(0)), init)
    species = generate_initial_species(grid, test, ll, fit, init)
    assert evaluations == cfg.n_test
    np.testing.assert_array_equal(species.poses, f.initial.poses)
    np.testing.assert_array_equal(species.labels, f.initial.labels)


def test_test_poses_follow_the_free_area_up_to_n_test() -> None:
    """``test_poses_per_m2`` of free space, at most ``n_test``: with one round of 1,500 a
    square metre the hall (213 m^2 free) gets about 320,000, a building of 5,000 m^2 the
    paper's 10^6, and ``None`` always ``n_test``; with the second round (departure 20, the
    default) both rounds together stay within ``n_test``."""
    from ceamcl.filters.ceamcl.initialisation import sample_test_poses

    init = ONE_ROUND.initialisation
    assert init.test_pose_count(213.0) == 319_500
    assert init.test_pose_count(5_000.0) == init.n_test == 1_000_000
    assert init.test_pose_count(0.0) == 1
    assert init.refine_count(319_500) == 0
    fixed = CEAMCLConfig(test_poses_per_m2=None, init_refine_share=0.0).initialisation
    assert fixed.test_pose_count(213.0) == fixed.n_test
    grid = paper_scenario(0).grid()
    poses = sample_test_poses(grid, init, np.random.default_rng(0))
    assert poses.shape == (round(1500.0 * grid.free_area_m2), 3)
    assert GUIDED.initialisation.test_pose_count(213.0) == 31_950
    two = SECOND_ROUND.initialisation
    assert two.test_pose_count(213.0) == 95_850
    first = two.test_pose_count(5_000.0)
    assert first == int(two.n_test / (1 + two.refine_share * two.refine_per_pose))
    assert first + two.refine_count(first) * two.refine_per_pose <= two.n_test


def test_second_round_draws_around_the_best_test_poses_in_free_space() -> None:
    """The second round (departure 20) draws ``refine_per_pose`` poses around each of the best
    ``refine_share`` of the first round, keeps those in free space, reproduces with the seed,
    and puts several times more test poses near each of the four images of the true pose
    than the first round's uniform draws, nearer their peak, for a tenth of the evaluations."""
    from ceamcl.filters.ceamcl.initialisation import (
        refine_test_poses,
        sample_test_poses,
        score_test_poses,
    )

    grid, truth, scan = _first_scan(2, 8)
    sensor = LikelihoodFieldModel(grid)
    prepared = sensor.prepare(scan)
    init = SECOND_ROUND.initialisation
    test = sample_test_poses(grid, init, np.random.default_rng(9))
    ll, _, _ = score_test_poses(test, sensor, prepared, init)
    more = refine_test_poses(grid, test, ll, init, np.random.default_rng(10))
    again = refine_test_poses(grid, test, ll, init, np.random.default_rng(10))
    np.testing.assert_array_equal(more, again)
    k = init.refine_count(test.shape[0])
    assert k == int(np.ceil(init.refine_share * test.shape[0]))
    assert 0.9 * k * init.refine_per_pose <= more.shape[0] <= k * init.refine_per_pose
    assert np.all(grid.is_free(more[:, 0], more[:, 1]))
    assert np.all(np.abs(more[:, 2]) <= np.pi)
    # every drawn pose lies within 5 sigma of one of the best first-round poses
    best = test[np.argsort(-ll)[:k]]
    sxy, sth = init.refine_sigma
    dxy = np.hypot(more[:, None, 0] - best[None, :, 0], more[:, None, 1] - best[None, :, 1])
    dth = np.abs(angles.diff(more[:, None, 2], best[None, :, 2]))
    assert np.all(((dxy <= 5 * sxy * np.sqrt(2)) & (dth <= 5 * sth)).any(axis=1))
    more_ll, _, _ = score_test_poses(more, sensor, prepared, init)
    for image in symmetric_images(truth):
        near = [within(p, image, 0.3, 0.15) for p in (test, more)]
        best_first = np.max(ll[near[0]], initial=-np.inf)
        best_second = np.max(more_ll[near[1]], initial=-np.inf)
        print(
            f"image {np.round(image, 2)}: test poses within 0.3 m and 0.15 rad "
            f"{near[0].sum()} -> +{near[1].sum()}, best log-likelihood there "
            f"{best_first:.1f} -> {best_second:.1f}"
        )
        assert near[1].sum() >= 3 * max(1, near[0].sum())
        assert best_second > best_first


@pytest.mark.parametrize(
    ("name", "config", "share"),
    [("second round", SECOND_ROUND, 0.4), ("guided", GUIDED, 0.15)],
)
@pytest.mark.parametrize("room", START_ROOMS)
def test_fewer_test_poses_find_the_four_images(
    room: int, name: str, config: CEAMCLConfig, share: float
) -> None:
    """The initial species cover the four images of the true pose as with one round of 1,500
    uniform test poses a square metre, for a share of its evaluations (both rounds and the
    polish counted): departure 20's second round over 450 uniform test poses a square metre
    (the default from departure 24 to 26) for under 0.4 of them, departure 27's 150 a square
    metre with headings drawn from the scan's geometry (the default) for under 0.15 (when
    written: 36,400-36,700 against 321,000, about a ninth)."""
    sim_seed, filter_seed = np.random.SeedSequence(300 + room).spawn(2)
    grid, truth, scan = _first_scan(room, sim_seed)
    spent = {}
    for label, cfg in (("one round", ONE_ROUND), (name, config)):
        f = CEAMCL(
            grid,
            OdometryMotionModel(),
            LikelihoodFieldModel(grid),
            cfg,
            rng=np.random.default_rng(filter_seed),
        )
        spent[label] = f.initialise_global(scan).likelihood_evaluations
        means = np.array([s.mean for s in f.stats.values()])
        found = covers(means, symmetric_images(truth)).any(axis=0)
        assert found.all(), f"{label}: no species near images {np.flatnonzero(~found)}"
    print(f"room {room}: evaluations {spent}")
    assert spent[name] < share * spent["one round"]


def test_polish_moves_initial_samples_uphill_and_nearer_the_pose() -> None:
    """The greedy moves after section 3.1 never lower a sample's likelihood, score what they
    keep exactly, count one evaluation per sample and round, and bring samples scattered
    around the true pose nearer to it; with no rounds nothing moves and nothing is spent."""
    from ceamcl.filters.ceamcl.initialisation import polish

    grid, truth, scan = _first_scan(1, 5)
    sensor = LikelihoodFieldModel(grid)
    prepared = sensor.prepare(scan)
    rng = np.random.default_rng(6)
    poses = truth + rng.normal(scale=[0.15, 0.15, 0.08], size=(300, 3))
    ll0 = sensor.log_likelihood(poses, prepared)
    init = CEAMCLConfig().initialisation
    moved, ll, spent = polish(poses, ll0, sensor, prepared, init, rng)
    assert spent == init.polish_rounds * poses.shape[0] > 0
    assert np.all(ll >= ll0)
    np.testing.assert_allclose(ll, sensor.log_likelihood(moved, prepared))
    stayed = ll == ll0
    np.testing.assert_array_equal(moved[stayed], poses[stayed])
    assert np.count_nonzero(~stayed) > poses.shape[0] // 4
    before = np.hypot(*(poses[:, :2] - truth[:2]).T)
    after = np.hypot(*(moved[:, :2] - truth[:2]).T)
    print(f"median distance to the pose {np.median(before):.3f} -> {np.median(after):.3f} m")
    assert np.median(after) < np.median(before)
    none = CEAMCLConfig(init_polish_rounds=0).initialisation
    same, ll_same, zero = polish(poses, ll0, sensor, prepared, none, rng)
    assert zero == 0 and same is poses and ll_same is ll0


def test_a_scan_without_usable_beams_spreads_the_species_without_a_heading_density(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Every reading at the laser's maximum range (no beam the sensor model uses): the
    species spread uniformly over free space, so the heading density is not worked out
    for nothing; it is where the scan has beams."""
    from ceamcl.filters.ceamcl import filter as ceamcl_filter

    seen: list[object] = []
    real = ceamcl_filter.heading_proposal

    def recording(grid: Any, scan: Any, settings: Any) -> Any:
        seen.append(scan)
        return real(grid, scan, settings)

    monkeypatch.setattr(ceamcl_filter, "heading_proposal", recording)
    sc = paper_scenario()
    grid = sc.grid()
    f = make_filter("ceamcl", grid, np.random.default_rng(0))
    assert isinstance(f, CEAMCL)
    log = Simulator(grid).run(np.array([[3.75, 3.75, np.pi / 2]]), np.random.default_rng(1))
    scan = log.scan(0)
    blind = replace(scan, ranges=np.full_like(scan.ranges, scan.range_max))
    f.initialise_global(blind)
    assert seen == [None]
    assert f.particle_set.n > 0 and np.all(np.isfinite(f.particle_set.poses))
    f.initialise_global(scan)
    assert seen[-1] is scan


# ---------------------------------------------------------------- departure 29
def test_the_search_model_is_the_filters_own_unless_it_casts_rays() -> None:
    from ceamcl.sensors import BeamModel
    from ceamcl.sensors.base import with_settings
    from ceamcl.sensors.search import search_model

    grid = paper_scenario().grid()
    field = LikelihoodFieldModel(grid)
    assert search_model(field) is field
    beam = with_settings(BeamModel(grid), {"max_beams": 30, "temper": 0.1, "sigma_hit_m": 0.15})
    search = search_model(beam)
    assert isinstance(search, LikelihoodFieldModel) and search.grid is grid
    c = search.config
    assert (c.max_beams, c.temper, c.sigma_hit_m, c.scoring) == (30, 0.1, 0.15, "product")


@pytest.mark.parametrize("room", [0, 2])
def test_a_beam_model_filter_searches_with_the_field_and_judges_with_its_own(
    model_evaluations: dict[str, int], room: int
) -> None:
    """The global search of a filter weighing with the beam model: the likelihood field
    scores the test poses, the beam model only the best of them (5 %, the second round and
    the polish), and every initial sample carries the beam model's log-likelihood; the four
    images are still found. With ``search_with_field=False`` the beam model scores them all."""
    from ceamcl.sensors.search import judged_count

    grid, truth, scan = _first_scan(room, 5)
    counts = model_evaluations
    f = make_filter("ceamcl", grid, np.random.default_rng(3), sensor="beam")
    assert isinstance(f, CEAMCL)
    f.initialise_global(scan)
    n_test = f.config.initialisation.test_pose_count(grid.free_area_m2)
    judged = judged_count(n_test)
    assert counts["field"] >= n_test  # every test pose, by the field
    assert judged <= counts["beam"] < 0.25 * counts["field"]  # the best, by the beam model
    searched = counts["beam"]
    prepared = f.sensor.prepare(scan)
    np.testing.assert_allclose(
        f.particle_set.loglik, f.sensor.log_likelihood(f.particle_set.poses, prepared)
    )
    means = np.array([s.mean for s in f.stats.values()])
    for image in symmetric_images(truth):
        dist = np.hypot(means[:, 0] - image[0], means[:, 1] - image[1])
        dth = np.abs(np.angle(np.exp(1j * (means[:, 2] - image[2]))))
        assert np.any((dist < 0.5) & (dth < 0.3)), f"no species near image {image}"
    counts.update(beam=0, field=0)
    g = make_filter(
        "ceamcl",
        grid,
        np.random.default_rng(3),
        sensor="beam",
        config=replace(CEAMCLConfig(), search_with_field=False),
    )
    g.initialise_global(scan)
    assert counts["field"] == 0 and counts["beam"] >= n_test > 4 * searched
