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
  (an editable install keeps its version while its code changes) gave other numbers silently.

:func:`prepare` waits a bounded time for a worker, refuses workers whose software differs from
the command's (naming them and what differs), gives every worker the command's memory budget
(as the local executors do, so a trial's checks do not depend on where it ran) through a
worker plugin that also refuses, at its start, a worker that joins later with other software,
and runs :func:`ceamcl.warmup.warm_up` on every worker before the first trial (compiling
there what its cache lacks, in parallel on every worker).
"""

from __future__ import annotations

import hashlib
import platform
from functools import cache
from pathlib import Path
from typing import Any

import numba
import numpy as np
import scipy
from distributed import Client, Worker, wait
from distributed.diagnostics.plugin import WorkerPlugin

import ceamcl
from ceamcl import budget
from ceamcl.errors import ConfigError
from ceamcl.warmup import warm_up

#: How long :func:`prepare` waits for the scheduler to have a worker before it gives up.
WORKER_WAIT_S = 30.0

#: How long a worker may take to load (and compile) the kernels: 18 s on 2 cores when none is
#: cached; a worker that leaves meanwhile would hold the command for good.
WARM_UP_WAIT_S = 300.0

#: The worker plugin's name: registering it again (the next command) replaces it.
PLUGIN_NAME = "ceamcl-trials"


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
    """On every worker of the scheduler, now and joining later: the command's memory budget,
    and a refusal (the worker does not start) where its software is not the command's."""

    idempotent = False  # a later command's plugin, with its budget, replaces an earlier one

    def __init__(self, memory_bytes: int, expected: dict[str, str]) -> None:
        self.memory_bytes = int(memory_bytes)
        self.expected = dict(expected)

    def setup(self, worker: Worker) -> None:
        differ = differences(software(), self.expected)
        if differ:
            raise ConfigError(
                f"Dask worker {worker.address} runs other software than the command that "
                f"sent the trials ({'; '.join(differ)})"
            )
        budget.install(budget.Budget(self.memory_bytes))


def _warm_up() -> int:
    """On a worker: every kernel loaded or compiled; how many were compiled."""
    return warm_up().compiled


def prepare(client: Client, where: str) -> dict[str, int]:
    """Make the workers of the scheduler at ``where`` (``HOST:PORT``) ready for trials (the
    module docstring); the count of kernels each worker compiled, by address. Raises
    :class:`ConfigError` where no worker comes within :data:`WORKER_WAIT_S` or a worker's
    software differs from this command's."""
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except TimeoutError:
        raise ConfigError(
            f"executor: the Dask scheduler at {where} has no workers (waited "
            f"{WORKER_WAIT_S:.0f} s); start them with `dask worker tcp://{where}`"
        ) from None
    ours = software()
    try:
        client.run_on_scheduler(software)
    except Exception as exc:  # the scheduler cannot import this module: no or another ceamcl
        raise ConfigError(
            f"executor: the Dask scheduler at {where} cannot import ceamcl's code ({exc}); "
            "it unpickles every trial it hands out, so it needs ceamcl installed as its "
            "workers do"
        ) from None
    found: dict[str, dict[str, str]] = client.run(software)
    differ = {address: differences(theirs, ours) for address, theirs in found.items()}
    differ = {address: d for address, d in differ.items() if d}
    if differ:
        lines = "; ".join(f"{address}: {', '.join(d)}" for address, d in sorted(differ.items()))
        raise ConfigError(
            f"executor: {len(differ)} of the {len(found)} Dask workers at {where} run other "
            f"software than this command ({lines}); a trial's numbers would depend on the "
            "worker that ran it: install the same ceamcl and libraries on every worker"
        )
    client.register_plugin(TrialWorker(budget.current().memory_bytes, ours), name=PLUGIN_NAME)
    futures: dict[str, Any] = {
        address: client.submit(
            _warm_up,
            workers=[address],
            allow_other_workers=False,
            pure=False,
        )
        for address in found
    }
    try:
        wait(list(futures.values()), timeout=WARM_UP_WAIT_S)
    except TimeoutError:
        late = sorted(address for address, future in futures.items() if not future.done())
        raise ConfigError(
            f"executor: the Dask workers {', '.join(late)} at {where} did not load ceamcl's "
            f"kernels within {WARM_UP_WAIT_S:.0f} s (did they leave the scheduler?)"
        ) from None
    return {address: int(future.result()) for address, future in futures.items()}
