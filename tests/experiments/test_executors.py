"""open_executor / map_trials: every spec gives the same results in input order; failures name
the trial; bad specs are clear errors."""

from __future__ import annotations

import functools
import math
import operator
import subprocess
import sys
from concurrent.futures import Future
from pathlib import Path

import pytest

from ceamcl.errors import ConfigError
from ceamcl.experiments.executors import SerialExecutor, TrialError, map_trials, open_executor
from ceamcl.filters import make_sensor


def test_serial_map_keeps_input_order() -> None:
    with open_executor("serial") as ex:
        assert isinstance(ex, SerialExecutor)
        out = map_trials(ex, operator.neg, [3, 1, 2], label="t", quiet=True)
    assert out == [-3, -1, -2]


def test_local_processes_give_the_same_results_as_serial() -> None:
    items = [0.5 * k for k in range(7)]
    with open_executor("serial") as ex:
        serial = map_trials(ex, math.exp, items, label="serial", quiet=True)
    with open_executor("local", workers=2) as ex:
        local = map_trials(ex, math.exp, items, label="local", quiet=True)
    assert local == serial


def test_failing_trial_is_named_and_keeps_its_type() -> None:
    with (
        open_executor("serial") as ex,
        pytest.raises(ValueError, match="math domain error") as info,
    ):
        map_trials(ex, math.sqrt, [1.0, -1.0], label="roots", quiet=True)
    assert any("-1.0" in note for note in info.value.__notes__)


def test_failing_trial_with_project_error_becomes_trial_error() -> None:
    with open_executor("serial") as ex, pytest.raises(TrialError, match="trial 'sonar'"):
        unknown_sensor = functools.partial(make_sensor, grid=None)
        map_trials(ex, unknown_sensor, ["sonar"], label="sensors", quiet=True)


@pytest.mark.parametrize(
    "spec", ["threads", "dask://nohost", "dask://host:port", "dask://h:99999", "dask://h:0", ""]
)
def test_unknown_spec_is_a_config_error(spec: str) -> None:
    with pytest.raises(ConfigError, match="executor"), open_executor(spec):
        pass


def test_bad_worker_count_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="workers"), open_executor("local", workers=0):
        pass


def _interrupt() -> None:
    raise KeyboardInterrupt


def test_serial_executor_stops_at_ctrl_c_instead_of_running_every_trial() -> None:
    """The serial executor stored Ctrl-C (and SIGTERM) in the trial's future and went on with
    every other trial; only then did the command stop."""
    ran: list[int] = []
    with SerialExecutor() as ex, pytest.raises(KeyboardInterrupt):
        ex.submit(_interrupt)
        ran.append(1)
    assert ran == []


def test_worker_processes_take_the_commands_memory_budget() -> None:
    """--memory-budget was set in the command's process only: local and Dask workers used the
    default, so CEAMCL's initialisation grid (sized by the budget) and its numbers differed."""
    from ceamcl import budget

    small = budget.Budget(300 * 1024 * 1024)
    with budget.use(small), open_executor("local", 1) as ex:
        seen = ex.submit(budget.current).result()
    assert seen.memory_bytes == small.memory_bytes
    with budget.use(budget.Budget(600 * 1024 * 1024)), pytest.raises(ConfigError, match="workers"):
        with open_executor("local", 4):  # 4 x 256 MiB of worker processes
            pass


def test_workers_holding_a_large_map_fit_the_memory_budget_together() -> None:
    """Each worker that builds filters on a log's map holds its layers (a CEAMCL on
    fr-clinic's 40 million cells: 1.9 GB). The CPU count of them was started whatever the map,
    and together could ask for several times the machine's memory. The default count is what
    the budget holds (at least one); a count that does not fit is refused, naming the map."""
    import os

    from ceamcl import budget
    from ceamcl.experiments.executors import check_executor, worker_count

    cpus = os.cpu_count() or 1
    large_map = 40_000_000 * budget.FILTER_CELL_BYTES  # 2.4 GiB a worker
    with budget.use(budget.Budget(6 << 30)):
        assert worker_count(None) == min(cpus, 24)  # 256 MiB each
        assert worker_count(None, large_map) == min(cpus, 2)
        assert worker_count(2, large_map) == 2
        with pytest.raises(ConfigError, match=r"--workers: 3 worker processes \(2.4 GiB each"):
            check_executor("local", 3, large_map)
    with budget.use(budget.Budget(2 << 30)):
        assert worker_count(None, large_map) == 1


