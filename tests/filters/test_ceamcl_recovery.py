"""CEAMCL relocalises a kidnapped robot (fitness-collapse recovery, docs/ceamcl.md) and
does not restart when nothing happened."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.motion.odometry import OdometryMotionModel, OdometryNoise
from ceamcl.runner import RunResult, run_filter
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.simulation.scenarios import kidnapped_scenario, office_scenario
from ceamcl.simulation.simulator import SimulatedLog

RECOVERY_TIME_S = 5.0  # the stated bound: within 0.5 m of the truth 5 s after the kidnap


def run(scenario_log: SimulatedLog, grid_seed: int, recovery: bool) -> RunResult:
    grid = kidnapped_scenario().grid()
    rng = np.random.default_rng(np.random.SeedSequence(grid_seed).spawn(2)[1])
    if recovery:
        f = make_filter("ceamcl", grid, rng)
    else:
        cfg = replace(CEAMCLConfig(), recovery=False)
        f = CEAMCL(
            grid, OdometryMotionModel(OdometryNoise()), LikelihoodFieldModel(grid), cfg, rng=rng
        )
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
