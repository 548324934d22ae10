"""Ctrl-C is never lost, even when it lands in a finaliser or a garbage collector's callback
(where Python prints "Exception ignored in ..." and drops it; seen in CI while llvmlite
finalised Numba's compiler output, and with hypothesis's gc callback installed)."""

from __future__ import annotations

import argparse
import gc
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numba
import numba.core.event
import pytest
from rich.console import Console

import ceamcl.cli as cli
from ceamcl.cli import interrupt
from ceamcl.io.results import ensure_output_dir


@pytest.fixture(autouse=True)
def _ctrl_c_as_at_a_terminal() -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt, as at a terminal, for each test here: a shell that
    starts the suite in the background (``make test &``) starts it with SIGINT ignored, and
    the command line then rightly leaves Ctrl-C alone (``interrupt.guard``)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class _InterruptedWhileFinalised:
    def __del__(self) -> None:
        signal.raise_signal(signal.SIGINT)


def _cli_running(monkeypatch: pytest.MonkeyPatch, run: Any, handles_ctrl_c: bool = False) -> None:
    def build_parser() -> argparse.ArgumentParser:
        parser = argparse.ArgumentParser()
        parser.set_defaults(run=run, memory_budget=None, handles_ctrl_c=handles_ctrl_c)
        return parser

    monkeypatch.setattr(cli, "build_parser", build_parser)


def _finalise_during_sigint() -> None:
    obj = _InterruptedWhileFinalised()
    del obj
    gc.collect()


