"""``--executor dask://HOST:PORT``: a scheduler's own workers checked and made ready before
the first trial (ceamcl.experiments.dask_workers). The scheduler and its workers are started
here as a Dask LocalCluster, whose address the executor reaches as it would a remote one."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import ceamcl
from ceamcl import budget
from ceamcl.errors import ConfigError, RunWarning
from ceamcl.experiments import executors
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
    seen: list[tuple[str, int, int]] = []
    with (
        budget.use(budget.Budget(asked)),
        open_executor(scheduler, progress=lambda *a: seen.append(a)) as ex,
    ):
        assert ex.submit(_memory_budget).result(timeout=60) == asked
        assert ex.submit(_kernels_without_their_signatures).result(timeout=60) == []
    # the bar the command shows while the workers load the kernels
    assert seen[0] == (dask_workers.WARM_UP_LABEL, 0, 1)
    assert seen[-1] == (dask_workers.WARM_UP_LABEL, 1, 1)


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


def _join(address: str, log: Path) -> subprocess.Popen[bytes]:
    """A worker started as a user starts one, joining the scheduler at ``address``; its log
    goes to ``log``."""
    dask = Path(sys.executable).with_name("dask")
    # the repository on its path, as the spawned workers have it: trials sent from here
    # refer to this module's functions
    root = str(Path(__file__).resolve().parents[2])
    path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "PYTHONPATH": path}
    with log.open("wb") as out:
        return subprocess.Popen(
            [str(dask), "worker", address, "--nthreads", "1", "--no-dashboard"],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=out,
        )


def _end(process: subprocess.Popen[bytes]) -> None:
    """Ends a worker started by :func:`_join`."""
    if process.poll() is None:
        process.terminate()
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout=10)


def _answer() -> int:
    return 42


def test_the_refusal_names_the_worker_and_what_differs() -> None:
    worker = SimpleNamespace(address="tcp://10.0.0.7:40000")
    other = {**dask_workers.software(), "numpy": "1.0.0"}
    why = dask_workers.TrialWorker(123, other).refusal(worker)
    assert why is not None
    assert "tcp://10.0.0.7:40000" in why
    assert f"numpy {np.__version__} here, 1.0.0 there" in why
    assert dask_workers.TrialWorker(123, dask_workers.software()).refusal(worker) is None


def test_a_worker_joining_with_other_software_closes_before_it_runs_a_trial(
    tmp_path: Path,
) -> None:
    """Before: Dask caught the plugin's refusal at the worker's start and the worker ran the
    trial anyway."""
    cluster, spec = _start(0)
    address = "tcp://" + spec.removeprefix("dask://")
    other = {**dask_workers.software(), "numpy": "1.0.0"}
    process = None
    try:
        with distributed.Client(address, timeout="10s") as client:
            client.register_plugin(
                dask_workers.TrialWorker(2 * 1024**3, other),
                name=f"{dask_workers.PLUGIN_PREFIX}:a-test",
            )
            future = client.submit(_answer, pure=False)
            process = _join(address, tmp_path / "worker.log")
            assert process.wait(timeout=60) == 0  # it closed itself, with its nanny
            assert not future.done()
            assert client.nthreads() == {}
            future.cancel()
        assert "runs other software than the command" in (tmp_path / "worker.log").read_text()
    finally:
        if process is not None:
            _end(process)
        cluster.close()  # type: ignore[attr-defined]


def test_a_worker_joining_later_loads_the_kernels_before_its_first_trial(tmp_path: Path) -> None:
    cluster, spec = _start(1)
    address = "tcp://" + spec.removeprefix("dask://")
    process = None
    try:
        with open_executor(spec), distributed.Client(address, timeout="10s") as client:
            first = set(client.nthreads())
            process = _join(address, tmp_path / "worker.log")
            client.wait_for_workers(2, timeout=60)
            (late,) = set(client.nthreads()) - first
            missing = client.submit(
                _kernels_without_their_signatures, workers=[late], allow_other_workers=False
            )
            assert missing.result(timeout=120) == []
    finally:
        if process is not None:
            _end(process)
        cluster.close()  # type: ignore[attr-defined]


def test_a_run_whose_workers_all_left_ends_with_an_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before: the command sat at its last count for good once the only worker was gone."""
    monkeypatch.setattr(dask_workers, "WORKER_WAIT_S", 1.0)
    monkeypatch.setattr(executors, "WATCH_S", 0.2)
    cluster, spec = _start(1)
    try:
        with open_executor(spec) as ex:
            cluster.scale(0)  # type: ignore[attr-defined]
            assert isinstance(ex, dask_workers.SchedulerExecutor)
            deadline = time.monotonic() + 60
            while ex._client.nthreads() and time.monotonic() < deadline:
                time.sleep(0.1)
            with pytest.raises(ConfigError, match=r"every worker .* left while trials ran"):
                dask_workers._within(  # a wait for good fails the test instead of holding it
                    lambda: executors.map_trials(ex, abs, [-1, -2], label="trials", quiet=True),
                    60,
                )
    finally:
        cluster.close()  # type: ignore[attr-defined]


