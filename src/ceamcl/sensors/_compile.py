"""Compiling one kernel source as a serial and a parallel numba function.

Numba's on-disk cache (``cache=True``) names its files after the Python function's qualified
name and keys its entries by signature and bytecode, *not* by compile options. Two ``njit``
wrappers of the same function (one ``parallel=True``) therefore share cache entries: whichever
compiled first is what the other loads in later processes. The "parallel" kernel could then run
serial code, or the serial one parfor code; with ``fastmath`` the two also differed in their
last bits, so a trial gave other numbers in a worker than in the main process. Each variant here
is compiled from its own copy of the function, with its own qualified name, so each has its own
cache files.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

import numba


def _clone(func: Callable[..., Any], suffix: str) -> types.FunctionType:
    assert isinstance(func, types.FunctionType)
    copy = types.FunctionType(
        func.__code__, func.__globals__, func.__name__ + suffix, func.__defaults__, func.__closure__
    )
    copy.__qualname__ = func.__qualname__ + suffix
    copy.__module__ = func.__module__
    copy.__doc__ = func.__doc__
    return copy


def serial_and_parallel(func: Callable[..., Any]) -> tuple[Any, Any]:
    """``(serial, parallel)`` compiled versions of ``func`` (which loops with ``numba.prange``),
    each cached on disk under its own name."""
    serial = numba.njit(cache=True)(_clone(func, "_serial"))
    parallel = numba.njit(cache=True, parallel=True)(_clone(func, "_parallel"))
    return serial, parallel
