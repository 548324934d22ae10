"""CEAMCL relocalises a kidnapped robot (fitness-collapse recovery, docs/ceamcl.md) and
does not restart when nothing happened."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryMotionModel, OdometryNoise
from ceamcl.runner import RunResult, run_filter
from ceamcl.sensors.beam_skip import BeamSkipConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.simulation.scenarios import kidnapped_scenario, office_scenario, paper_scenario
from ceamcl.simulation.simulator import SimulatedLog

RECOVERY_TIME_S = 5.0  # the stated bound: within 0.5 m of the truth 5 s after the kidnap


def tracker(grid: OccupancyGrid, config: CEAMCLConfig, rng: np.random.Generator) -> CEAMCL:
    """CEAMCL with ``config``, the default odometry noise and the likelihood field."""
    motion, sensor = OdometryMotionModel(OdometryNoise()), LikelihoodFieldModel(grid)
    return CEAMCL(grid, motion, sensor, config, rng=rng)


def run(scenario_log: SimulatedLog, grid_seed: int, recovery: bool) -> RunResult:
    grid = kidnapped_scenario().grid()
    rng = np.random.default_rng(np.random.SeedSequence(grid_seed).spawn(2)[1])
    if recovery:
        f = make_filter("ceamcl", grid, rng)
    else:
        f = tracker(grid, replace(CEAMCLConfig(), recovery=False), rng)
    return run_filter(f, scenario_log)


def kidnapped_log(seed: int) -> SimulatedLog:
    sc = kidnapped_scenario()
    return sc.simulate(np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ceamcl_relocalises_after_a_kidnap(seed: int) -> None:
    log = kidnapped_log(seed)
    (kidnap,) = log.kidnapped_at
    result = run(log, seed, recovery=True)
    err = result.position_errors
    assert err is not None
    assert err[kidnap - 10 : kidnap].max() < 0.5  # localised before the kidnap
    restarts = [k for k, d in enumerate(result.diagnostics) if d.reinitialised]
    assert restarts and all(k >= kidnap for k in restarts)  # only once kidnapped
    assert result.diagnostics[restarts[0]].record.columns()["recoveries"] == 1.0
    back = kidnap + int(RECOVERY_TIME_S * 10)
    assert err[back:].max() < 0.5  # found again and kept to the end


def test_without_recovery_the_kidnapped_robot_stays_lost() -> None:
    log = kidnapped_log(0)
    (kidnap,) = log.kidnapped_at
    result = run(log, 0, recovery=False)
    err = result.position_errors
    assert err is not None
    assert not any(d.reinitialised for d in result.diagnostics)
    assert np.median(err[kidnap + 50 :]) > 0.5


@pytest.mark.parametrize("seed", [0, 3])
def test_no_recovery_fires_on_an_ordinary_run(seed: int) -> None:
    sc = office_scenario()
    sim, filt = np.random.SeedSequence(seed).spawn(2)
    log = sc.simulate(np.random.default_rng(sim))
    f = make_filter("ceamcl", sc.grid(), np.random.default_rng(filt))
    result = run_filter(f, log)
    assert not any(d.record.columns()["recoveries"] for d in result.diagnostics)


def cluttered_office_log(seed: int, start: int, steps: int) -> SimulatedLog:
    """The office run with people in front of the laser for ``steps`` steps from ``start``: in
    each of those scans a random half of the beams read 0.3-1.5 m (nothing the map holds)."""
    sc = office_scenario()
    log = sc.simulate(np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0]))
    rng = np.random.default_rng(seed)
    ranges = log.ranges.copy()
    for k in range(start, start + steps):
        beams = rng.random(ranges.shape[1]) < 0.5
        ranges[k, beams] = rng.uniform(0.3, 1.5, int(beams.sum()))
    return replace(log, ranges=ranges)


def track_cluttered(seed: int, config: CEAMCLConfig) -> RunResult:
    log = cluttered_office_log(seed, start=60, steps=12)
    grid = office_scenario().grid()
    f = tracker(grid, config, np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1]))
    cov = np.diag([0.1**2, 0.1**2, 0.05**2])
    return run_filter(f, log, initial_pose=(log.true_poses[0], cov))


@pytest.mark.parametrize("seed", [0, 1])
def test_clutter_is_not_a_kidnap(seed: int) -> None:
    """Half the beams on people for 1.2 s: CEAMCL tracking one species leaves out the short
    readings it cannot explain (beam skipping), so no recovery fires and the estimate stays on
    the truth. Weighing every beam, the fitness collapses, the recovery fires and a look-alike
    place leads for about 3 s (measured: 3.4 m off in 3 of 4 seeds)."""
    result = track_cluttered(seed, CEAMCLConfig())
    skipped = [d.record.columns()["skipped_beams"] for d in result.diagnostics[60:72]]
    assert min(skipped) > 0
    assert not any(d.record.columns()["recoveries"] for d in result.diagnostics)
    err = result.position_errors
    assert err is not None and err.max() < 0.5
    every_beam = track_cluttered(seed, replace(CEAMCLConfig(), beam_skip=None))
    assert any(d.record.columns()["recoveries"] for d in every_beam.diagnostics[60:80])


CROWD = range(10, 25)  # 1.5 s in the middle of room 0, its walls metres away


def track_through_a_crowd(seed: int, config: CEAMCLConfig) -> RunResult:
    """The hall's room 0 with people all round the laser for 1.5 s: in each of those scans
    every beam but a random 5 % reads 0.3-0.8 m (or less, where the room is nearer), far from
    any wall. CEAMCL tracks from the true pose."""
    sc = paper_scenario(0)
    grid = sc.grid()
    sim, filt = np.random.SeedSequence(seed).spawn(2)
    log = sc.simulate(np.random.default_rng(sim), grid)
    rng = np.random.default_rng(seed)
    ranges = log.ranges.copy()
    for k in CROWD:
        people = rng.random(ranges.shape[1]) >= 0.05
        ranges[k, people] = np.minimum(ranges[k, people], rng.uniform(0.3, 0.8, people.sum()))
    log = replace(log, ranges=ranges)
    f = tracker(grid, config, np.random.default_rng(filt))
    cov = np.diag([0.1**2, 0.1**2, 0.05**2])
    return run_filter(f, log, initial_pose=(log.true_poses[0], cov))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_crowd_that_blocks_almost_the_whole_view_is_not_a_kidnap(seed: int) -> None:
    """Departure 34 (docs/ceamcl.md): with 95 % of the readings on people, the few the map
    explains are what the tracked species is weighed by (beam skipping's error threshold 1.0),
    so no recovery fires and the estimate stays on the truth. With amcl's threshold (0.9)
    every beam counts in that view, the fitness collapses and a recovery fires."""
    result = track_through_a_crowd(seed, CEAMCLConfig())
    crowded = result.diagnostics[CROWD.start : CROWD.stop]
    assert min(d.record.columns()["skipped_beams"] for d in crowded) > 0
    assert not any(d.record.columns()["recoveries"] for d in result.diagnostics)
    err = result.position_errors
    assert err is not None and err.max() < 0.3
    amcl = replace(CEAMCLConfig(), beam_skip=BeamSkipConfig(error_threshold=0.9))
    counted = track_through_a_crowd(seed, amcl)
    assert any(d.record.columns()["recoveries"] for d in counted.diagnostics)
