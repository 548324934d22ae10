"""A Dask scheduler's own workers (``--executor dask://HOST:PORT``) made ready for trials.

The workers of an existing scheduler are other processes, usually on other machines, started by
``dask worker`` before the command. Before this module, the command sent them its trials as
they were and three things went wrong (measured 2026-12-01, one scheduler and one worker on
this machine, the worker's Numba cache empty as on a fresh machine):

- a scheduler without workers held the command at ``0/4`` for good (stopped after 60 s);
- a worker compiled the kernels inside its first trial: that trial's mean step was 11.7 ms,
  against 2.0-2.5 ms for the other seven of ``table1 --trials 2``, and Fig. 5 showed it;
- nothing checked that a worker ran the same code: a trial's numbers depend only on its seed
  for the same ``ceamcl``, NumPy, SciPy, Numba and Python, and a worker with another checkout
  (an editable install keeps its version while its code changes) gave other numbers silently;
- and (2026-12-02) once every worker had left, the command waited for good; with a worker
  stopped by SIGSTOP it sat at its first line (7 min, until killed), and a worker that froze
  mid-run held it, saying nothing, until the scheduler's worker-ttl acted (or for good).

docs/experiments.md lists what else was measured and mended (the address probed before Dask
connects, a lost or frozen scheduler, the plugin of a killed command, one command at a time).

:func:`prepare` waits a bounded time for a worker, refuses workers whose software differs from
the command's (naming them and what differs), gives every worker the command's memory budget
(as the local executors do, so a trial's checks do not depend on where it ran) through a
worker plugin that also refuses, at its start, a worker that joins later with other software,
and runs :func:`ceamcl.warmup.warm_up` on every worker before the first trial (compiling
there what its cache lacks, in parallel on every worker; a worker that joins later does it at
its start). Every worker is asked within a bounded time (:func:`ask_workers`); one that does
not answer is named. :class:`SchedulerExecutor` ends a run whose workers have all left after
:data:`WORKER_WAIT_S`, names a worker that stops beating, and ends the run if the scheduler
keeps it.
"""

from __future__ import annotations

import asyncio
import functools
import hashlib
import logging
import platform
import socket
import struct
import threading
import time
import warnings
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, Future
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import numba
import numpy as np
import scipy
from distributed import Client, Worker, wait
from distributed.diagnostics.plugin import WorkerPlugin

import ceamcl
from ceamcl import budget
from ceamcl.errors import ConfigError, RunWarning
from ceamcl.warmup import warm_up

R = TypeVar("R")

#: How long :func:`prepare` waits for the scheduler to have a worker before it gives up, and
#: how long a run waits when every worker has left (:class:`SchedulerExecutor`).
WORKER_WAIT_S = 30.0

#: How long the command waits for the Dask scheduler to greet it (:func:`probe`).
GREETING_WAIT_S = 10.0

#: How long a running command waits for the scheduler to say how many workers it has.
ANSWER_WAIT_S = 10.0

#: A scheduler's greeting (its comm's handshake) is a few hundred bytes.
GREETING_MAX_BYTES = 1 << 20

#: How long :func:`prepare` waits for every worker to say what software it runs (importing
#: NumPy, SciPy, Numba and ceamcl, about 1 s in a new worker process): Dask's ``client.run``
#: waits for good on a worker that does not answer (one stopped with SIGSTOP, measured
#: 2026-12-02: the command sat at its first line for 7 min, until it was killed).
CHECK_WAIT_S = 30.0

#: A worker whose heartbeat has not reached the scheduler for :data:`SILENT_WARN_S` while
#: trials run is frozen (stopped with SIGSTOP, swapping, cut off): the command says so
#: (:meth:`SchedulerExecutor.stalled`; a busy worker still beats, every 0.5-6 s by the
#: cluster's size, as Dask's event loop runs beside the trial). The scheduler restarts or drops
#: it after its ``worker-ttl`` (5 min by default; measured 2026-12-02, a worker with a nanny
#: restarted after 586 s) and its trials run elsewhere; where it keeps it (the ttl off) a trial
#: sent there waits for good, so after :data:`SILENT_WAIT_S` the command stops.
SILENT_WARN_S = 60.0
SILENT_WAIT_S = 900.0