def test_a_lost_scheduler_is_named_while_trials_run() -> None:
    """Before: the trials' futures were cancelled and the command ended with a bare
    CancelledError traceback (the scheduler stopped mid-run)."""
    client = SimpleNamespace(status="connecting", get_executor=lambda: None)
    ex = dask_workers.SchedulerExecutor(client, "10.0.0.7:8786")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"lost the Dask scheduler at 10.0.0.7:8786 while"):
        ex.stalled()


@contextmanager
def _service(greeting: bytes | None) -> Iterator[int]:
    """A TCP service on this machine that sends ``greeting`` to whoever connects (``None``:
    says nothing, as an HTTP server waits for a request; ``b""``: hangs up); its port."""
    server = socket.create_server(("127.0.0.1", 0))
    done = threading.Event()

    def serve() -> None:
        server.settimeout(0.1)
        while not done.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            with conn:
                if greeting is not None:
                    conn.sendall(greeting)
                if greeting != b"":
                    done.wait(5)  # b"": hangs up at once

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        done.set()
        thread.join(timeout=10)
        server.close()


def test_a_service_that_does_not_greet_is_not_taken_for_a_scheduler() -> None:
    """Before: pointed at an HTTP port (the dashboard's 8787 for the scheduler's 8786), the
    command waited for good."""
    with _service(None) as port:
        with pytest.raises(ConfigError, match=r"nothing at 127.0.0.1:\d+ answered as a Dask"):
            dask_workers.probe("127.0.0.1", port, wait_s=0.5)


def test_a_service_that_greets_otherwise_is_refused_before_dask_reads_it() -> None:
    """Before: Dask took its first bytes for a message's length and tried to allocate 3 EiB."""
    with _service(b"HTTP/1.1 400 Bad Request\r\n") as port:
        with pytest.raises(ConfigError, match=r"answered, but not as a Dask scheduler"):
            dask_workers.probe("127.0.0.1", port, wait_s=5)
    with _service(b"") as port:
        with pytest.raises(ConfigError, match=r"closed the connection without answering"):
            dask_workers.probe("127.0.0.1", port, wait_s=5)


def test_a_scheduler_greets_as_the_probe_expects(scheduler: str) -> None:
    host, _, port = scheduler.removeprefix("dask://").rpartition(":")
    dask_workers.probe(host, int(port), wait_s=10)


def _plugins(dask_scheduler: object) -> list[str]:
    return sorted(
        name
        for name in dask_scheduler.worker_plugins  # type: ignore[attr-defined]
        if name.startswith(dask_workers.PLUGIN_PREFIX)
    )