def test_an_interrupt_in_a_finaliser_stops_a_command_that_runs_on(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    reached: list[float] = []

    def run(args: argparse.Namespace, console: Console) -> int:
        _finalise_during_sigint()
        start = time.monotonic()
        while time.monotonic() - start < 5.0:
            time.sleep(0.01)
        reached.append(time.monotonic() - start)
        return 0

    _cli_running(monkeypatch, run)
    assert cli.main([]) == 130
    assert not reached, "the command ran to its end after Ctrl-C"
    assert capsys.readouterr().err.strip().splitlines()[-1] == "ceamcl: interrupted"


def test_an_interrupt_in_a_finaliser_just_before_the_end_still_counts(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new"

    def run(args: argparse.Namespace, console: Console) -> int:
        ensure_output_dir(out)
        _finalise_during_sigint()
        return 0  # before the interrupt is raised again

    _cli_running(monkeypatch, run)
    assert cli.main([]) == 130
    assert not out.exists(), "the folder the interrupted command created is left behind"
    time.sleep(3 * interrupt.RETRY_S)  # a retry cancelled with the command raises nothing


def test_a_command_that_handles_ctrl_c_itself_decides_its_exit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def run(args: argparse.Namespace, console: Console) -> int:
        try:
            signal.raise_signal(signal.SIGINT)
            time.sleep(1.0)
        except KeyboardInterrupt:
            return 0  # as the ROS node does: Ctrl-C is how it is stopped
        return 1

    _cli_running(monkeypatch, run, handles_ctrl_c=True)
    assert cli.main([]) == 0


def test_an_interrupt_caught_by_the_command_line_is_not_raised_again(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def run(args: argparse.Namespace, console: Console) -> int:
        signal.raise_signal(signal.SIGINT)
        return 0

    _cli_running(monkeypatch, run)
    assert cli.main([]) == 130
    assert not interrupt.pending()
    time.sleep(4 * interrupt.RETRY_S)  # no retry left to fire: a stray one would raise here


def test_an_interrupt_swallowed_by_a_garbage_collector_callback_still_stops_the_command(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """As CI saw with hypothesis's gc callback installed: the handler ran inside the callback,
    not in the finaliser, and Python dropped its exception."""
    seen: list[str] = []

    def callback(phase: str, info: dict[str, int]) -> None:
        if phase == "start" and not seen:
            seen.append(phase)
            signal.raise_signal(signal.SIGINT)

    def run(args: argparse.Namespace, console: Console) -> int:
        gc.callbacks.append(callback)
        try:
            gc.collect()
        finally:
            gc.callbacks.remove(callback)
        start = time.monotonic()
        while time.monotonic() - start < 5.0:
            time.sleep(0.01)
        return 0

    _cli_running(monkeypatch, run)
    assert cli.main([]) == 130
    assert seen


class _SignalInTheCompiler(numba.core.event.Listener):
    """A listener of Numba's compile event: a signal while Numba's own Python code runs."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def on_start(self, event: Any) -> None:
        signal.raise_signal(self.signum)

    def on_end(self, event: Any) -> None:
        pass


@pytest.mark.parametrize(
    ("signum", "code", "line"),
    [
        (signal.SIGINT, 130, "ceamcl: interrupted"),
        (signal.SIGTERM, 143, "ceamcl: terminated"),
    ],
)
def test_a_signal_in_the_compiler_waits_until_the_code_is_compiled(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    signum: int,
    code: int,
    line: str,
) -> None:
    """Ctrl-C raised inside Numba's compiler left it half-done: with a cold cache the demo
    then failed with ``RuntimeError: no compiled object yet`` (exit 1), and CI saw a
    segmentation fault. It is held back until the compiler returns, then stops the command."""
    results: list[int] = []
    reached: list[bool] = []

    def run(args: argparse.Namespace, console: Console) -> int:
        @numba.njit(cache=False)
        def twice(x: int) -> int:
            return 2 * x

        with numba.core.event.install_listener("numba:compile", _SignalInTheCompiler(signum)):
            results.append(twice(21))  # the signal arrives while this compiles
        start = time.monotonic()
        while time.monotonic() - start < 5.0:
            time.sleep(0.01)
        reached.append(True)
        return 0

    previous = signal.signal(signal.SIGTERM, signal.SIG_DFL)  # as in a process of its own
    try:
        _cli_running(monkeypatch, run)
        assert cli.main([]) == code
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert results == [42], "the compiler was cut short"
    assert not reached, "the command ran to its end after the signal"
    assert capsys.readouterr().err.strip().splitlines()[-1] == line


def test_only_the_compilers_frames_hold_an_interrupt_back() -> None:
    """Told by the module's name: a project checked out under a folder named ``numba`` is not
    the compiler (a path test would hold Ctrl-C back there for good)."""
    assert not interrupt.in_compiler(sys._getframe())
    code = compile("def f():\n    return sys._getframe()\n", "/home/me/numba/f.py", "exec")
    for module in ("numba.core.dispatcher", "llvmlite.binding"):
        space: dict[str, Any] = {"sys": sys, "__name__": module}
        exec(code, space)
        assert interrupt.in_compiler(space["f"]())
    for module in ("numbat", "myproject.numba_tools", "__main__"):
        space = {"sys": sys, "__name__": module}
        exec(code, space)
        assert not interrupt.in_compiler(space["f"]())


def test_the_default_handler_is_back_after_a_command(monkeypatch: pytest.MonkeyPatch) -> None:
    hook = sys.unraisablehook
    _cli_running(monkeypatch, lambda args, console: 0)
    assert cli.main([]) == 0
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert sys.unraisablehook is hook


def test_an_interrupt_that_unwinds_normally_lets_the_clean_up_finish(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Only a dropped interrupt is raised again: one that unwinds the command as usual must
    not cut its clean-up short (a pool shutting down, files closing), however long it takes."""
    cleaned: list[bool] = []

    def run(args: argparse.Namespace, console: Console) -> int:
        try:
            signal.raise_signal(signal.SIGINT)
            time.sleep(1.0)
        finally:
            time.sleep(6 * interrupt.RETRY_S)
            cleaned.append(True)
        return 0

    _cli_running(monkeypatch, run)
    assert cli.main([]) == 130
    assert cleaned == [True]


SCRIPT = """
import argparse, gc, signal, sys, time
import ceamcl.cli as cli

class Finalised:
    def __del__(self):
        signal.raise_signal(signal.SIGINT)

def run(args, console):
    obj = Finalised()
    del obj
    gc.collect()
    time.sleep(30.0)
    print("slept to the end")
    return 0

def build_parser():
    parser = argparse.ArgumentParser()
    parser.set_defaults(run=run, memory_budget=None)
    return parser

cli.build_parser = build_parser
sys.exit(cli.main([]))
"""


def test_a_dropped_interrupt_prints_one_line_and_exits_130() -> None:
    """Outside pytest (whose own hook collects unraisable exceptions): Python's "Exception
    ignored in ..." is not printed, the command line's one line is, and the interrupt is
    raised again in a main thread that sleeps (a real signal, not a flag)."""
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.returncode == 130, proc.stderr
    assert "slept to the end" not in proc.stdout  # the retry woke the sleeping main thread
    assert [line for line in proc.stderr.splitlines() if line.strip()] == ["ceamcl: interrupted"]


def _children(pid: int) -> list[int]:
    """The processes ``pid`` started (Linux: /proc)."""
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(c) for c in path.read_text().split()] if path.exists() else []


def _running(pid: int) -> bool:
    """Whether ``pid`` is a live process (an exited one nobody has reaped yet is not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux's /proc")
def test_sigterm_ends_an_experiment_with_its_workers_and_its_folder(tmp_path: Path) -> None:
    """SIGTERM to the command alone (``kill``, ``timeout``, a job scheduler) would end it on
    the spot and leave its worker processes computing and its folder half-written; it now
    unwinds as Ctrl-C does: workers ended, folder removed, one line, exit 143."""
    out = tmp_path / "table1"
    command = [sys.executable, "-m", "ceamcl", "experiment", "table1", "--trials", "10"]
    command += ["--algorithms", "gmcl", "--workers", "2", "--out", str(out), "--quiet"]
    started: list[int] = []
    proc = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and proc.poll() is None:
            started = _children(proc.pid)
            if len(started) >= 3:  # the resource tracker and two workers
                break
            time.sleep(0.05)
        assert len(started) >= 3 and proc.poll() is None, "the workers did not start"
        time.sleep(1.0)  # the workers are inside their first trials
        proc.send_signal(signal.SIGTERM)
        # the workers hold stderr open too: a worker left running keeps this from returning
        _, err = proc.communicate(timeout=30)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(_running(p) for p in started):
            time.sleep(0.05)
        leftover = [p for p in started if _running(p)]
    finally:
        for pid in [proc.pid, *started]:  # whatever this test started ends with it
            if _running(pid):
                os.kill(pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == 143, err
    assert [line for line in err.splitlines() if line.strip()][-1] == "ceamcl: terminated"
    assert not out.exists(), "the terminated command left its folder behind"
    assert not leftover, "a worker outlived the command"


@pytest.mark.parametrize(
    ("raised", "code", "line"),
    [
        ("KeyboardInterrupt", 130, "ceamcl: interrupted"),
        ("Terminated", 143, "ceamcl: terminated"),
    ],
)
def test_a_signal_while_the_commands_are_imported_is_one_line(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    raised: str,
    code: int,
    line: str,
) -> None:
    """Building the parser imports every command (about 2 s): Ctrl-C then ended the process with
    Python's traceback, SIGTERM without a word."""
    import ceamcl.cli as cli
    from ceamcl.cli import interrupt

    exc = KeyboardInterrupt if raised == "KeyboardInterrupt" else interrupt.Terminated

    def interrupted() -> None:
        raise exc

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["demo"]) == code
    err = capsys.readouterr().err
    assert err.strip() == line
