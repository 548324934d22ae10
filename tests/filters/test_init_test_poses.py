"""The same initialisation budget for every filter: ``init_test_poses`` (filters/particles.py
``importance_start``) in MCL, GMCL and KLD-AMCL."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.budget import Budget, BudgetError, use
from ceamcl.errors import ConfigError
from ceamcl.experiments.routes import paper_course
from ceamcl.filters import make_filter, make_sensor
from ceamcl.filters.particles import importance_start
from ceamcl.filters.registry import with_config
from ceamcl.sensors import LaserGeometry
from ceamcl.simulation import get_scenario

BASELINES = ("mcl", "gmcl", "kld-amcl")


def _count(algorithm: str) -> str:
    return "max_particles" if algorithm == "kld-amcl" else "n_particles"


@pytest.mark.parametrize("algorithm", BASELINES)
def test_test_poses_are_counted_and_resampled_to_the_particle_count(algorithm: str) -> None:
    course = paper_course()
    grid = course.grid()
    log = course.scenario(0).simulate(np.random.default_rng(3), grid)
    # KLD-AMCL with the textbook product here: amcl's 1 + sum pz^3 is too flat for one scan
    # to gather particles anywhere (this test is about the start, not the scoring).
    extra = {"scoring": "product"} if algorithm == "kld-amcl" else {}
    config = with_config(algorithm, init_test_poses=1_000_000, init_batch=300_000, **extra)
    f = make_filter(algorithm, grid, np.random.default_rng(4), config=config, n_particles=1000)
    first = f.initialise_global(log.scan(0))
    assert first.likelihood_evaluations == 1_000_000 and first.resampled
    w = f.particle_weights()
    assert w.size == 1000 and np.allclose(w, 1.0 / 1000)
    # The symmetric hall: the first scan cannot tell its four images apart; resampling 10^6
    # weighed test poses puts particles near each, the truth's included (when written: 98 to
    # 392 of 1000). 1000 uniform poses put about 15 within 0.5 m of a pose.
    images = course.images(log.true_poses[0])
    assert images.shape[0] == 4
    poses = f.particles().poses
    for image in images:
        near = np.hypot(poses[:, 0] - image[0], poses[:, 1] - image[1]) < 0.5
        assert near.sum() >= 50, (image, near.sum())


@pytest.mark.parametrize("algorithm", BASELINES)
def test_zero_test_poses_is_the_uniform_start(algorithm: str) -> None:
    sc = get_scenario("office")
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(5), grid)
    f = make_filter(algorithm, grid, np.random.default_rng(6), n_particles=800)
    first = f.initialise_global(log.scan(0))
    # N uniform particles, each weighed once by the first scan (GMCL also evolves them).
    assert first.likelihood_evaluations >= 800
    assert f.particle_weights().size <= 800


def test_batches_do_not_change_the_start() -> None:
    sc = get_scenario("office")
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(7), grid)
    sensor = make_sensor("likelihood-field", grid)
    prepared = sensor.prepare(log.scan(0))
    a, na = importance_start(grid, sensor, prepared, 20_000, 500, np.random.default_rng(8))
    b, nb = importance_start(
        grid, sensor, prepared, 20_000, 500, np.random.default_rng(8), batch=999
    )
    assert na == nb == 20_000
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.loglik, b.loglik)
    assert np.all((a.fitness > 0) & (a.fitness <= 1))


def test_a_scan_without_usable_beams_gives_uniform_particles_and_costs_nothing() -> None:
    grid = get_scenario("office").grid()
    sensor = make_sensor("likelihood-field", grid)
    empty = sensor.prepare(LaserGeometry.covering(np.pi, 7, 8.0).scan(np.full(7, np.nan)))
    ps, n = importance_start(grid, sensor, empty, 10_000, 300, np.random.default_rng(9))
    assert n == 0 and ps.n == 300
    assert np.all(grid.is_free(ps.poses[:, 0], ps.poses[:, 1]))


def test_every_test_pose_impossible_gives_uniform_particles() -> None:
    class Impossible:
        temper = 1.0
        scoring = "product"

        def __init__(self, inner):  # type: ignore[no-untyped-def]
            self.inner = inner

        def prepare(self, scan):  # type: ignore[no-untyped-def]
            return self.inner.prepare(scan)

        def log_likelihood(self, poses, prepared):  # type: ignore[no-untyped-def]
            return np.full(np.asarray(poses).reshape(-1, 3).shape[0], np.nan)

        def max_log_beam_likelihood(self, prepared):  # type: ignore[no-untyped-def]
            return self.inner.max_log_beam_likelihood(prepared)

    sc = get_scenario("office")
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(10), grid)
    sensor = Impossible(make_sensor("likelihood-field", grid))
    prepared = sensor.prepare(log.scan(0))
    ps, n = importance_start(grid, sensor, prepared, 5_000, 200, np.random.default_rng(11))
    assert n == 5_000 and ps.n == 200
    assert np.all(np.isfinite(ps.poses)) and np.all(np.isfinite(ps.weights))


def test_test_poses_are_checked_against_the_memory_budget() -> None:
    sc = get_scenario("office")
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(12), grid)
    sensor = make_sensor("likelihood-field", grid)
    prepared = sensor.prepare(log.scan(0))
    with use(Budget(64 << 20)), pytest.raises(BudgetError, match="init_test_poses"):
        importance_start(grid, sensor, prepared, 10**9, 100, np.random.default_rng(13))


@pytest.mark.parametrize("algorithm", BASELINES)
def test_negative_test_poses_are_refused(algorithm: str) -> None:
    with pytest.raises((ConfigError, ValueError), match="init_test_poses"):
        with_config(algorithm, init_test_poses=-1)


@pytest.mark.parametrize("algorithm", BASELINES)
@pytest.mark.parametrize("with_field", [True, False])
def test_with_the_beam_model_the_field_searches_and_the_beam_model_judges(
    model_evaluations: dict[str, int], algorithm: str, with_field: bool
) -> None:
    """A baseline weighing with the beam model starts as CEAMCL does (docs/baselines.md): the
    likelihood field of the same parameters scores the test poses, the beam model the best 5 %
    of them (at least 2,000), and the particles are resampled from those by the beam model's
    weights; both counts are the start's likelihood evaluations, and the four images are
    still found. ``init_search_with_field=False``: the beam model scores every test pose."""
    from ceamcl.sensors import BeamModel
    from ceamcl.sensors.search import judged_count

    course = paper_course()
    grid = course.grid()
    log = course.scenario(0).simulate(np.random.default_rng(3), grid)
    counts = model_evaluations
    n_test = 100_000
    extra = {"scoring": "product"} if algorithm == "kld-amcl" else {}
    config = with_config(
        algorithm, init_test_poses=n_test, init_search_with_field=with_field, **extra
    )
    f = make_filter(
        algorithm, grid, np.random.default_rng(4), config=config, n_particles=1000, sensor="beam"
    )
    first = f.initialise_global(log.scan(0))
    if with_field:
        k = judged_count(n_test)
        assert k == 5_000 and counts["field"] == n_test
        assert counts["beam"] >= k  # the judged poses (GMCL's evolution scores more)
        assert first.likelihood_evaluations >= n_test + k
    else:
        assert counts["field"] == 0 and counts["beam"] >= n_test
    if algorithm != "gmcl":  # GMCL's evolution moves the particles on after the start
        spent = n_test + judged_count(n_test) if with_field else n_test
        assert first.likelihood_evaluations == spent
        ps = f.particle_set  # type: ignore[attr-defined]
        beam = f.sensor  # type: ignore[attr-defined]
        assert isinstance(beam, BeamModel)
        np.testing.assert_allclose(
            ps.loglik, beam.log_likelihood(ps.poses, beam.prepare(log.scan(0)))
        )
    # each image holds particles (when written: 21-648 of 1000, the same with the beam model
    # scoring every test pose); 1000 uniform poses put about 4 within 0.5 m of a pose
    poses = f.particles().poses
    for image in course.images(log.true_poses[0]):
        near = np.hypot(poses[:, 0] - image[0], poses[:, 1] - image[1]) < 0.5
        assert near.sum() >= 12, (image, near.sum())
