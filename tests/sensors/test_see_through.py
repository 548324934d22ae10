"""Readings through walls and what they cost a pose in the likelihood field
(:mod:`ceamcl.sensors.see_through`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ceamcl.maps.worlds import get_world
from ceamcl.sensors.beam_model import BeamModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel
from ceamcl.sensors.scan import LaserScan, prepare_scan
from ceamcl.sensors.see_through import (
    readings_through_walls,
    readings_through_walls_reference,
    see_through_penalty,
)
from ceamcl.simulation.scenarios import office_scenario

GRID = get_world("small-office")
LF = LikelihoodFieldModel(GRID)
MARGIN = 0.5


@pytest.fixture(scope="module")
def seen() -> tuple[LaserScan, np.ndarray, np.ndarray]:
    """A scan, the true pose, and half a turn from it (its long readings run into walls)."""
    log = office_scenario().simulate(np.random.default_rng(2))
    truth = log.true_poses[10]
    return log.scan(10), truth, truth + np.array([0.0, 0.0, np.pi])


def test_the_true_pose_pays_nothing_and_a_turned_pose_pays_for_its_readings_through_walls(
    seen: tuple[LaserScan, np.ndarray, np.ndarray],
) -> None:
    scan, truth, turned = seen
    penalty = see_through_penalty(GRID, LF, np.stack([truth, turned]), scan, MARGIN, 0.1)
    assert penalty[0] == 0.0
    prepared = prepare_scan(scan, LF.config.max_beams, keep_max_range=True)
    through = readings_through_walls(GRID, turned, prepared, MARGIN)[0]
    assert through.mean() > 0.2
    # each reading through a wall loses at most what a perfect beam scores over an unexplained
    # one, tempered; the 10 % forgiven lose nothing
    per_beam = LF.temper * (LF.max_log_beam_likelihood(prepared) - LF.unexplained_value(prepared))
    counted = through.sum() - int(0.1 * prepared.n_beams)
    assert -counted * per_beam <= penalty[1] < -0.5 * per_beam


def test_one_reading_through_a_wall_costs_its_likelihood_over_the_unexplained_floor(
    seen: tuple[LaserScan, np.ndarray, np.ndarray],
) -> None:
    scan, truth, _ = seen
    prepared = prepare_scan(scan, LF.config.max_beams, keep_max_range=True)
    before = readings_through_walls(GRID, truth, prepared, MARGIN)[0]
    # lengthen one reading that ends on a wall by 2 m: it now runs through that wall
    k = int(np.flatnonzero(~before & ~prepared.is_max & (prepared.ranges < 3.0))[0])
    ranges = scan.ranges.copy()
    ranges[prepared.source_indices[k]] += 2.0
    longer = dataclasses.replace(scan, ranges=ranges)
    longer_prepared = prepare_scan(longer, LF.config.max_beams, keep_max_range=True)
    after = readings_through_walls(GRID, truth, longer_prepared, MARGIN)[0]
    assert after[k] and (after & ~before).sum() == 1
    value = LF.beam_values(truth, longer_prepared)[0, k]
    expected = -LF.temper * (value - LF.unexplained_value(longer_prepared))
    gained = see_through_penalty(GRID, LF, truth, longer, MARGIN, 0.0)[0]
    gained -= see_through_penalty(GRID, LF, truth, scan, MARGIN, 0.0)[0]
    assert gained == pytest.approx(expected)
    assert expected < 0


def test_the_tolerance_forgives_the_costliest_readings_first(
    seen: tuple[LaserScan, np.ndarray, np.ndarray],
) -> None:
    scan, _, turned = seen
    penalties = [see_through_penalty(GRID, LF, turned, scan, MARGIN, t)[0] for t in (0, 0.1, 0.3)]
    assert penalties[0] < penalties[1] < penalties[2] <= 0
    prepared = prepare_scan(scan, LF.config.max_beams, keep_max_range=True)
    n_through = int(readings_through_walls(GRID, turned, prepared, MARGIN)[0].sum())
    everything = (n_through + 0.5) / prepared.n_beams
    assert see_through_penalty(GRID, LF, turned, scan, MARGIN, everything)[0] == 0.0


def test_models_that_see_walls_or_score_as_amcl_pay_nothing_and_bad_poses_are_left_alone(
    seen: tuple[LaserScan, np.ndarray, np.ndarray],
) -> None:
    scan, _, turned = seen
    amcl_scoring = LikelihoodFieldModel(GRID, LikelihoodFieldConfig(scoring="ros"))
    for model in (BeamModel(GRID), amcl_scoring):
        assert not see_through_penalty(GRID, model, turned, scan, MARGIN, 0.0).any()

    alone = see_through_penalty(GRID, LF, turned, scan, MARGIN, 0.0)
    mixed = see_through_penalty(GRID, LF, np.stack([[np.nan, 0.0, 0.0], turned]), scan, MARGIN, 0.0)
    assert mixed[0] == 0.0 and mixed[1] == alone[0]
    blind = dataclasses.replace(scan, ranges=np.full_like(scan.ranges, np.nan))
    assert see_through_penalty(GRID, LF, turned, blind, MARGIN, 0.0)[0] == 0.0


@pytest.mark.parametrize("origin_yaw", [0.0, 0.3])
def test_the_compiled_pass_equals_the_reference(
    seen: tuple[LaserScan, np.ndarray, np.ndarray], origin_yaw: float
) -> None:
    """Poses anywhere on the map (one, for the state's read, and hundreds, cast in parallel),
    a laser mounted off the axis and a map whose origin is turned: the same readings through
    walls as the laser poses, the grid frame and the ray cast in NumPy."""
    scan, truth, _ = seen
    grid = GRID.with_data(GRID.data)
    grid = dataclasses.replace(grid, origin=(1.5, -2.0, origin_yaw)) if origin_yaw else grid
    mounted = dataclasses.replace(scan, pose=(0.12, -0.03, 0.05))
    prepared = prepare_scan(mounted, 90, keep_max_range=True)
    rng = np.random.default_rng(3)
    for n in (1, 400):
        poses = grid.sample_free_poses(n, rng)
        poses[0] = truth
        got = readings_through_walls(grid, poses, prepared, MARGIN)
        want = readings_through_walls_reference(grid, poses, prepared, MARGIN)
        assert got.shape == (n, prepared.n_beams)
        np.testing.assert_array_equal(got, want)
        assert want.any() and not want.all()  # a comparison that says something