#: How long a worker may take to load (and compile) the kernels: 18 s on 2 cores when none is
#: cached; a worker that leaves meanwhile would hold the command for good.
WARM_UP_WAIT_S = 300.0

#: The progress bar's label while the workers load the kernels.
WARM_UP_LABEL = "kernels on the Dask workers"

#: The start of the worker plugin's name; the rest is the command's Dask client id, so a
#: command's plugin is told from one a killed command left (whose client is gone).
PLUGIN_PREFIX = "ceamcl-trials"


@cache
def software() -> dict[str, str]:
    """What a trial's numbers depend on besides its seed: Python's, NumPy's, SciPy's, Numba's
    and ceamcl's versions, and a digest of ceamcl's sources (every ``.py`` file of the package,
    its path and its bytes)."""
    root = Path(ceamcl.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "ceamcl": ceamcl.__version__,
        "ceamcl sources": digest.hexdigest()[:16],
    }


def differences(theirs: dict[str, str], ours: dict[str, str]) -> list[str]:
    """``"numpy 2.1.0 here, 2.0.2 there"`` for each item that differs."""
    return [
        f"{key} {ours.get(key, 'absent')} here, {theirs.get(key, 'absent')} there"
        for key in sorted(set(ours) | set(theirs))
        if ours.get(key) != theirs.get(key)
    ]


class TrialWorker(WorkerPlugin):
    """On every worker of the scheduler, now and joining later: the command's memory budget;
    a worker whose software is not the command's is closed (with its nanny) before it takes a
    trial; every worker has its kernels loaded before its first trial (:func:`prepare`
    registers this plugin once the workers present have loaded them, within its bound, so
    here only a worker that joins later has anything to load).

    Dask catches a plugin's failure at a worker's start and lets the worker run (measured
    with distributed 2026.8: a late worker with another NumPy took and ran a task), so raising
    is not enough: the worker closes itself. The scheduler keeps the plugin for the workers
    to come until it is unregistered (:func:`release`): left there after the command, it
    closed every worker started later with other code, the next command's too."""

    # each command registers its own (plugin_name), so nothing is registered twice
    idempotent = False

    def __init__(self, memory_bytes: int, expected: dict[str, str]) -> None:
        self.memory_bytes = int(memory_bytes)
        self.expected = dict(expected)

    def refusal(self, worker: Worker) -> str | None:
        """Why ``worker`` may not run the command's trials, or ``None``."""
        differ = differences(self.expected, software())  # "here": this worker
        if not differ:
            return None
        return (
            f"Dask worker {worker.address} runs other software than the command that sent the "
            f"trials ({'; '.join(differ)}): it closes"
        )

    async def setup(self, worker: Worker) -> None:
        why = self.refusal(worker)
        if why is not None:
            # after this setup returns: the worker's start goes on, then closes
            worker.loop.add_callback(worker.close, nanny=True, reason="ceamcl-other-software")
            raise ConfigError(why)
        budget.install(budget.Budget(self.memory_bytes))
        # loaded already (prepare's task) or, on a worker that joined later, loaded now:
        # the scheduler may have sent it trials, which it reads only once this returns; a
        # thread keeps its event loop (and comms) going
        await asyncio.to_thread(warm_up)


def plugin_name(client: Client) -> str:
    """The name of ``client``'s command's :class:`TrialWorker` on the scheduler."""
    return f"{PLUGIN_PREFIX}:{client.id}"


def _ceamcl_plugins(dask_scheduler: Any) -> dict[str, bool]:
    """On the scheduler: the ceamcl plugins it holds, each with whether its command's client
    is still connected."""
    return {
        name: name.partition(":")[2] in dask_scheduler.clients
        for name in dask_scheduler.worker_plugins
        if name.startswith(PLUGIN_PREFIX)
    }


