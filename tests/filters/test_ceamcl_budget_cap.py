"""``max_samples`` caps CEAMCL's total sample size at every step, a recovery's included: the
species a step adds beside the living ones (a recovery's search keeps the old species,
departure 19 starts one) make room by the species with the least weight giving way
(``phases.fit_budget``). Tracking's particle budget is that cap, as ``max_particles`` is
Nav2 AMCL's."""

from __future__ import annotations

import numpy as np

from ceamcl.experiments.tracking_log import start_covariance, tracking_filter
from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl.phases import fit_budget
from ceamcl.filters.particles import ParticleSet
from ceamcl.filters.registry import with_config
from ceamcl.pose import position_error
from ceamcl.replay import UpdatePace
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation import office_scenario


def _set(sizes: dict[int, int]) -> ParticleSet:
    labels = np.concatenate([np.full(n, sid, dtype=np.int64) for sid, n in sizes.items()])
    ps = ParticleSet.from_poses(np.zeros((labels.size, 3)), labels)
    ps.loglik = np.arange(labels.size, dtype=np.float64)  # later samples score higher
    return ps


def test_within_the_budget_nothing_goes() -> None:
    ps = _set({1: 10, 2: 10})
    assert fit_budget(ps, 20, 3, {1: 0.0, 2: -5.0}) == 0
    assert ps.n == 20


def test_the_species_with_the_least_weight_give_way_and_a_cut_one_keeps_its_best() -> None:
    ps = _set({1: 10, 2: 10, 3: 10, 4: 10})
    loglik = ps.loglik.copy()
    # ranks: 3 first, then 1, then 4; 2 last. Room 24: 3 and 1 whole, 4 cut to its best 4.
    dropped = fit_budget(ps, 24, 3, {1: -1.0, 2: -9.0, 3: 0.0, 4: -2.0})
    assert dropped == 16 and ps.n == 24
    counts = {int(s): int(np.sum(ps.labels == s)) for s in np.unique(ps.labels)}
    assert counts == {1: 10, 3: 10, 4: 4}
    assert np.array_equal(np.sort(ps.loglik[ps.labels == 4]), loglik[36:40])
    # a remainder below the viable size goes rather than leaving a species of 2
    ps = _set({1: 10, 2: 10})
    assert fit_budget(ps, 12, 3, {1: 0.0, 2: -1.0}) == 10
    assert np.all(ps.labels == 1)


def _wrong_start_run(max_samples: int | None, budget: int) -> RunResult:
    """Tracking the simulated office from a start 3 m off the truth: the tracked species
    fails and a recovery's global search proposes new species beside it."""
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(7), grid)
    start = log.true_poses[0] + np.array([3.0, 0.0, 0.0])
    if max_samples is None:
        f = tracking_filter("ceamcl", grid, np.random.default_rng(0), budget)
    else:
        cfg = with_config("ceamcl", tracking_samples=budget, max_samples=max_samples)
        f = make_filter("ceamcl", grid, np.random.default_rng(0), config=cfg)
    return run_filter(
        f, log, update_when=UpdatePace(0.2, 0.2).policy(), initial_pose=(start, start_covariance())
    )


def test_tracking_never_holds_more_samples_than_its_budget_through_a_recovery() -> None:
    budget = 60
    uncapped = _wrong_start_run(20_000, budget)  # the scenario does exceed without the cap
    assert max(d.n_particles for d in uncapped.diagnostics) > 2 * budget
    run = _wrong_start_run(None, budget)
    sizes = [d.n_particles for d in run.diagnostics]
    recoveries = sum(
        int(d.record.columns().get("recoveries") or 0)
        for d in run.diagnostics
        if d.record is not None
    )
    assert recoveries >= 1
    assert max(sizes) <= budget
    # the recovery still finds the robot within the budget
    assert position_error(run.estimates[-1], run.truth[-1]) < 0.2
