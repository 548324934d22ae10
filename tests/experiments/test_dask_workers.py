"""``--executor dask://HOST:PORT``: a scheduler's own workers checked and made ready before
the first trial (ceamcl.experiments.dask_workers). The scheduler and its workers are started
here as a Dask LocalCluster, whose address the executor reaches as it would a remote one."""

from __future__ import annotations

from collections.abc import Iterator
from types import SimpleNamespace

import numpy as np
import pytest

import ceamcl
from ceamcl import budget
from ceamcl.errors import ConfigError
from ceamcl.experiments.executors import open_executor
from tests.experiments.test_experiments import _numbers, small_table1

distributed = pytest.importorskip("distributed")
dask_workers = pytest.importorskip("ceamcl.experiments.dask_workers")


def _start(workers: int) -> tuple[object, str]:
    cluster = distributed.LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=40,
        env={"NUMBA_NUM_THREADS": "1"},
    )
    address = str(cluster.scheduler_address)
    return cluster, "dask://" + address.removeprefix("tcp://")


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """A scheduler with one worker, ended after this module's tests."""
    cluster, spec = _start(1)
    try:
        yield spec
    finally:
        cluster.close()  # type: ignore[attr-defined]


def _memory_budget() -> int:
    return budget.current().memory_bytes


def _kernels_without_their_signatures() -> list[str]:
    from ceamcl.warmup import kernels

    return [name for name, dispatcher, sig in kernels() if sig not in dispatcher.overloads]


def test_workers_hold_the_commands_budget_and_every_kernel_before_the_first_trial(
    scheduler: str,
) -> None:
    """Before: a worker kept its own budget and compiled the kernels inside its first trial
    (whose mean step was 11.7 ms against 2.0-2.5 ms for the others)."""
    asked = 3 * 1024**3 + 12345
    with budget.use(budget.Budget(asked)), open_executor(scheduler) as ex:
        assert ex.submit(_memory_budget).result(timeout=60) == asked
        assert ex.submit(_kernels_without_their_signatures).result(timeout=60) == []


def test_a_schedulers_workers_give_the_same_numbers_as_this_process(scheduler: str) -> None:
    here_rows, here_est = _numbers(small_table1("serial"))
    there_rows, there_est = _numbers(small_table1(scheduler))
    assert len(here_rows) == 2
    assert there_rows == here_rows
    assert all(np.array_equal(a, b) for a, b in zip(here_est, there_est, strict=True))


def test_workers_with_other_software_are_refused_naming_what_differs(
    scheduler: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    theirs = ceamcl.__version__
    monkeypatch.setattr(ceamcl, "__version__", "0.0.0-elsewhere")
    dask_workers.software.cache_clear()
    try:
        with pytest.raises(ConfigError) as caught, open_executor(scheduler):
            pass
    finally:
        dask_workers.software.cache_clear()
    text = str(caught.value)
    assert "1 of the 1 Dask workers" in text
    assert f"ceamcl 0.0.0-elsewhere here, {theirs} there" in text
    assert "tcp://" in text


def test_a_scheduler_without_workers_is_an_error_after_a_bounded_wait(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before: `experiment table1 --executor dask://...` waited at 0/4 for good."""
    monkeypatch.setattr(dask_workers, "WORKER_WAIT_S", 1.0)
    cluster, spec = _start(0)
    try:
        with pytest.raises(ConfigError, match=r"has no workers \(waited 1 s\); start them"):
            with open_executor(spec):
                pass
    finally:
        cluster.close()  # type: ignore[attr-defined]


def test_a_worker_joining_with_other_software_does_not_start() -> None:
    """The plugin's check, which a worker joining after the command started meets at its
    start; one with the same software takes the command's budget."""
    worker = SimpleNamespace(address="tcp://10.0.0.7:40000")
    other = {**dask_workers.software(), "numpy": "1.0.0"}
    with pytest.raises(ConfigError, match=r"tcp://10.0.0.7:40000 .*numpy 1.0.0 here, "):
        dask_workers.TrialWorker(123, other).setup(worker)
    with budget.use(budget.current()):
        dask_workers.TrialWorker(2 * 1024**3, dask_workers.software()).setup(worker)
        assert budget.current().memory_bytes == 2 * 1024**3