def _within(what: Callable[[], R], wait_s: float) -> R:
    """``what()`` in a daemon thread, waited for at most ``wait_s``: its result or its
    exception, or :class:`TimeoutError` (the thread is then left to end on its own: Dask's
    calls to a frozen scheduler take no timeout of their own)."""
    box: list[Any] = []

    def run() -> None:
        try:
            box.append((True, what()))
        except BaseException as exc:  # handed to the caller
            box.append((False, exc))

    thread = threading.Thread(target=run, name="ceamcl-dask-call", daemon=True)
    thread.start()
    thread.join(wait_s)
    if not box:
        raise TimeoutError
    ok, value = box[0]
    if not ok:
        raise value
    return value


def ask_workers(
    client: Client, fn: Callable[[], R], addresses: Iterable[str], wait_s: float
) -> tuple[dict[str, R], dict[str, BaseException], list[str]]:
    """``fn()`` run on each worker of ``addresses`` (Dask's ``client.run``), every one waited
    for at most ``wait_s``, all at once: the answers, the errors the workers raised (one that
    cannot import ceamcl), and the workers that did not answer in time, by address; one that
    left meanwhile is in none of them."""
    wanted = list(addresses)

    async def one(address: str) -> tuple[str, Any]:
        try:
            call = client.run(fn, workers=[address], asynchronous=True)
            answer = await asyncio.wait_for(call, wait_s)
        except TimeoutError:
            return address, None
        except Exception as exc:  # raised on the worker, or the worker left meanwhile
            return address, exc
        if address not in answer:  # it left meanwhile: nothing to ask it
            return address, ()
        return address, (answer[address],)

    async def every() -> list[tuple[str, Any]]:
        return list(await asyncio.gather(*(one(address) for address in wanted)))

    answers: dict[str, R] = {}
    failed: dict[str, BaseException] = {}
    silent: list[str] = []
    for address, got in client.sync(every, callback_timeout=wait_s + ANSWER_WAIT_S):
        if got is None:
            silent.append(address)
        elif isinstance(got, BaseException):
            failed[address] = got
        elif got:
            answers[address] = got[0]
    return answers, failed, sorted(silent)


def release(client: Client, names: Iterable[str], wait_s: float | None = None) -> None:
    """Unregisters those of the plugins ``names`` the scheduler holds, from it and its
    workers, waiting at most ``wait_s`` (:data:`ANSWER_WAIT_S`) for each call; what fails is
    ignored (the scheduler may be gone or frozen). Their budget stays installed on the workers
    (a worker plugin's teardown cannot tell what the worker had before); the next command
    installs its own."""
    wait = ANSWER_WAIT_S if wait_s is None else wait_s
    try:
        held = _within(lambda: client.run_on_scheduler(_ceamcl_plugins), wait)
        for name in [n for n in names if n in held]:
            _within(functools.partial(client.unregister_worker_plugin, name), wait)
    except Exception:  # the scheduler is gone or frozen, or the plugin went meanwhile
        pass


def close(client: Client, lost: bool = False) -> None:
    """Ends the command's connection: its plugin unregistered (:func:`release`) while the
    scheduler answers; where it was ``lost`` (or the client says so), Dask's log of the
    reconnection it then cancels (a 30-line ``CancelledError`` traceback on stderr) is kept
    quiet, as the command has said what happened in one line."""
    if not lost and client.status == "running":
        release(client, [plugin_name(client)])
        client.close()
        return
    log = logging.getLogger("distributed.client")
    level = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        client.close(timeout=ANSWER_WAIT_S)
    finally:
        log.setLevel(level)


def _warm_up() -> int:
    """On a worker: every kernel loaded or compiled; how many were compiled."""
    return warm_up().compiled


