"""A finished filter is freed as soon as the last reference to it goes, without waiting for
the cyclic garbage collector: a worker runs trial after trial, and on a 40-million-cell map
each CEAMCL kept alive by a reference cycle held its likelihood field (307 MiB) until the
collector ran, several trials later (fr-clinic read as a corrected log: 6.7 GB resident over
ten windows with one worker, 1.9 GB once the cycle was gone)."""

from __future__ import annotations

import copy
import gc
import pickle
import weakref
from collections.abc import Iterator

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.registry import names
from ceamcl.runner import run_filter
from ceamcl.simulation import office_scenario


@pytest.fixture
def no_cyclic_collector() -> Iterator[None]:
    gc.collect()
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


@pytest.mark.parametrize("algorithm", ["ceamcl", "mcl", "gmcl", "kld-amcl"])
@pytest.mark.usefixtures("no_cyclic_collector")
def test_a_finished_filter_is_freed_without_the_cyclic_collector(algorithm: str) -> None:
    assert algorithm in names()
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(7), grid)
    f = make_filter(algorithm, grid, np.random.default_rng(0))
    run_filter(f, log)  # every phase ran, recoveries' anchor included
    gone = weakref.ref(f)
    sensor = weakref.ref(f.sensor)  # type: ignore[attr-defined]
    del f
    assert gone() is None
    assert sensor() is None


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copied_ceamcl_asks_its_own_anchor_contest(how: str) -> None:
    """The anchor holds the filter's methods weakly; a copy (or a pickled and loaded filter)
    holds its own copy's, not the original's."""
    sc = office_scenario()
    grid = sc.grid()
    f = make_filter("ceamcl", grid, np.random.default_rng(0))
    run_filter(f, sc.simulate(np.random.default_rng(7), grid))
    g = copy.deepcopy(f) if how == "deepcopy" else pickle.loads(pickle.dumps(f))
    for callback in (g.confident.contest, g.confident.envelope):  # type: ignore[attr-defined]
        assert callback._ref().__self__ is g
    assert g.confident.envelope() == f.confident.envelope()  # type: ignore[attr-defined]
