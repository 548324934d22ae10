"""Ctrl-C that is never lost.

Python turns SIGINT into ``KeyboardInterrupt`` wherever the main thread happens to be. When
that is a finaliser (``__del__``, which llvmlite runs while Numba compiles) or a callback of
the garbage collector, Python hands the exception to ``sys.unraisablehook`` ("Exception
ignored in ...") and carries on, so the command would finish as if nothing had happened (CI
saw the demo exit 0 after Ctrl-C).

:func:`guard` installs a hook that catches exactly those dropped interrupts: it marks the
interrupt *swallowed* and raises it again in the main thread :data:`RETRY_S` later, and a
command that returns before that counts as interrupted (:func:`swallowed`). An interrupt that
was not dropped is left alone: it unwinds the command (its clean-up included) as it always did.
Commands that catch Ctrl-C themselves (the ROS node and player, which end that way) run
without the guard.

SIGTERM (``kill``, ``timeout``, a job scheduler) would end the process on the spot, leaving
its worker processes running and a half-written output folder behind; under the guard it
raises :class:`Terminated`, which unwinds the command as Ctrl-C does (exit 143).
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

#: How long after an interrupt was dropped it is raised again (seconds).
RETRY_S = 0.05

# re-entrant: the hook can run inside a finaliser while the main thread holds the lock
_lock = threading.RLock()
_state: dict[str, bool] = {"active": False, "swallowed": False, "retry": False}
_timers: list[threading.Timer] = []


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived: the command unwinds as after Ctrl-C (its workers ended, a folder it
    created removed) and the command line exits 143."""


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise Terminated


@contextmanager
def during_setup() -> Iterator[None]:
    """SIGTERM raises :class:`Terminated` inside the block (the command's set-up, before
    :func:`guard`), as Ctrl-C raises ``KeyboardInterrupt``; the old handler is put back after.
    Outside the main thread (a test calling ``main``) nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def _retry() -> None:
    with _lock:
        if _state["active"] and _state["swallowed"]:
            _state["retry"] = True
            # a real signal, not ``_thread.interrupt_main``: it also wakes a main thread
            # that sleeps or waits in a system call
            main_id = threading.main_thread().ident
            if main_id is not None:
                signal.pthread_kill(main_id, signal.SIGINT)


def _handler(signum: int, frame: FrameType | None) -> None:
    retry, _state["retry"] = _state["retry"], False
    if retry:
        if not (_state["active"] and _state["swallowed"]):
            return  # the command ended meanwhile: nothing left to interrupt
        _state["swallowed"] = False
    raise KeyboardInterrupt


def _hook_for(previous: Any) -> Any:
    def hook(unraisable: Any) -> None:
        exc_type = unraisable.exc_type
        if exc_type is not None and issubclass(exc_type, KeyboardInterrupt):
            with _lock:
                _state["swallowed"] = True
                timer = threading.Timer(RETRY_S, _retry)
                timer.daemon = True
                _timers.append(timer)
                timer.start()
            return  # ours to raise again: nothing to print
        previous(unraisable)

    return hook


def swallowed() -> bool:
    """Whether an interrupt was dropped by Python and has not been raised again since."""
    return _state["swallowed"]


def consume() -> None:
    """The command line raises the dropped interrupt itself: no retry is needed."""
    with _lock:
        _state["swallowed"] = False


@contextmanager
def guard(enabled: bool = True) -> Iterator[None]:
    """Install the handlers and the hook for the duration of a command, in the main thread:
    SIGTERM's where it has its default action, Ctrl-C's only where SIGINT is not ignored (a
    job a shell started in the background keeps ignoring it)."""
    _state.update(swallowed=False, retry=False)
    if not enabled or threading.current_thread() is not threading.main_thread():
        yield
        return
    term = signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    if term:
        signal.signal(signal.SIGTERM, _terminate)
    try:
        if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            yield
        else:
            with _guard_ctrl_c():
                yield
    finally:
        if term:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextmanager
def _guard_ctrl_c() -> Iterator[None]:
    """Ctrl-C's handler and the hook that catches a dropped interrupt (module docstring)."""
    previous_hook = sys.unraisablehook
    _state["active"] = True
    sys.unraisablehook = _hook_for(previous_hook)
    signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        try:
            with _lock:
                _state["active"] = False  # no retry fires after this, and one that fired
                for timer in _timers:  # just before finds the handler still here: dropped
                    timer.cancel()
                _timers.clear()
        finally:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            sys.unraisablehook = previous_hook


__all__ = ["RETRY_S", "Terminated", "consume", "guard", "swallowed"]