def probe(host: str, port: int, wait_s: float | None = None) -> None:
    """Checks, within a bounded time, that a Dask scheduler answers at ``host:port`` before
    Dask's client connects, which does not bound it: measured (distributed 2026.8), the
    client waited for good at an HTTP server's port (the scheduler's dashboard, 8787, is the
    usual slip for its 8786) and, at a service that answered with other bytes, tried to
    allocate 3 EiB for what it took for a message's length. A scheduler speaks first: its
    handshake, a frame whose first 8 bytes give its length (little-endian), a few hundred.
    Raises :class:`ConfigError` naming the address and what was found."""
    wait = GREETING_WAIT_S if wait_s is None else float(wait_s)
    where = f"{host}:{port}"
    name = host[1:-1] if host.startswith("[") and host.endswith("]") else host  # IPv6
    deadline = time.monotonic() + wait
    head = b""
    try:
        with socket.create_connection((name, port), timeout=wait) as sock:
            while len(head) < 8:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError
                sock.settimeout(left)
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        raise ConfigError(
            f"executor: nothing at {where} answered as a Dask scheduler within {wait:.0f} s "
            "(a scheduler speaks first; is it the dashboard's port? a scheduler listens on "
            "8786 unless told otherwise)"
        ) from None
    except OSError as exc:
        raise ConfigError(f"executor: cannot reach the Dask scheduler at {where}: {exc}") from None
    if len(head) < 8:
        raise ConfigError(
            f"executor: {where} closed the connection without answering as a Dask scheduler"
        )
    (size,) = struct.unpack("<Q", head)
    if not 0 < size <= GREETING_MAX_BYTES:
        raise ConfigError(
            f"executor: {where} answered, but not as a Dask scheduler (its first message "
            f"claims {size} bytes; a scheduler's greeting is a few hundred): is it the "
            "scheduler's address?"
        )


def _no_answer(where: str, wait_s: float) -> ConfigError:
    """The error of a scheduler that greeted the command and then stopped answering."""
    return ConfigError(
        f"executor: the Dask scheduler at {where} did not answer within {wait_s:.0f} s (frozen?)"
    )