def test_evaluate_log_counts_its_map_in_each_worker(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``evaluate-log`` tells the executor what its map costs each worker: with a filter's
    cost per cell raised so that two workers on the box's map exceed the budget, ``--workers
    2`` is refused before any trial runs, in one line, and leaves no folder behind."""
    from ceamcl import budget
    from ceamcl.cli import main
    from tests.robustness.hostile_cases import box_log_lines, write_lines

    write_lines("box.log", box_log_lines(30, neff=True))(tmp_path)
    out = tmp_path / "ev"
    argv = ["evaluate-log", str(tmp_path / "box.log"), "--algorithms", "mcl", "--quiet"]
    argv += ["--scans", "10", "--starts", "1", "--memory-budget", "1GiB", "--out", str(out)]
    # the box's map has about 10,000 cells: about 2.7 GB a worker
    monkeypatch.setattr(budget, "FILTER_CELL_BYTES", (1 << 30) // 4_000)
    assert main([*argv, "--workers", "2"]) == 2
    err = capsys.readouterr().err
    assert "--workers: 2 worker processes (" in err and "each for their trials' map" in err, err
    assert not out.exists()


def test_experiments_count_their_map_in_each_worker(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The experiments' workers build filters on the course's map (a route file may name any
    ROS map): counted as evaluate-log's are, before any trial runs."""
    from ceamcl import budget
    from ceamcl.cli import main

    monkeypatch.setattr(budget, "FILTER_CELL_BYTES", 1 << 20)  # the hall: 88 GiB a worker
    out = tmp_path / "t1"
    argv = ["experiment", "table1", "--trials", "1", "--algorithms", "mcl", "--quiet"]
    assert main([*argv, "--workers", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--workers: 2 worker processes (" in err and "each for their trials' map" in err, err
    assert not out.exists()


def _die(_: int) -> int:
    import os

    os._exit(9)  # as the out-of-memory killer ends a worker


def test_a_worker_that_dies_is_one_line_naming_what_happened() -> None:
    """A worker killed (out of memory) gave a 23-line BrokenProcessPool traceback."""
    with open_executor("local", 1) as ex, pytest.raises(TrialError, match="a worker process died"):
        map_trials(ex, _die, [1, 2], label="trials", quiet=True)


def test_a_script_without_a_main_guard_is_told_about_it(tmp_path: Path) -> None:
    """docs/experiments.md's examples, run as scripts without an ``if __name__ ==
    "__main__":`` guard, died in every spawned worker (which imports the script again and
    opens a pool of its own) and the error pointed to memory only: it names the guard too."""
    script = tmp_path / "trials.py"
    script.write_text(
        "import operator\n"
        "from ceamcl.experiments.executors import map_trials, open_executor\n"
        "with open_executor('local', workers=1) as ex:\n"
        "    print(map_trials(ex, operator.neg, [1, 2], label='my trials', quiet=True))\n"
    )
    proc = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=tmp_path,
    )
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("ceamcl.experiments.executors.TrialError: my trials: a worker")
    assert "'spawn'" in last and 'if __name__ == "__main__":' in last


def _compile_a_kernel() -> int:
    """Compile a Numba function in this process, as a worker does for each kernel its numba
    cache does not hold (a fresh clone, or a source edit)."""
    import numba

    return int(numba.njit(lambda x: x + 1)(1))


def test_a_worker_can_compile_a_kernel() -> None:
    """The worker's initialiser set ``NUMBA_NUM_THREADS`` after Numba had read it (importing
    this package imports Numba) and had started its threads, so every compilation in a worker
    re-read it and stopped with "Cannot set NUMBA_NUM_THREADS to a different value once the
    threads have been launched": `evaluate-log --workers 2` failed on a fresh clone, whose
    kernels are compiled in the first run, until a run without workers had cached them."""
    with open_executor("local", 1) as ex:
        assert ex.submit(_compile_a_kernel).result(timeout=120) == 2


def _kernel_threads() -> int:
    import numba

    return int(numba.get_num_threads())


@pytest.mark.parametrize("spec", ["local", "dask"])
def test_a_worker_runs_its_kernels_on_one_thread(spec: str) -> None:
    """N workers use N cores. A Dask worker runs its tasks in a thread of its own, where the
    initialiser's thread count did not hold: each ran its kernels on every core."""
    if spec == "dask":
        pytest.importorskip("distributed")
    with open_executor(spec, 1) as ex:
        assert ex.submit(_kernel_threads).result(timeout=120) == 1


class _Cancelling(SerialExecutor):
    """An executor that ends every trial before it runs, as Dask's does when it loses its
    scheduler."""

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[no-untyped-def]
        future: Future[object] = Future()
        future.cancel()
        future.set_running_or_notify_cancel()
        return future


def test_a_trial_the_executor_cancelled_is_one_line_naming_it() -> None:
    """Before: a bare CancelledError traceback (the Dask scheduler stopped mid-run)."""
    with pytest.raises(TrialError, match=r"^trials: trial -[23] was cancelled by the executor"):
        map_trials(_Cancelling(), abs, [-2, -3], label="trials", quiet=True)
