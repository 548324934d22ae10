"""Tests of the runner's step records (``ceamcl.runner``): it measures each step's time,
particle count and ESS; the filter's own record rides along."""

from __future__ import annotations

from typing import Any

import numpy as np

from ceamcl.filters import KLDAMCLRecord, StepRecord, make_filter
from ceamcl.filters.resampling import effective_sample_size
from ceamcl.filters.state import LocalisationState, State, initialising
from ceamcl.runner import measure, run_filter
from ceamcl.simulation import office_scenario


def test_runner_measures_time_count_and_ess_of_every_step() -> None:
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(1), grid)
    f = make_filter("kld-amcl", grid, np.random.default_rng(2))
    res = run_filter(f, log)
    assert [d.step for d in res.diagnostics] == list(range(len(log)))
    assert all(d.step_ms > 0 for d in res.diagnostics)
    assert all(isinstance(d.record, KLDAMCLRecord) for d in res.diagnostics)
    last = res.diagnostics[-1]
    w = f.particle_weights()
    assert last.n_particles == w.size and last.ess == effective_sample_size(w)
    row = last.row()
    assert list(row)[:6] == [
        "step",
        "n_particles",
        "ess",
        "resampled",
        "likelihood_evaluations",
        "step_ms",
    ]
    assert {"updated", "w_slow", "w_fast", "injected", "kld_target"} <= set(row)


class Hidden:
    """A filter that cannot show its particles (as the Nav2 peer)."""

    def particle_weights(self) -> np.ndarray:
        return np.full(7, np.nan)

    def state(self, hypotheses: object = None) -> LocalisationState:
        return initialising()


def test_hidden_weights_give_the_reported_count_and_an_unknown_ess() -> None:
    d = measure(Hidden(), 3, lambda: StepRecord(resampled=True))  # type: ignore[arg-type]
    assert d.step == 3 and d.n_particles == 7 and np.isnan(d.ess) and d.resampled
    assert d.state is not None and d.state.state is State.INITIALISING


def test_runner_records_the_state_of_every_step_in_the_diagnostics_rows() -> None:
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(1), grid)
    res = run_filter(make_filter("ceamcl", grid, np.random.default_rng(2)), log)
    assert len(res.states) == len(log)
    assert all(s is not None for s in res.states)
    assert res.diagnostics[0].row()["state"] == "INITIALISING"
    assert res.diagnostics[-1].row()["state"] == "LOCALISED"
    assert 0.0 <= float(res.diagnostics[-1].row()["state_confidence"]) <= 1.0


def test_run_filter_names_a_wrong_argument_in_one_line() -> None:
    """``run_filter(f, None)`` said "object of type 'NoneType' has no len()" and
    ``run_filter(grid, log)`` "'OccupancyGrid' object has no attribute 'initialise_global'"."""
    import pytest

    from ceamcl.errors import ConfigError, InputTypeError

    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(1), grid)
    f = make_filter("mcl", grid, np.random.default_rng(2), n_particles=50)
    bad: Any = None
    cases: list[tuple[tuple[Any, Any], dict[str, Any], str]] = [
        ((f, bad), {}, r"^log: expected a robot log .* got None$"),
        ((f, log.ranges), {}, r"^log: expected a robot log .* got ndarray$"),
        ((grid, log), {}, r"^f: expected a localisation filter .* got OccupancyGrid$"),
        ((f, log), {"on_step": 3}, r"^on_step: expected a function or None, got int$"),
        ((f, log), {"snapshot_every": 2.5}, r"^snapshot_every: expected int, got float$"),
        ((f, log), {"initial_pose": np.zeros(3)}, r"^initial_pose: expected \(pose, covariance"),
    ]
    for args, kwargs, message in cases:
        with pytest.raises(InputTypeError, match=message):
            run_filter(*args, **kwargs)
    with pytest.raises(ConfigError, match="snapshot_every: expected a count >= 0, got -1"):
        run_filter(f, log, snapshot_every=-1)