def prepare(
    client: Client, where: str, progress: Callable[[str, int, int], None] | None = None
) -> dict[str, int]:
    """Make the workers of the scheduler at ``where`` (``HOST:PORT``) ready for trials (the
    module docstring); the count of kernels each worker compiled, by address. Raises
    :class:`ConfigError` where no worker comes within :data:`WORKER_WAIT_S` or a worker's
    software differs from this command's. ``progress(label, done, total)`` counts the workers
    that have loaded the kernels (up to 25 s each where their cache is empty)."""
    ours = software()
    try:
        plugins: dict[str, bool] = client.run_on_scheduler(
            _ceamcl_plugins, callback_timeout=ANSWER_WAIT_S
        )
    except TimeoutError:
        raise _no_answer(where, ANSWER_WAIT_S) from None
    except Exception as exc:  # the scheduler cannot import this module: no or another ceamcl
        raise ConfigError(
            f"executor: the Dask scheduler at {where} cannot import ceamcl's code ({exc}); "
            "it unpickles every trial it hands out, so it needs ceamcl installed as its "
            "workers do"
        ) from None
    running = sorted(name.partition(":")[2] for name, live in plugins.items() if live)
    if running:
        raise ConfigError(
            f"executor: another ceamcl command ({', '.join(running)}) is running trials on the "
            f"Dask scheduler at {where}; its workers hold that command's memory budget and "
            "checks, so run one command at a time on a scheduler (or start another one)"
        )
    # plugins that killed commands left: they would check later workers against their code
    release(client, [name for name, live in plugins.items() if not live])
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except TimeoutError:
        raise ConfigError(
            f"executor: the Dask scheduler at {where} has no workers (waited "
            f"{WORKER_WAIT_S:.0f} s); start them with `dask worker tcp://{where}`"
        ) from None
    try:
        addresses = list(client.nthreads(callback_timeout=ANSWER_WAIT_S))
    except TimeoutError:
        raise _no_answer(where, ANSWER_WAIT_S) from None
    try:
        found, failed, silent = ask_workers(client, software, addresses, CHECK_WAIT_S)
    except TimeoutError:  # the outer bound: the scheduler itself stopped answering
        raise _no_answer(where, CHECK_WAIT_S + ANSWER_WAIT_S) from None
    # the scheduler could not reach them (Dask's comm errors are OSErrors)
    unreachable = {a: exc for a, exc in failed.items() if isinstance(exc, OSError)}
    failed = {a: exc for a, exc in failed.items() if a not in unreachable}
    if silent or unreachable:  # those that left meanwhile are not asked for trials
        try:
            still = set(client.nthreads(callback_timeout=ANSWER_WAIT_S))
        except TimeoutError:
            still = set(addresses)
        silent = [a for a in silent if a in still]
        unreachable = {a: exc for a, exc in unreachable.items() if a in still}
    if silent or unreachable:
        why = [f"{address}: no answer within {CHECK_WAIT_S:.0f} s" for address in silent]
        why += [f"{a}: {type(exc).__name__}: {exc}" for a, exc in sorted(unreachable.items())]
        raise ConfigError(
            f"executor: {len(why)} of the {len(addresses)} Dask workers at {where} did not "
            f"answer ({'; '.join(why)}): frozen (stopped, or swapping) or cut off from the "
            "scheduler, which would send them trials until its worker-ttl restarts or drops "
            "them (5 min by default, or never); end or restart them and run the command again"
        )
    if failed:
        lines = "; ".join(
            f"{address}: {type(exc).__name__}: {exc}" for address, exc in sorted(failed.items())
        )
        raise ConfigError(
            f"executor: {len(failed)} of the {len(addresses)} Dask workers at {where} cannot "
            f"run ceamcl's code ({lines}); install the same ceamcl and libraries on every "
            "worker"
        )
    differ = {address: differences(theirs, ours) for address, theirs in found.items()}
    differ = {address: d for address, d in differ.items() if d}
    if differ:
        lines = "; ".join(f"{address}: {', '.join(d)}" for address, d in sorted(differ.items()))
        raise ConfigError(
            f"executor: {len(differ)} of the {len(found)} Dask workers at {where} run other "
            f"software than this command ({lines}); a trial's numbers would depend on the "
            "worker that ran it: install the same ceamcl and libraries on every worker"
        )
    futures: dict[str, Any] = {
        address: client.submit(
            _warm_up,
            workers=[address],
            allow_other_workers=False,
            pure=False,
        )
        for address in found
    }
    pending = list(futures.values())
    deadline = time.monotonic() + WARM_UP_WAIT_S
    try:
        while pending:
            if progress is not None:
                progress(WARM_UP_LABEL, len(futures) - len(pending), len(futures))
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            pending = list(wait(pending, timeout=left, return_when="FIRST_COMPLETED").not_done)
        if progress is not None:
            progress(WARM_UP_LABEL, len(futures), len(futures))
    except TimeoutError:
        late = sorted(address for address, future in futures.items() if not future.done())
        raise ConfigError(
            f"executor: the Dask workers {', '.join(late)} at {where} did not load ceamcl's "
            f"kernels within {WARM_UP_WAIT_S:.0f} s (did they leave the scheduler?)"
        ) from None
    compiled = {address: int(future.result()) for address, future in futures.items()}
    plugin = TrialWorker(budget.current().memory_bytes, ours)
    try:
        _within(lambda: client.register_plugin(plugin, name=plugin_name(client)), WARM_UP_WAIT_S)
    except TimeoutError:
        raise ConfigError(
            f"executor: the Dask workers at {where} did not all take ceamcl's worker plugin "
            f"within {WARM_UP_WAIT_S:.0f} s (a worker frozen, or one that joined meanwhile "
            "still loading the kernels)"
        ) from None
    except (ConfigError, OSError):
        # the scheduler stores the plugin before it hands it to the workers: a worker that
        # joined meanwhile with other software refused it (and closes), or one left meanwhile
        pass
    return compiled


