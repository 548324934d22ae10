"""Whole runs of the paper's experiment (section 4) in simulation: CEAMCL on symmetric-hall,
and on marked-hall, where the symmetry breaks at the goal. What the baselines do is measured by
the experiments (docs/experiments.md), not asserted here.

Each run is computed once per module (the cache below) and shared by the tests that check
different claims on it. Seeding: ``SeedSequence(seed).spawn(2)`` gives independent simulator
and filter generators, as in ``test_mcl.py``; the seeds are the first ones, not picked.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray

from ceamcl.experiments.metrics import CONFIDENT_SHARE, image_index, weight_shares
from ceamcl.filters import CEAMCLConfig, make_filter, species_of
from ceamcl.maps.worlds import symmetric_images
from ceamcl.runner import RunResult, run_filter
from ceamcl.sensors.raycast import cast_rays
from ceamcl.sensors.scan import laser_poses
from ceamcl.simulation import SimulatedLog, paper_scenario

# (seed, start room): three runs, three different start rooms.
SYMMETRIC_RUNS = ((0, 0), (1, 1), (2, 2))
MARKED_SEEDS = (0, 1, 2)

Runner = Callable[[str, str, int, int], tuple[SimulatedLog, RunResult]]


def generators(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    sim, filt = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(sim), np.random.default_rng(filt)


@pytest.fixture(scope="module")
def run() -> Runner:
    """``run(algorithm, world, seed, room)``: the log and the run result, computed once."""
    logs: dict[tuple[str, int, int], SimulatedLog] = {}
    results: dict[tuple[str, str, int, int], tuple[SimulatedLog, RunResult]] = {}

    def get(algorithm: str, world: str, seed: int, room: int) -> tuple[SimulatedLog, RunResult]:
        key = (algorithm, world, seed, room)
        if key not in results:
            sc = paper_scenario(room, world)
            grid = sc.grid()
            sim_rng, filter_rng = generators(seed)
            if (world, seed, room) not in logs:
                logs[(world, seed, room)] = sc.simulate(sim_rng, grid)
            log = logs[(world, seed, room)]
            f = make_filter(algorithm, grid, filter_rng)
            results[key] = (log, run_filter(f, log))
        return results[key]

    return get


def images_covered(
    hypotheses: NDArray[np.float64], truth: NDArray[np.float64], min_weight: float = 0.01
) -> int:
    """How many of the four symmetric images of ``truth`` have a hypothesis of weight above
    ``min_weight`` within 0.5 m and 0.3 rad."""
    h = hypotheses[hypotheses[:, 3] > min_weight]
    covered = 0
    for image in symmetric_images(truth):
        dist = np.hypot(h[:, 0] - image[0], h[:, 1] - image[1])
        dth = np.abs(np.angle(np.exp(1j * (h[:, 2] - image[2]))))
        covered += int(np.any((dist < 0.5) & (dth < 0.3)))
    return covered


# ---------------------------------------------------------------- claims 1 and 2 on CEAMCL
@pytest.mark.parametrize(("seed", "room"), SYMMETRIC_RUNS)
def test_ceamcl_keeps_all_four_symmetric_hypotheses(run: Runner, seed: int, room: int) -> None:
    log, r = run("ceamcl", "symmetric-hall", seed, room)
    covered = images_covered(r.hypotheses[-1], log.true_poses[-1])
    print(
        f"seed {seed} room {room}: CEAMCL covers {covered} images at the goal, "
        f"{len(r.hypotheses[-1])} species"
    )
    assert covered == 4


@pytest.mark.parametrize(("seed", "room"), SYMMETRIC_RUNS)
def test_ceamcl_sample_size_falls_as_the_pose_becomes_certain(
    run: Runner, seed: int, room: int
) -> None:
    _, r = run("ceamcl", "symmetric-hall", seed, room)
    sizes = np.array([d.n_particles for d in r.diagnostics])
    initial, final = int(sizes[0]), int(sizes[-1])
    print(
        f"seed {seed} room {room}: samples initial {initial}, peak {sizes.max()}, "
        f"final {final} ({final / initial:.2f} of initial)"
    )
    # Claim 1 (the paper's Fig. 6: ~961 initial samples fall to a few hundred, i.e. to about a
    # third): at the goal, where only the four images remain plausible, the sample size is
    # well below the initial one. 0.6 leaves room for the ambiguous initial phase, but a
    # filter whose sample size did not adapt (ratio ~1) fails it.
    # How often it holds: in a survey of seeds 0-15 with this seeding (room = seed % 4) the
    # ratio was 0.34-0.57 in 14 runs and 0.66 and 0.76 in two (seeds 5 and 13), both runs
    # where three mirror-image species of low fitness were still alive at the goal: every
    # species, however small, brings delta * epsilon = 40 resources (eq. 15), so the total
    # settles near 44 samples per living species. A single run fails with probability ~1/8;
    # the three seeds here are the first three, not picked, and the test is deterministic.
    assert final <= 0.6 * initial


# ---------------------------------------------------------- claim 2: weight, not just presence
@pytest.mark.parametrize(("seed", "room"), SYMMETRIC_RUNS)
def test_ceamcl_holds_weight_at_every_image_and_commits_to_none(
    run: Runner, seed: int, room: int
) -> None:
    """Keeping the four images means holding weight at each, not a token species: at the goal
    every image's hypotheses hold at least 5 % of the weight (an even split is 25 %), and no
    hypothesis holds 90 % (the filter does not commit to one of four poses it cannot tell
    apart). Measured on these runs: 15-33 % at each image, the heaviest 27-33 %."""
    log, r = run("ceamcl", "symmetric-hall", seed, room)
    h = r.hypotheses[-1]
    images = symmetric_images(log.true_poses[-1])
    where = image_index(h, images)
    per_image = [float(h[where == k, 3].sum() / h[:, 3].sum()) for k in range(4)]
    shares = weight_shares(h, images)
    print(
        f"seed {seed} room {room}: weight per image {np.round(per_image, 3)}, spurious "
        f"{shares.spurious:.3f}, heaviest {shares.heaviest:.3f}"
    )
    assert min(per_image) >= 0.05
    assert shares.heaviest < CONFIDENT_SHARE


# ---------------------------------------------------------------- marked-hall
def mark_first_seen(log: SimulatedLog) -> int:
    """First step whose noise-free scan differs between marked-hall and symmetric-hall."""
    laser = log.laser
    lp = laser_poses(log.true_poses, laser.pose)
    m = laser.n_beams
    origins = np.repeat(lp[:, :2], m, axis=0)
    angles = (lp[:, 2:3] + laser.angles[None, :]).reshape(-1)
    ranges = [
        cast_rays(paper_scenario(0, w).grid(), origins, angles, laser.range_max).reshape(-1, m)
        for w in ("marked-hall", "symmetric-hall")
    ]
    seen = np.nonzero(np.any(np.abs(ranges[0] - ranges[1]) > 0.05, axis=1))[0]
    assert seen.size, "the route never sees the mark"
    return int(seen[0])


@pytest.mark.parametrize("seed", MARKED_SEEDS)
def test_ceamcl_localises_once_the_mark_is_seen(run: Runner, seed: int) -> None:
    log, r = run("ceamcl", "marked-hall", seed, 0)
    seen = mark_first_seen(log)
    errors = r.position_errors
    assert errors is not None
    print(
        f"seed {seed}: mark first seen at step {seen} of {len(log)}; final error "
        f"{errors[-1]:.3f} m; images covered just before: "
        f"{images_covered(r.hypotheses[seen - 1], log.true_poses[seen - 1])}"
    )
    # Before the mark, the four images are indistinguishable and all alive.
    assert images_covered(r.hypotheses[seen - 1], log.true_poses[seen - 1]) == 4
    # At the goal the estimate is the truth, and so is the fittest hypothesis (the
    # hypotheses are sorted by fitness).
    assert errors[-1] < 0.3
    best = r.hypotheses[-1][0]
    assert best[4] == r.hypotheses[-1][:, 4].max()
    assert np.hypot(*(best[:2] - log.true_poses[-1, :2])) < 0.3
    assert abs(np.angle(np.exp(1j * (best[2] - log.true_poses[-1, 2])))) < 0.1
    # It also holds the largest share of the samples (weight = share of n x fitness).
    heaviest = r.hypotheses[-1][np.argmax(r.hypotheses[-1][:, 3])]
    assert np.hypot(*(heaviest[:2] - log.true_poses[-1, :2])) < 0.3


# ---------------------------------------------------------------- determinism
def head(log: SimulatedLog, n: int) -> SimulatedLog:
    return SimulatedLog(
        log.times[:n], log.true_poses[:n], log.odometry[:n], log.ranges[:n], log.laser, log.world
    )


@pytest.mark.parametrize(("algorithm", "particles"), [("ceamcl", None), ("gmcl", 2000)])
def test_same_seed_same_run(algorithm: str, particles: int | None) -> None:
    sc = paper_scenario(1)
    grid = sc.grid()
    log = head(sc.simulate(np.random.default_rng(60), grid), 120)
    runs = [
        run_filter(
            make_filter(algorithm, grid, np.random.default_rng(seed), n_particles=particles), log
        )
        for seed in (61, 61, 62)
    ]
    a, b, c = runs
    assert np.array_equal(a.estimates, b.estimates)
    assert np.array_equal(
        [d.n_particles for d in a.diagnostics], [d.n_particles for d in b.diagnostics]
    )
    assert all(np.array_equal(x, y) for x, y in zip(a.hypotheses, b.hypotheses, strict=True))
    assert np.array_equal(a.final_particles.poses, b.final_particles.poses)
    assert np.array_equal(a.final_particles.weights, b.final_particles.weights)
    assert not np.array_equal(a.estimates, c.estimates)  # the seed matters


# ---------------------------------------------------------------- diagnostics
@pytest.mark.parametrize(("seed", "room"), SYMMETRIC_RUNS)
def test_ceamcl_step_diagnostics_are_consistent(run: Runner, seed: int, room: int) -> None:
    log, r = run("ceamcl", "symmetric-hall", seed, room)
    f_cfg = CEAMCLConfig()  # what make_filter("ceamcl", ...) uses
    floor = f_cfg.delta_per_m2 * f_cfg.epsilon_m2
    assert len(r.diagnostics) == len(log)
    for k, d in enumerate(r.diagnostics):
        assert d.step == k and not d.reinitialised
        assert species_of(d), f"step {k}: no species"
        ids = [s.species_id for s in species_of(d)]
        assert len(set(ids)) == len(ids)
        assert d.n_particles == sum(s.n for s in species_of(d))
        for s in species_of(d):
            assert s.n >= f_cfg.min_species_size or k == 0
            assert np.isfinite(s.dn)
            assert 0.0 < s.fitness <= 1.0
            assert s.area_m2 >= 0.0
            assert s.resources >= floor
            assert s.capacity > 0.0
        total = sum(s.resources for s in species_of(d))
        assert d.record.columns()["total_resources"] == pytest.approx(total)
        h = r.hypotheses[k]
        assert np.all(np.isfinite(h))
        assert h[:, 3].sum() == pytest.approx(1.0)
    assert np.all(np.isfinite(r.estimates))
    for snap in (r.initial_particles, r.final_particles):
        assert np.all(np.isfinite(snap.poses)) and np.all(np.isfinite(snap.weights))
        assert snap.weights.sum() == pytest.approx(1.0)
