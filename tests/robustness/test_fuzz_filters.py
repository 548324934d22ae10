"""Fuzzing every filter on random small maps, scans and odometry: never a NaN or an inf."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ceamcl.filters import ALGORITHMS
from ceamcl.filters.ceamcl import CEAMCLConfig
from ceamcl.maps.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.runner import timed_step
from ceamcl.sensors.scan import LaserScan
from tests.robustness._filters import assert_all_finite, small_filter, small_sensor

CEAMCL_TINY = CEAMCLConfig(
    n_test=150, test_batch=150, max_samples=200, tracking_samples=20, cell_m=0.2
)


@st.composite
def grids(draw: st.DrawFn) -> OccupancyGrid:
    h, w = draw(st.integers(3, 24)), draw(st.integers(3, 24))
    cells = draw(
        arrays(np.int8, (h, w), elements=st.sampled_from([FREE, FREE, FREE, OCCUPIED, UNKNOWN]))
    )
    cells[draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1))] = FREE  # one free cell
    resolution = draw(st.sampled_from([0.05, 0.1, 0.25, 1.0]))
    origin = (draw(st.floats(-50, 50)), draw(st.floats(-50, 50)), draw(st.floats(-3.2, 3.2)))
    return OccupancyGrid(cells, resolution, origin)


READING = st.one_of(
    st.floats(0.0, 12.0),
    st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1.0, 1e300, 5e-324]),
    st.floats(allow_nan=True, allow_infinity=True),
)


@st.composite
def scans(draw: st.DrawFn) -> LaserScan:
    n = draw(st.integers(0, 24))
    range_max = draw(st.sampled_from([0.5, 4.0, 8.0, 30.0]))
    return LaserScan(
        np.array(draw(st.lists(READING, min_size=n, max_size=n)), dtype=np.float64),
        angle_min=draw(st.floats(-4.0, 4.0)),
        angle_increment=draw(st.floats(-0.2, 0.2)),
        range_min=draw(st.sampled_from([0.0, 0.02, 0.3])),
        range_max=range_max,
        pose=(draw(st.floats(-0.5, 0.5)), draw(st.floats(-0.5, 0.5)), draw(st.floats(-4, 4))),
    )


increments = st.builds(
    OdometryIncrement,
    st.floats(-7.0, 7.0),
    st.one_of(st.floats(0.0, 3.0), st.just(0.0)),
    st.floats(-7.0, 7.0),
)


@settings(
    max_examples=1000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(
    algorithm=st.sampled_from(ALGORITHMS),
    sensor=st.sampled_from(["likelihood-field", "beam"]),
    grid=grids(),
    first=scans(),
    steps=st.lists(st.tuples(increments, st.one_of(st.none(), scans())), min_size=1, max_size=3),
    seed=st.integers(0, 2**32 - 1),
    tracking=st.booleans(),
)
def test_fuzz_filters_never_produce_nan(
    algorithm: str,
    sensor: str,
    grid: OccupancyGrid,
    first: LaserScan,
    steps: list[tuple[OdometryIncrement, LaserScan | None]],
    seed: int,
    tracking: bool,
) -> None:
    model = small_sensor(sensor, grid, max_beams=12)
    f = small_filter(algorithm, grid, np.random.default_rng(seed), model, ceamcl_config=CEAMCL_TINY)
    if tracking:
        x0, x1, y0, y1 = grid.bounds
        f.initialise_pose([(x0 + x1) / 2, (y0 + y1) / 2, 0.0], np.diag([0.04, 0.04, 0.1]))
    else:
        f.initialise_global(first)
    assert_all_finite(f)
    for k, (increment, scan) in enumerate(steps, start=1):
        diag = timed_step(f, k, increment, scan)
        assert diag.n_particles == f.particles().poses.shape[0]
        assert_all_finite(f)
