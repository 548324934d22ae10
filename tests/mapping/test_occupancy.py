"""Occupancy grid mapping: the inverse sensor model on single beams, and a simulated run
whose map must agree with the world it was simulated in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ceamcl.errors import LogFormatError
from ceamcl.io.logs import RecordedLog
from ceamcl.mapping import MappingConfig, build_map, log_odds_map, map_from_log
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.scan import laser_poses
from ceamcl.simulation import paper_scenario


def beam_log(ranges: list[float], repeats: int, range_max: float = 30.0) -> RecordedLog:
    """``repeats`` identical scans from the origin facing +x: beams at bearing 0."""
    n, b = repeats, len(ranges)
    return RecordedLog(
        path="beams.log",
        times=np.arange(n, dtype=np.float64),
        poses=np.zeros((n, 3)),
        ranges_flat=np.tile(np.asarray(ranges, dtype=np.float64), n),
        offsets=np.arange(n + 1, dtype=np.intp) * b,
        angle_min=np.zeros(n),
        angle_increment=np.zeros(n),
        range_min=np.zeros(n),
        range_max=np.full(n, range_max),
        laser_mount=np.zeros((n, 3)),
    )


def value_at(grid: OccupancyGrid, x: float, y: float = 0.01) -> int:
    ix, iy = grid.world_to_cell(x, y)
    return int(grid.data[int(iy), int(ix)])


CFG = MappingConfig(resolution_m=0.1, max_range_m=5.0, no_return_free_m=2.0, margin_m=0.5)


def test_hit_marks_end_occupied_and_path_free() -> None:
    log = beam_log([3.0], repeats=10)
    grid, stats = map_from_log(log, CFG)
    assert stats.hits == 10 and stats.no_return == 0
    for x in (0.05, 1.0, 2.0, 2.85):
        assert value_at(grid, x) == 0, x
    assert value_at(grid, 3.05) == 100
    assert grid.occupied_mask.sum() == 1
    # nothing beyond the hit was seen
    assert value_at(grid, 3.3) == -1


def test_one_pass_is_not_enough_to_call_a_cell_free() -> None:
    grid, _ = map_from_log(beam_log([3.0], repeats=1), CFG)
    assert value_at(grid, 1.0) == -1  # l_free alone gives p = 0.4, above free_prob
    assert value_at(grid, 3.05) == 100  # l_occ alone gives p = 0.7, above occupied_prob


def test_no_return_clears_up_to_its_cap_and_marks_no_hit() -> None:
    grid, stats = map_from_log(beam_log([30.0], repeats=10), CFG)
    assert stats.no_return == 10 and stats.hits == 0
    assert not grid.occupied_mask.any()
    assert value_at(grid, 1.9) == 0
    assert value_at(grid, 2.2) == -1


def test_reading_beyond_usable_range_clears_to_it_without_hit() -> None:
    grid, stats = map_from_log(beam_log([12.0], repeats=10), CFG)
    assert stats.hits == 0 and stats.no_return == 0
    assert not grid.occupied_mask.any()
    assert value_at(grid, 4.9) == 0
    assert value_at(grid, 5.3) == -1


def test_inf_is_no_return_and_nan_and_zero_are_dropped() -> None:
    """REP 117: +inf is "no return" (clears free space), NaN an erroneous reading (dropped)."""
    grid, stats = map_from_log(beam_log([math.inf, math.nan, 0.0], repeats=10), CFG)
    assert stats.no_return == 10
    assert stats.beams == 10  # only the +inf readings are traced
    assert value_at(grid, 1.5) == 0


def test_all_nan_scans_are_refused_rather_than_mapped_as_free() -> None:
    with pytest.raises(LogFormatError, match=r"beams\.log: no usable reading in 10 scans"):
        map_from_log(beam_log([math.nan] * 5, repeats=10), CFG)


def test_a_map_beyond_the_memory_budget_is_refused_before_allocating() -> None:
    from ceamcl import budget

    log = beam_log([3.0], repeats=2)
    far = RecordedLog(
        **{**log.__dict__, "poses": np.array([[0.0, 0.0, 0.0], [3000.0, 3000.0, 0.0]])}
    )
    with budget.use(budget.Budget(1 << 30)), pytest.raises(budget.BudgetError) as info:
        map_from_log(far, CFG)
    message = str(info.value)
    assert message.startswith(
        "beams.log: map built at resolution 0.1 m over the log's 3004 m x 3001 m"
    )
    assert "map cells would need" in message and "memory budget of 1.0 GiB" in message


def test_diagonal_beam_passes_through_contiguous_cells() -> None:
    log = beam_log([4.0], repeats=10)
    log = RecordedLog(**{**log.__dict__, "angle_min": np.full(10, 0.7)})
    logodds, _origin, _ = log_odds_map(log, log.laser_world_poses(), CFG)
    touched = np.argwhere(logodds < 0)
    # a 4 m beam crosses about 4 / 0.1 * (|cos| + |sin|) cells, none skipped
    expected = 4.0 / 0.1 * (abs(math.cos(0.7)) + abs(math.sin(0.7)))
    assert touched.shape[0] == pytest.approx(expected, abs=3)


def test_simulated_run_reproduces_the_world() -> None:
    scenario = paper_scenario(start_room=0, world="symmetric-hall")
    world = scenario.grid()
    sim = scenario.simulate(np.random.default_rng(4), world)
    lw = laser_poses(sim.true_poses, sim.laser.pose)
    grid, stats = build_map(sim, lw, MappingConfig(resolution_m=world.resolution))
    assert stats.hits > 0
    # cells the map calls free are free in the world (noise may blur walls by a cell or two)
    iy, ix = np.nonzero(grid.free_mask)
    cx, cy = world.world_to_cell(*grid.cell_to_world(ix, iy))
    inside = world.in_bounds(cx, cy)
    free_in_world = np.zeros(ix.size, dtype=bool)
    free_in_world[inside] = world.free_mask[cy[inside], cx[inside]]
    assert np.mean(free_in_world) > 0.99
    # occupied cells of the map lie on the world's walls
    iy, ix = np.nonzero(grid.occupied_mask)
    x, y = grid.cell_to_world(ix, iy)
    cx, cy = world.world_to_cell(x, y)
    inside = world.in_bounds(cx, cy)
    near = world.distance_to_occupied[cy[inside], cx[inside]] <= 2 * world.resolution
    assert np.mean(near) > 0.95
