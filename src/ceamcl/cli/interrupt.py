"""Ctrl-C that is never lost.

Python turns SIGINT into ``KeyboardInterrupt`` wherever the main thread happens to be. When
that is a finaliser (``__del__``, which llvmlite runs while Numba compiles), Python prints
"Exception ignored in ..." and carries on, so the command would finish as if nothing had
happened. :func:`guard` installs a handler that, when the interrupt lands in a finaliser,
raises it again a moment later, and :func:`pending` lets the command line treat a command
that returned before that retry as interrupted all the same. (A command that catches
``KeyboardInterrupt`` itself, as the ROS node and player do, still decides its own exit.)
"""

from __future__ import annotations

import _thread
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

#: How long a deferred interrupt waits before it is raised again (seconds).
RETRY_S = 0.05

_state: dict[str, bool] = {"pending": False}
_timers: list[threading.Timer] = []


def _in_finaliser(frame: FrameType | None) -> bool:
    while frame is not None:
        if frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


def _handler(signum: int, frame: FrameType | None) -> None:
    if _in_finaliser(frame):
        _state["pending"] = True
        # an exception raised here would be printed and dropped: raise it once the
        # finaliser has returned
        timer = threading.Timer(RETRY_S, _thread.interrupt_main)
        timer.daemon = True
        timer.start()
        _timers.append(timer)
        return
    _state["pending"] = False
    raise KeyboardInterrupt


def pending() -> bool:
    """Whether an interrupt landed in a finaliser and has not been raised since."""
    return _state["pending"]


@contextmanager
def guard() -> Iterator[None]:
    """Install the handler for the duration of a command (main thread only, and only where
    SIGINT is not ignored: a job a shell started in the background keeps ignoring it)."""
    _state["pending"] = False
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        for timer in _timers:
            timer.cancel()  # the command has ended: nothing left to interrupt
        _timers.clear()
        signal.signal(signal.SIGINT, signal.default_int_handler)


__all__ = ["RETRY_S", "guard", "pending"]
