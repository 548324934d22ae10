"""Where experiment trials run: this process, local worker processes, or a Dask cluster.

Every experiment hands its trials to a :class:`concurrent.futures.Executor` chosen by a short
spec string, so one code path serves a laptop and a cluster::

    with open_executor("local", workers=2) as ex:
        results = map_trials(ex, run_trial, trials, label="table1")

Specs:

``"serial"``
    Runs each trial in this process when it is submitted (tests, debugging, profiling).
``"local"``
    A :class:`~concurrent.futures.ProcessPoolExecutor` with ``workers`` processes
    (default ``os.cpu_count()``), started with ``spawn`` because the numba kernels run threads,
    which ``fork`` does not copy safely.
``"dask"``
    A local Dask distributed cluster (``workers`` single-threaded worker processes),
    through :meth:`dask.distributed.Client.get_executor`.
``"dask://HOST:PORT"``
    An existing Dask scheduler at ``tcp://HOST:PORT``; its workers are checked (the same
    software as this process), given this process's memory budget and their kernels loaded
    before the first trial (:mod:`ceamcl.experiments.dask_workers`).

Trial functions must be top-level functions of an importable module and take and return
picklable values (plain dataclasses, numpy arrays). A trial's numbers depend only on its own
seed, never on which executor or worker ran it.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

import numba

from ceamcl import budget
from ceamcl.errors import CeamclError, ConfigError
from ceamcl.maps.grid import OccupancyGrid

T = TypeVar("T")
R = TypeVar("R")

#: ``progress(label, done, total)``: how far a batch of trials is; the front end supplies it.
ProgressCallback = Callable[[str, int, int], None]

EXECUTOR_SPECS: tuple[str, ...] = ("local", "serial", "dask", "dask://HOST:PORT")

#: How often :func:`map_trials` asks an executor that can stall (a Dask scheduler whose
#: workers may all leave) whether its trials can still run, while none completes.
WATCH_S = 2.0


class TrialError(CeamclError, RuntimeError):
    """A trial failed on bad input (a :class:`CeamclError` inside a trial), naming the trial."""


class SerialExecutor(Executor):
    """Runs each submitted call at once, in this process; the future is already done."""

    def __init__(self) -> None:
        self._shutdown = False

    def submit(self, fn: Callable[..., R], /, *args: Any, **kwargs: Any) -> Future[R]:
        if self._shutdown:
            raise RuntimeError("cannot submit to a SerialExecutor after shutdown")
        future: Future[R] = Future()
        try:
            result = fn(*args, **kwargs)
        except Exception as exc:  # a trial's error, read from its future as a pool's would be
            future.set_exception(exc)
        else:  # Ctrl-C and SIGTERM (BaseException) stop the run here, not after every trial
            future.set_result(result)
        return future

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._shutdown = True


def _single_threaded_worker(memory_bytes: int) -> None:
    """Worker initialiser: one numba thread per worker process, so ``workers`` processes use
    ``workers`` cores rather than each spreading its kernels over every core; Ctrl-C ignored
    (a terminal sends it to the whole process group: the command ends its workers itself, and
    each printed a traceback); the command's memory budget (``--memory-budget``, which was
    set in the command's process only, so the executors' numbers differed).

    Numba has read ``NUMBA_NUM_THREADS`` by then (this module imports it, through the map), so
    the count is set for the thread that runs the trials; setting the variable instead made
    every later compilation in the worker fail ("cannot set NUMBA_NUM_THREADS to a different
    value once the threads have been launched")."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    budget.install(budget.Budget(memory_bytes))
    numba.set_num_threads(1)


#: What a worker process holds (the interpreter, NumPy, SciPy, Numba, a map): about 185 MB
#: measured; counted against the memory budget before any is started.
WORKER_BYTES = 256 * 1024 * 1024


def worker_count(workers: int | None, each_bytes: int = 0) -> int:
    """The worker count. Each worker holds :data:`WORKER_BYTES` and ``each_bytes`` more (what
    its trials build: a filter's layers of a large map, :data:`ceamcl.budget.FILTER_CELL_BYTES`
    a cell), and together they share the command's memory budget. By default as many as
    there are CPUs and as the budget holds, at least one; a count asked for is refused where
    they would not fit (``--workers 64`` started 64 processes unchecked, and the CPU count of
    workers, each building a filter on a map of 40 million cells, could ask for several times
    the machine's memory)."""
    each = WORKER_BYTES + max(0, int(each_bytes))
    if workers is None:
        fits = budget.current().memory_bytes // each
        return int(max(1, min(os.cpu_count() or 1, fits)))
    if workers < 1:
        raise ConfigError(f"workers: expected a positive count, got {workers}")
    what = "worker processes"
    if each_bytes > 0:
        what += f" ({budget.format_bytes(each_bytes)} each for their trials' map)"
    budget.require("--workers", workers, each, what)
    return workers


def filter_bytes(grid: OccupancyGrid) -> int:
    """What a worker building filters on ``grid`` holds for it: the ``worker_bytes`` of
    :func:`open_executor` for trials on a log's map."""
    return int(grid.data.size) * budget.FILTER_CELL_BYTES


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ConfigError(
            "executor: Dask is not installed; install the extra with "
            "`pip install 'ceamcl[distributed]'` or use --executor local"
        ) from None
    return distributed


def _end_workers(pool: ProcessPoolExecutor) -> None:
    """The run stops (a trial failed, Ctrl-C, SIGTERM): end the worker processes now rather
    than wait for the trials they are running (``shutdown`` would wait; a SIGTERM sent to the
    command alone does not reach them)."""
    processes = getattr(pool, "_processes", None) or {}
    for process in list(processes.values()):
        if process.is_alive():
            process.terminate()
    pool.shutdown(wait=True, cancel_futures=True)


def _scheduler(spec: str) -> tuple[str, str]:
    """``(host, port)`` of a ``dask://HOST:PORT`` spec; a :class:`ConfigError` otherwise."""
    host, sep, port = spec[len("dask://") :].rpartition(":")
    if not (sep and host and port.isascii() and port.isdigit() and 0 < int(port) < 65536):
        raise ConfigError(
            "executor: expected dask://HOST:PORT with PORT in 1-65535 (e.g. "
            f"dask://10.0.0.5:8786), got {spec!r}"
        )
    return host, port


def check_executor(spec: str, workers: int | None = None, worker_bytes: int = 0) -> None:
    """Refuse an executor spec :func:`open_executor` would refuse (its form, not whether a
    Dask scheduler answers), and ``workers`` where the spec takes none or the memory budget
    does not hold them (each with ``worker_bytes`` for its trials), before any work."""
    if spec in ("serial", "local", "dask"):
        if workers is not None:
            worker_count(workers, worker_bytes)
        return
    if spec.startswith("dask://"):
        _scheduler(spec)
        if workers is not None:
            raise ConfigError(
                "workers: a Dask scheduler's workers are its own (start them with dask-worker); "
                f"expected no --workers with --executor {spec}"
            )
        return
    raise ConfigError(
        f"executor: unknown executor {spec!r}; expected one of {', '.join(EXECUTOR_SPECS)}"
    )


@contextmanager
def open_executor(
    spec: str = "local",
    workers: int | None = None,
    worker_bytes: int = 0,
    progress: ProgressCallback | None = None,
) -> Iterator[Executor]:
    """An executor for ``spec`` (see the module docstring), shut down on exit. ``worker_bytes``:
    what each worker's trials build beyond the interpreter; the local workers' count is bounded
    so that together they fit the memory budget (:func:`worker_count`). Each takes the
    command's budget for its own checks, so a trial's numbers do not depend on the count.
    ``progress``: how far a scheduler's own workers are with loading the kernels
    (``dask://HOST:PORT``, :func:`~ceamcl.experiments.dask_workers.prepare`).

    Raises :class:`ConfigError` for an unknown spec, a bad worker count or a missing Dask.
    """
    check_executor(spec, workers, worker_bytes)
    if spec == "serial":
        with SerialExecutor() as ex:
            yield ex
        return
    if spec == "local":
        n = worker_count(workers, worker_bytes)
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            max_workers=n,
            mp_context=ctx,
            initializer=_single_threaded_worker,
            initargs=(budget.current().memory_bytes,),
        ) as pool:
            try:
                yield pool
            except BaseException:
                _end_workers(pool)
                raise
        return
    if spec == "dask" or spec.startswith("dask://"):
        distributed = _import_distributed()
        if spec == "dask":
            n = worker_count(workers, worker_bytes)
            cluster = distributed.LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=40,  # logging.ERROR
                # before Numba is imported: the initialiser's set_num_threads holds for the
                # thread it runs in, and a Dask worker runs its tasks in another
                env={"NUMBA_NUM_THREADS": "1"},
            )
            client = distributed.Client(cluster)
            try:
                client.run(_single_threaded_worker, budget.current().memory_bytes)
                yield client.get_executor()
            finally:
                client.close()
                cluster.close()
            return
        host, port = _scheduler(spec)
        from ceamcl.experiments import dask_workers

        dask_workers.probe(host, int(port))
        try:
            client = distributed.Client(f"tcp://{host}:{port}", timeout="10s")
        except OSError as exc:
            raise ConfigError(
                f"executor: cannot reach the Dask scheduler at {host}:{port}: {exc}"
            ) from None
        remote: dask_workers.SchedulerExecutor | None = None
        try:
            where = f"{host}:{port}"
            dask_workers.prepare(client, where, progress)
            remote = dask_workers.SchedulerExecutor(client, where)
            yield remote
        finally:
            dask_workers.close(client, lost=remote is not None and remote.lost)
        return


