"""Ctrl-C that is never lost.

Python turns SIGINT into ``KeyboardInterrupt`` wherever the main thread happens to be. When
that is a finaliser (``__del__``, which llvmlite runs while Numba compiles) or a callback of
the garbage collector, Python hands the exception to ``sys.unraisablehook`` ("Exception
ignored in ...") and carries on, so the command would finish as if nothing had happened (CI
saw the demo exit 0 after Ctrl-C).

:func:`guard` installs a hook that catches exactly those dropped interrupts: it marks the
interrupt *pending* and raises it again in the main thread :data:`RETRY_S` later, and a
command that returns before that counts as interrupted (:func:`pending`). An interrupt that
was not dropped is left alone: it unwinds the command (its clean-up included) as it always did.
Commands that catch Ctrl-C themselves (the ROS node and player, which end that way) run
without the guard.

Numba compiles (and loads its on-disk cache) through llvmlite, which LLVM calls back from C.
An interrupt raised there is dropped by the callback and leaves the compiler half-done: Numba
then fails with ``RuntimeError: no compiled object yet`` (seen with a cold cache) and a
segmentation fault was seen in CI. So while any frame of the main thread's stack belongs to
Numba or llvmlite, the handler *defers* the signal: it marks it pending and raises it again
:data:`RETRY_S` later, once the compiler has returned. A compiled kernel that runs runs no
Python code, so this holds Ctrl-C back only while code is compiled or loaded (about a second).

SIGTERM (``kill``, ``timeout``, a job scheduler) would end the process on the spot, leaving
its worker processes running and a half-written output folder behind; under the guard it
raises :class:`Terminated`, which unwinds the command as Ctrl-C does (exit 143), and is
deferred out of the compiler the same way.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

#: How long after an interrupt was dropped or deferred it is raised again (seconds).
RETRY_S = 0.05

#: Where a signal is not raised but deferred: the packages that drive LLVM (module docstring).
COMPILER_PACKAGES = ("numba", "llvmlite")

# re-entrant: the hook can run inside a finaliser while the main thread holds the lock
_lock = threading.RLock()
# ``pending``: an interrupt was dropped by Python or deferred by the handler and is still
# to be raised; ``retry``: the signal now arriving is the retry's, not the user's;
# ``terminate``: what is pending is SIGTERM's
_state: dict[str, bool] = {"active": False, "pending": False, "retry": False, "terminate": False}
_timers: list[threading.Timer] = []


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived: the command unwinds as after Ctrl-C (its workers ended, a folder it
    created removed) and the command line exits 143."""


def in_compiler(frame: FrameType | None) -> bool:
    """Whether ``frame`` or any frame below it runs Numba's or llvmlite's Python code (told by
    the module's name, not its file's path, which may hold any folder name)."""
    while frame is not None:
        module = frame.f_globals.get("__name__")
        if isinstance(module, str) and module.partition(".")[0] in COMPILER_PACKAGES:
            return True
        frame = frame.f_back
    return False


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


def _schedule() -> None:
    """Raise the pending interrupt again :data:`RETRY_S` from now (the caller holds the lock)."""
    timer = threading.Timer(RETRY_S, _retry)
    timer.daemon = True
    _timers.append(timer)
    timer.start()


def _retry() -> None:
    with _lock:
        if _state["active"] and _state["pending"]:
            _state["retry"] = True
            # a real signal, not ``_thread.interrupt_main``: it also wakes a main thread
            # that sleeps or waits in a system call
            main_id = threading.main_thread().ident
            if main_id is not None:
                sig = signal.SIGTERM if _state["terminate"] else signal.SIGINT
                signal.pthread_kill(main_id, sig)


def _raise(terminate: bool, frame: FrameType | None) -> None:
    """The guard's handler of both signals: raise, or defer while the compiler runs."""
    retry, _state["retry"] = _state["retry"], False
    if retry and not (_state["active"] and _state["pending"]):
        return  # the command ended meanwhile: nothing left to interrupt
    if _state["active"] and in_compiler(frame):
        with _lock:
            _state["pending"] = True
            _state["terminate"] = _state["terminate"] or terminate
            _schedule()
        return
    terminate = terminate or (retry and _state["terminate"])
    _state["pending"] = _state["terminate"] = False
    raise Terminated if terminate else KeyboardInterrupt


def _handler(signum: int, frame: FrameType | None) -> None:
    _raise(False, frame)


def _guarded_terminate(signum: int, frame: FrameType | None) -> None:
    _raise(True, frame)


def _hook_for(previous: Any) -> Any:
    def hook(unraisable: Any) -> None:
        exc_type = unraisable.exc_type
        if exc_type is not None and issubclass(exc_type, KeyboardInterrupt):
            with _lock:
                _state["pending"] = True
                _state["terminate"] = _state["terminate"] or issubclass(exc_type, Terminated)
                _schedule()
            return  # ours to raise again: nothing to print
        previous(unraisable)

    return hook


def pending() -> bool:
    """Whether an interrupt was dropped by Python or deferred out of the compiler and has not
    been raised since."""
    return _state["pending"]


def consume() -> type[KeyboardInterrupt]:
    """The command line raises the pending interrupt itself (no retry is needed): which one."""
    with _lock:
        terminate = _state["terminate"]
        _state["pending"] = _state["terminate"] = False
    return Terminated if terminate else KeyboardInterrupt


@contextmanager
def guard(enabled: bool = True) -> Iterator[None]:
    """Install the handlers and the hook for the duration of a command, in the main thread:
    SIGTERM's where it has its default action, Ctrl-C's only where SIGINT is not ignored (a
    job a shell started in the background keeps ignoring it)."""
    _state.update(pending=False, retry=False, terminate=False)
    if not enabled or threading.current_thread() is not threading.main_thread():
        yield
        return
    term = signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    ctrl_c = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    previous_hook = sys.unraisablehook
    _state["active"] = True
    sys.unraisablehook = _hook_for(previous_hook)
    if term:
        signal.signal(signal.SIGTERM, _guarded_terminate)
    if ctrl_c:
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
            if ctrl_c:
                signal.signal(signal.SIGINT, signal.default_int_handler)
            if term:
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
            sys.unraisablehook = previous_hook


__all__ = [
    "COMPILER_PACKAGES",
    "RETRY_S",
    "Terminated",
    "consume",
    "guard",
    "in_compiler",
    "pending",
]
