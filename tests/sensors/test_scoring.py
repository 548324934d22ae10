"""ROS amcl's scoring, ``log(1 + sum_k pz_k^3)``, in both laser models (sensors/scoring.py)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from ceamcl.maps.grid import FREE, OCCUPIED, OccupancyGrid
from ceamcl.maps.worlds import get_world
from ceamcl.sensors import (
    BeamModel,
    BeamModelConfig,
    LaserGeometry,
    LikelihoodFieldConfig,
    LikelihoodFieldModel,
    fitness,
)
from ceamcl.sensors.tempering import resolve_temper
from ceamcl.simulation import SimulatedLog, office_scenario

Model = LikelihoodFieldModel | BeamModel
ROS: dict[str, Callable[[OccupancyGrid], Model]] = {
    "likelihood-field": lambda g: LikelihoodFieldModel(g, LikelihoodFieldConfig(scoring="ros")),
    "beam": lambda g: BeamModel(g, BeamModelConfig(scoring="ros")),
}


@pytest.fixture(scope="module")
def office_log() -> SimulatedLog:
    return office_scenario().simulate(np.random.default_rng(2))


def corridor_grid() -> OccupancyGrid:
    """A wall 2 m ahead of the origin pose: x in [2.0, 2.1), all y; 0.05 m cells."""
    data = np.full((80, 80), FREE, dtype=np.int8)
    data[:, 40:42] = OCCUPIED
    return OccupancyGrid(data, 0.05, (0.0, -2.0, 0.0))


@pytest.mark.parametrize("model_name", list(ROS))
def test_compiled_ros_score_equals_reference(model_name: str, office_log: SimulatedLog) -> None:
    rng = np.random.default_rng(31)
    office = get_world("small-office")
    moved = OccupancyGrid(office.data, office.resolution, (3.0, -1.0, 0.8), name="moved")
    for grid in (office, moved):
        model = ROS[model_name](grid)
        poses = grid.sample_free_poses(300, rng)
        for k in (0, len(office_log) // 2):
            prepared = model.prepare(office_log.scan(k))
            fast = model.log_likelihood(poses, prepared)
            ref = model.log_likelihood_reference(poses, prepared)
            np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=0)
            assert fast.std() > 0.1  # the poses really score differently
            # 1 + sum of cubes of pz <= 1: between log 1 and log(1 + n_beams).
            assert np.all((fast >= 0.0) & (fast <= math.log1p(prepared.n_beams)))


def test_likelihood_field_ros_score_by_hand() -> None:
    # amcl: pz = z_hit exp(-d^2 / (2 sigma^2)) + z_rand / range_max (no 1/(sqrt(2 pi) sigma)),
    # p = 1 + sum pz^3.
    grid = corridor_grid()
    cfg = LikelihoodFieldConfig(max_beams=10, scoring="ros")
    model = LikelihoodFieldModel(grid, cfg)
    geom = LaserGeometry.covering(0.2, 2, 8.0)
    pose = np.array([[0.0, 0.025, 0.0]])
    prepared = model.prepare(geom.scan([2.01, 3.0]))
    assert prepared.n_beams == 2
    # each range looked up half a cell farther (the field's end-point offset)
    read = np.array([2.01, 3.0]) + model.end_point_offset_m
    assert model.end_point_offset_m == pytest.approx(0.025)
    ends = pose[0, :2] + read[:, None] * np.column_stack(
        [np.cos(prepared.bearings), np.sin(prepared.bearings)]
    )
    ix, iy = grid.world_to_cell(ends[:, 0], ends[:, 1])
    inside = grid.in_bounds(ix, iy)
    d = np.where(inside, grid.distance_to_occupied[iy.clip(0, 79), ix.clip(0, 79)], 2.0)
    d = np.minimum(d, cfg.max_occ_dist_m)
    pz = cfg.z_hit * np.exp(-d * d / (2 * cfg.sigma_hit_m**2)) + cfg.z_rand / 8.0
    want = math.log(1.0 + float(np.sum(pz**3)))
    assert model.log_likelihood(pose, prepared)[0] == pytest.approx(want, rel=1e-12)


def test_beam_model_ros_score_by_hand() -> None:
    grid = corridor_grid()
    cfg = BeamModelConfig(max_beams=10, scoring="ros")
    model = BeamModel(grid, cfg)
    pose = np.array([[0.0, 0.025, 0.0]])  # expected range straight ahead: 2.0 m
    geom = LaserGeometry.covering(0.0, 1, 8.0)
    for r, is_max in [(2.01, False), (1.97, False), (1.2, False), (8.0, True)]:
        z = r - 2.0
        pz = cfg.z_hit * math.exp(-z * z / (2 * cfg.sigma_hit_m**2))
        if z < 0:
            pz += cfg.z_short * cfg.lambda_short * math.exp(-cfg.lambda_short * r)
        pz += cfg.z_max if is_max else cfg.z_rand / 8.0
        got = model.log_likelihood(pose, model.prepare(geom.scan([r])))[0]
        assert got == pytest.approx(math.log(1.0 + pz**3), abs=1e-7), (r, got)


@pytest.mark.parametrize("model_name", list(ROS))
def test_ros_score_peaks_at_the_truth_and_fitness_is_in_unit_interval(
    model_name: str, office_log: SimulatedLog
) -> None:
    grid = get_world(office_log.world)
    model = ROS[model_name](grid)
    rng = np.random.default_rng(32)
    for k in np.linspace(0, len(office_log) - 1, 5).astype(int):
        prepared = model.prepare(office_log.scan(k))
        poses = np.vstack([office_log.true_poses[k], grid.sample_free_poses(500, rng)])
        ll = model.log_likelihood(poses, prepared)
        assert ll[0] > np.quantile(ll[1:], 0.99)
        fit = fitness(ll, prepared, model)
        assert np.all((fit > 0.0) & (fit <= 1.0))
        assert fit[0] > 0.8  # the power mean of order 3 of pz / pz_max at the truth
        assert np.median(fit[1:]) < fit[0]


def test_ros_fitness_is_one_for_a_perfect_match() -> None:
    model = LikelihoodFieldModel(get_world("small-office"), LikelihoodFieldConfig(scoring="ros"))
    prepared = model.prepare(LaserGeometry.covering(0.5, 3, 8.0).scan([1.0, 1.5, 2.0]))
    best = math.exp(model.max_log_beam_likelihood(prepared))
    perfect = np.array([math.log1p(3 * best**3)])
    assert fitness(perfect, prepared, model)[0] == pytest.approx(1.0)
    assert fitness(np.array([-np.inf]), prepared, model)[0] == 0.0


@pytest.mark.parametrize("config", [LikelihoodFieldConfig, BeamModelConfig])
def test_ros_scoring_refuses_tempering_and_unknown_scorings(config: type) -> None:
    assert config(scoring="ros").temper is None  # the scoring's default: no tempering
    assert resolve_temper(None, "ros") == 1.0
    with pytest.raises(ValueError, match="temper: applies to scoring 'product' only"):
        config(scoring="ros", temper=0.3)
    with pytest.raises(ValueError, match="scoring: expected one of product, ros"):
        config(scoring="sum")
