"""Ctrl-C that is never lost.

Python turns SIGINT into ``KeyboardInterrupt`` wherever the main thread happens to be. When
that is a finaliser (``__del__``, which llvmlite runs while Numba compiles) or a callback of
the garbage collector, Python prints "Exception ignored in ..." and carries on, so the command
would finish as if nothing had happened (CI saw the demo exit 0 after Ctrl-C).

:func:`guard` installs a handler that raises ``KeyboardInterrupt`` and keeps it *pending*
until the command line has caught it (:func:`delivered`); while it is pending it is raised
again every :data:`RETRY_S`, and a command that returns with one pending counts as interrupted
(:func:`pending`). Commands that catch Ctrl-C themselves (the ROS node and player, which end
that way) run without the guard.
"""

from __future__ import annotations

import _thread
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

#: How long an interrupt that was not caught waits before it is raised again (seconds).
RETRY_S = 0.05

_lock = threading.Lock()
_state: dict[str, bool] = {"active": False, "pending": False, "retry": False}
_timers: list[threading.Timer] = []


def _retry() -> None:
    with _lock:
        if _state["active"] and _state["pending"]:
            _state["retry"] = True
            _thread.interrupt_main()


def _handler(signum: int, frame: FrameType | None) -> None:
    retry, _state["retry"] = _state["retry"], False
    if retry and not (_state["pending"] and _state["active"]):
        return  # caught in the meantime, or the command is over: nothing to raise again
    _state["pending"] = True
    timer = threading.Timer(RETRY_S, _retry)
    timer.daemon = True
    _timers.append(timer)
    timer.start()
    raise KeyboardInterrupt


def pending() -> bool:
    """Whether an interrupt was raised and has not reached the command line since."""
    return _state["pending"]


def delivered() -> None:
    """The command line caught the interrupt: stop raising it again."""
    with _lock:
        _state["pending"] = False
        _state["retry"] = False
        for timer in _timers:
            timer.cancel()
        _timers.clear()


@contextmanager
def guard(enabled: bool = True) -> Iterator[None]:
    """Install the handler for the duration of a command (in the main thread, and only where
    SIGINT is not ignored: a job a shell started in the background keeps ignoring it)."""
    delivered()
    if (
        not enabled
        or threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    _state["active"] = True
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


__all__ = ["RETRY_S", "delivered", "guard", "pending"]