def test_the_command_leaves_no_plugin_and_removes_one_left_before(tmp_path: Path) -> None:
    """Before: the plugin stayed on the scheduler after the command, and closed every worker
    started later with other code, the next command's own included ("has no workers")."""
    cluster, spec = _start(0)
    address = "tcp://" + spec.removeprefix("dask://")
    process = None
    left = f"{dask_workers.PLUGIN_PREFIX}:Client-of-a-killed-command"

    def command() -> tuple[int, list[str]]:
        with open_executor(spec) as ex:
            return ex.submit(_answer).result(timeout=60), client.run_on_scheduler(_plugins)

    try:
        with distributed.Client(address, timeout="10s") as client:
            stale = {**dask_workers.software(), "ceamcl sources": "an earlier checkout"}
            client.register_plugin(dask_workers.TrialWorker(2 * 1024**3, stale), name=left)
            thread = ThreadPoolExecutor(1)
            try:
                run = thread.submit(command)  # waits for a worker
                deadline = time.monotonic() + 30
                while left in client.run_on_scheduler(_plugins):
                    assert time.monotonic() < deadline, "the plugin left before is still there"
                    time.sleep(0.1)
                process = _join(address, tmp_path / "worker.log")  # this checkout's worker
                answer, during = run.result(timeout=120)
            finally:
                thread.shutdown(wait=False)  # a command that hangs fails the test
            assert answer == 42
            assert len(during) == 1 and during != [left]  # the command's own
            assert process.poll() is None
            assert client.run_on_scheduler(_plugins) == []
    finally:
        if process is not None:
            _end(process)
        cluster.close()  # type: ignore[attr-defined]


def test_a_second_command_on_a_busy_scheduler_is_refused_and_the_first_goes_on(
    scheduler: str,
) -> None:
    """Before: the second command replaced the first's plugin (its budget on the first's
    workers) and, ending, removed it: the first's later workers went unchecked."""
    with open_executor(scheduler) as first:
        with pytest.raises(ConfigError, match=r"another ceamcl command .* is running trials"):
            with open_executor(scheduler):
                pass
        assert first.submit(_answer).result(timeout=60) == 42
        with distributed.Client("tcp://" + scheduler.removeprefix("dask://")) as client:
            assert len(client.run_on_scheduler(_plugins)) == 1


def test_an_ipv6_address_is_probed_without_its_brackets() -> None:
    try:
        server = socket.create_server(("::1", 0), family=socket.AF_INET6)
    except OSError as exc:
        pytest.skip(f"no IPv6 loopback on this machine ({exc})")
    try:
        port = server.getsockname()[1]
        with pytest.raises(ConfigError, match=r"nothing at \[::1\]:\d+ answered"):
            dask_workers.probe("[::1]", port, wait_s=0.5)
    finally:
        server.close()


def test_a_frozen_scheduler_ends_the_run_and_closes_without_waiting_on_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before: `client.nthreads()` waited for good on a scheduler stopped with SIGSTOP."""
    monkeypatch.setattr(dask_workers, "ANSWER_WAIT_S", 0.2)
    calls: list[str] = []
    thawed = threading.Event()

    def frozen(n_workers: int) -> dict[str, object]:
        calls.append("asked for its workers")
        thawed.wait(30)  # as Dask's call to a frozen scheduler: it takes no timeout
        return {"workers": {}}

    client = SimpleNamespace(
        status="running",
        get_executor=lambda: None,
        scheduler_info=frozen,
        close=lambda timeout=None: calls.append(f"close within {timeout}"),
        run_on_scheduler=lambda *a: calls.append("asked the scheduler"),
    )
    ex = dask_workers.SchedulerExecutor(client, "10.0.0.7:8786")  # type: ignore[arg-type]
    try:
        with pytest.raises(
            ConfigError, match=r"lost the Dask scheduler .* did not answer within 0 s"
        ):
            ex.stalled()
        assert ex.lost
        dask_workers.close(client, lost=ex.lost)  # type: ignore[arg-type]
        assert calls == ["asked for its workers", "close within 0.2"]
    finally:
        thawed.set()


@contextmanager
def _frozen(address: str, worker: str) -> Iterator[None]:
    """The process of the Dask worker ``worker`` (of the scheduler at ``address``) stopped with
    SIGSTOP for the block, and let go on at its end whatever happens in it."""
    with distributed.Client(address, timeout="10s") as client:
        pid = client.run(os.getpid, workers=[worker])[worker]
    os.kill(pid, signal.SIGSTOP)
    try:
        yield
    finally:
        os.kill(pid, signal.SIGCONT)


def _raises_on_the_worker() -> None:
    raise ModuleNotFoundError("No module named 'ceamcl'")


def test_workers_are_asked_each_within_a_bounded_time(scheduler: str) -> None:
    """Before: one `client.run` to every worker, which waits for good on a frozen one."""
    address = "tcp://" + scheduler.removeprefix("dask://")
    with distributed.Client(address, timeout="10s") as client:
        (worker,) = client.nthreads()
        answers, failed, silent = dask_workers.ask_workers(client, _answer, [worker], 10)
        assert (answers, failed, silent) == ({worker: 42}, {}, [])
        answers, failed, silent = dask_workers.ask_workers(
            client, _raises_on_the_worker, [worker], 10
        )
        assert answers == {} and silent == []
        assert isinstance(failed[worker], ModuleNotFoundError)
        with _frozen(address, worker):
            start = time.monotonic()
            answers, failed, silent = dask_workers.ask_workers(client, _answer, [worker], 1.0)
            assert time.monotonic() - start < 10
        assert (answers, failed, silent) == ({}, {}, [worker])


def test_a_frozen_worker_is_named_before_the_first_trial(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before: the command sat at its first line (7 min measured, then killed) on a scheduler
    one of whose workers was stopped with SIGSTOP."""
    monkeypatch.setattr(dask_workers, "CHECK_WAIT_S", 1.0)
    cluster, spec = _start(2)
    address = "tcp://" + spec.removeprefix("dask://")
    try:
        with distributed.Client(address, timeout="10s") as client:
            client.wait_for_workers(2, timeout=60)
            frozen, _ = sorted(client.nthreads())
        with _frozen(address, frozen):
            with pytest.raises(ConfigError) as caught:
                dask_workers._within(lambda: open_executor(spec).__enter__(), 60)
        assert f"1 of the 2 Dask workers at {spec.removeprefix('dask://')} did not answer" in str(
            caught.value
        )
        assert f"{frozen}: no answer within 1 s" in str(caught.value)
    finally:
        cluster.close()  # type: ignore[attr-defined]