def _describe(item: object) -> str:
    name = getattr(item, "name", None)
    if isinstance(name, str):
        return name
    text = repr(item)
    return text if len(text) <= 80 else text[:77] + "..."


def _as_completed(
    futures: Iterable[Future[R]], stalled: Callable[[], None] | None
) -> Iterator[Future[R]]:
    """The futures as they complete, as :func:`concurrent.futures.as_completed`; with
    ``stalled``, that check also runs every :data:`WATCH_S` (it raises to end the wait)."""
    if stalled is None:
        yield from as_completed(futures)
        return
    pending = set(futures)
    while pending:
        try:
            for future in as_completed(pending, timeout=WATCH_S):
                pending.discard(future)
                yield future
        except TimeoutError:
            stalled()


def map_trials(
    executor: Executor,
    fn: Callable[[T], R],
    items: Sequence[T],
    *,
    label: str,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
) -> list[R]:
    """``[fn(item) for item in items]`` on ``executor``, reporting progress over trials.

    All items are submitted at once; ``progress(label, done, total)`` is called once before
    any completes and again as each trial completes (in any order; the front end draws it,
    e.g. the CLI's progress bar); ``quiet`` reports nothing. The results come back in input
    order. A trial that raises stops the experiment: the trials
    not yet started are cancelled and the exception is re-raised naming the trial (its
    ``name`` attribute, else its repr). A :class:`CeamclError` becomes a :class:`TrialError`
    (one clean line on the command line); any other exception is re-raised as it is, with a
    note naming the trial, so its traceback is kept. An executor with a ``stalled()`` method
    (a Dask scheduler's, whose workers may all leave: :class:`~ceamcl.experiments.dask_workers.
    SchedulerExecutor`) is also asked every :data:`WATCH_S` whether they can still run; the
    :class:`CeamclError` it raises ends the wait (the trials left are cancelled).
    """
    report = None if quiet else progress
    total = len(items)
    results: list[Any] = [None] * total
    if report is not None:
        report(label, 0, total)
    futures: dict[Future[R], int] = {executor.submit(fn, item): i for i, item in enumerate(items)}
    stalled: Callable[[], None] | None = getattr(executor, "stalled", None)
    try:
        for done, future in enumerate(_as_completed(futures, stalled), start=1):
            i = futures[future]
            if future.cancelled():  # not by us: the executor ended it (Dask: scheduler lost)
                if stalled is not None:
                    stalled()
                raise TrialError(
                    f"{label}: trial {_describe(items[i])} was cancelled by the executor "
                    "before it finished"
                )
            exc = future.exception()
            if exc is not None:
                name = _describe(items[i])
                if isinstance(exc, CeamclError):
                    raise TrialError(f"trial {name} failed: {exc}") from exc
                if isinstance(exc, BrokenProcessPool):
                    # a worker died (killed, out of memory; or, from a script without a
                    # __main__ guard, at its start: spawn re-imports the script, which then
                    # opens an executor of its own): every pending trial gets this error, so
                    # the one named is only the first to surface
                    raise TrialError(
                        f"{label}: a worker process died while the trials ran (killed, or out "
                        "of memory? --memory-budget and --workers bound what they may take; "
                        "from a Python script: workers start with 'spawn', which imports the "
                        "script again, so its code must sit under "
                        "'if __name__ == \"__main__\":'); "
                        f"the first trial to report it was {name}"
                    ) from exc
                exc.add_note(f"(in trial {name} of {label})")
                raise exc
            results[i] = future.result()
            if report is not None:
                report(label, done, total)
    finally:
        for future in futures:
            future.cancel()
    return results


@dataclass(frozen=True)
class Batch:
    """Where a batch of trials runs (:func:`open_executor`'s ``spec`` and ``workers``) and
    whom it reports to (:func:`map_trials`' ``progress`` and ``quiet``)."""

    executor: str = "local"
    workers: int | None = None
    progress: ProgressCallback | None = None
    quiet: bool = False

    def run(
        self, fn: Callable[[T], R], items: Sequence[T], label: str, worker_bytes: int = 0
    ) -> list[R]:
        """:func:`map_trials` on a freshly opened executor whose workers each need
        ``worker_bytes`` for these trials (:func:`open_executor`)."""
        report = None if self.quiet else self.progress
        with open_executor(self.executor, self.workers, worker_bytes, report) as ex:
            return map_trials(ex, fn, items, label=label, progress=self.progress, quiet=self.quiet)