class SchedulerExecutor(Executor):
    """The executor of a Dask scheduler's own workers (``client.get_executor()``), which
    :func:`~ceamcl.experiments.executors.map_trials` also asks whether its trials can still
    run. The scheduler keeps them waiting for good when every worker has left (measured
    2026-12-02: the command sat at its last count after the only worker was stopped) and
    sends them to a worker that froze (stopped with SIGSTOP, swapping, cut off), which it
    never drops; so :meth:`stalled` raises after :data:`WORKER_WAIT_S` without a worker, or
    once a worker has sent the scheduler no heartbeat for :data:`SILENT_WAIT_S`."""

    def __init__(self, client: Client, where: str, wait_s: float | None = None) -> None:
        self._client = client
        self._inner = client.get_executor()
        self.where = where
        self.wait_s = WORKER_WAIT_S if wait_s is None else float(wait_s)
        #: a worker silent this long is named, and this long ends the command
        self.warn_s, self.silent_s = SILENT_WARN_S, SILENT_WAIT_S
        self._empty_since: float | None = None
        #: each worker's last heartbeat as the scheduler has it (its clock), and when this
        #: command last saw it change (this command's clock)
        self._beats: dict[str, tuple[float, float]] = {}
        self._named: set[str] = set()  # the silent workers already named
        #: the scheduler was lost (or stopped answering) while trials ran
        self.lost = False

    def submit(self, fn: Callable[..., R], /, *args: Any, **kwargs: Any) -> Future[R]:
        return self._inner.submit(fn, *args, **kwargs)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._inner.shutdown(wait=wait)

    def stalled(self) -> None:
        """Raises :class:`ConfigError` once the scheduler has had no worker for
        :attr:`wait_s`, once a worker has been silent for :attr:`silent_s`, or when the
        scheduler is lost; does nothing otherwise."""
        lost = (
            f"executor: lost the Dask scheduler at {self.where} while trials ran (stopped, or "
            "the network between them failed); the trials it held are gone"
        )
        self.lost = True  # until it answers
        if self._client.status != "running":  # it reconnects, or gave up
            raise ConfigError(lost)
        try:
            # Dask's scheduler_info takes no timeout of its own
            info = _within(lambda: self._client.scheduler_info(n_workers=-1), ANSWER_WAIT_S)
        except TimeoutError:
            raise ConfigError(f"{lost} (it did not answer within {ANSWER_WAIT_S:.0f} s)") from None
        except Exception as exc:  # the scheduler left or the connection broke
            raise ConfigError(f"{lost} ({exc})") from None
        self.lost = False
        now = time.monotonic()
        workers: dict[str, Any] = dict(info.get("workers") or {})
        self._watch(workers, now)
        if workers:
            self._empty_since = None
            return
        if self._empty_since is None:
            self._empty_since = now
        elif now - self._empty_since >= self.wait_s:
            raise ConfigError(
                f"executor: every worker of the Dask scheduler at {self.where} left while "
                f"trials ran and none came back within {self.wait_s:.0f} s; start them with "
                f"`dask worker tcp://{self.where}` and run the command again"
            )

    def _watch(self, workers: dict[str, Any], now: float) -> None:
        """Follows each worker's heartbeat (``last_seen``, compared with itself only: the
        scheduler's clock may not be this machine's): names a worker silent for
        :attr:`warn_s` once (a :class:`RunWarning`) and raises once one has been silent for
        :attr:`silent_s`."""
        beats: dict[str, tuple[float, float]] = {}
        for address, worker in workers.items():
            seen = float(worker.get("last_seen", float("nan")))
            before = self._beats.get(address)
            if before is None or seen != before[0] or not np.isfinite(seen):
                before = (seen, now)  # new, beating, or a scheduler that does not say
            beats[address] = before
        self._beats = beats
        silent = {a: now - since for a, (_, since) in beats.items() if now - since >= self.warn_s}
        self._named &= set(silent)  # one that beats again is named again if it freezes
        stopped = sorted(a for a, quiet in silent.items() if quiet >= self.silent_s)
        if stopped:
            raise ConfigError(
                f"executor: the Dask worker{'s' if len(stopped) > 1 else ''} "
                f"{', '.join(stopped)} at {self.where} sent the scheduler no heartbeat for "
                f"{self.silent_s:.0f} s while trials ran and the scheduler kept "
                f"{'them' if len(stopped) > 1 else 'it'} (frozen: stopped, swapping, or cut "
                "off; its worker-ttl off?), so the trials sent there would wait for good; "
                "end or restart it and run the command again"
            )
        for address in sorted(set(silent) - self._named):
            self._named.add(address)
            warnings.warn(
                f"executor: the Dask worker {address} at {self.where} has sent the scheduler "
                f"no heartbeat for {self.warn_s:.0f} s (frozen: stopped, swapping, or cut "
                "off); the scheduler restarts or drops such a worker after its worker-ttl "
                "(5 min by default) and runs its trials elsewhere; the command waits for that "
                f"at most {self.silent_s / 60:.0f} min",
                RunWarning,
                stacklevel=2,
            )