def test_a_scheduler_that_stops_answering_while_the_workers_are_asked_is_named() -> None:
    def frozen(*args: object, **kwargs: object) -> None:
        raise TimeoutError  # as Dask's sync call past its callback_timeout

    client = SimpleNamespace(
        run_on_scheduler=lambda *a, **k: {},
        wait_for_workers=lambda n, timeout: None,
        nthreads=lambda callback_timeout: {"tcp://10.0.0.8:40000": 1},
        run=lambda *a, **k: None,
        sync=frozen,
    )
    with pytest.raises(ConfigError, match=r"scheduler at 10.0.0.7:8786 did not answer within"):
        dask_workers.prepare(client, "10.0.0.7:8786")  # type: ignore[arg-type]


def test_a_worker_that_freezes_while_trials_run_is_named_then_the_run_stops(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before: a trial sent to a worker stopped with SIGSTOP held the command until the
    scheduler's worker-ttl acted (586 s measured), or for good where it is off."""
    monkeypatch.setattr(executors, "WATCH_S", 0.2)
    cluster, spec = _start(1)
    address = "tcp://" + spec.removeprefix("dask://")
    try:
        with open_executor(spec) as ex:
            assert isinstance(ex, dask_workers.SchedulerExecutor)
            ex.warn_s, ex.silent_s = 3.0, 6.0  # a live worker beats every 0.5 s
            with distributed.Client(address, timeout="10s") as client:
                (worker,) = client.nthreads()
            with _frozen(address, worker):
                with (
                    pytest.warns(RunWarning, match=rf"{worker} .* no heartbeat for 3 s"),
                    pytest.raises(ConfigError, match=rf"{worker} .* no heartbeat for 6 s"),
                ):
                    dask_workers._within(  # a wait for good fails the test instead
                        lambda: executors.map_trials(ex, abs, [-1], label="trials", quiet=True),
                        60,
                    )
    finally:
        cluster.close()  # type: ignore[attr-defined]


def test_trials_completing_while_the_executor_is_watched_come_back_once_each(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(executors, "WATCH_S", 0.01)
    watched: list[int] = []

    class Watched(ThreadPoolExecutor):
        def stalled(self) -> None:
            watched.append(1)

    with Watched(2) as ex:
        got = executors.map_trials(ex, _slowly, list(range(40)), label="trials", quiet=True)
    assert got == [2 * i for i in range(40)]
    assert watched  # asked while trials were still running


def _slowly(i: int) -> int:
    time.sleep(0.005)
    return 2 * i
