"""Resource budgets: every size derived from input is checked here before it is allocated.

A hostile or mistaken input can ask for any amount of memory with a few bytes: a map at
0.0005 m cells, a log pose at (3000, 3000), ``--particles 1000000000``, a YAML alias bomb. Each
such size is turned into the bytes it would need (count x bytes per element, with the
intermediate arrays counted in the per-element cost) and compared with one memory budget.

The default budget is a quarter of the machine's physical memory, or half of the process's
address-space limit (``ulimit -v``) if that is smaller; ``--memory-budget`` on every command
(or ``CEAMCL_MEMORY_BUDGET`` in the environment) replaces it, e.g. ``--memory-budget 16GiB``.
Derived bounds:

* a text line (CARMEN logs) may hold at most ``budget / 1024`` bytes, clamped to 1..64 MiB;
* a stream that is not a regular file (a pipe, a FIFO, a character device) may deliver at most
  the budget in bytes (its length is not known in advance);
* a YAML file (maps, routes) may hold at most 1 MiB and no aliases (:mod:`ceamcl.io.safe_yaml`).

A refusal raises :class:`BudgetError` naming the field, the size asked for and the budget.
"""

from __future__ import annotations

import os
import re
import resource
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from ceamcl.errors import ConfigError

__all__ = [
    "FILTER_CELL_BYTES",
    "MAP_CELL_BYTES",
    "PARTICLE_BYTES",
    "Budget",
    "BudgetError",
    "current",
    "default_memory_bytes",
    "format_bytes",
    "format_count",
    "parse_bytes",
    "require",
    "use",
]

_MIB = 1 << 20

#: Bytes per map cell: the int8 cells, their masks, the float64 distance field with its
#: indices, the sensor models' tables derived from it and the map drawn in a run's figures.
#: Measured 2026-11-30 (`ceamcl run` with --no-animation, maps of 1000^2, 2000^2 and 3000^2
#: cells): peak memory grows by 87-100 B a cell; 64 let a map through that needed 1.5 times
#: the budget.
MAP_CELL_BYTES = 128
#: Bytes per map cell that one filter built on the map holds (its distance transform with
#: indices, the likelihood field, the search's cells): measured 2026-12-01, a CEAMCL on
#: fr-clinic's 40.3 million cells peaks at 1.9 GB, 47 B a cell. Counted for each worker
#: process of a command that runs filters on a log's map (``ceamcl.experiments.executors``).
FILTER_CELL_BYTES = 64
#: Bytes per particle, with the per-beam work of weighting it (a scan of a few hundred beams).
PARTICLE_BYTES = 1024
_UNITS = {"": 1, "b": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


class BudgetError(ConfigError):
    """An input asks for more memory (or a longer line, or a bigger stream) than the budget."""


def _physical_memory() -> int:
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 8 << 30


def default_memory_bytes() -> int:
    """A quarter of physical memory, or half the address-space limit if that is smaller."""
    budget = _physical_memory() // 4
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY and soft > 0:
        budget = min(budget, soft // 2)
    return max(budget, 64 * _MIB)


def parse_bytes(text: str) -> int:
    """``"6GiB"``, ``"512M"``, ``"2e9"`` -> bytes (binary units; a bare number is bytes)."""
    m = re.fullmatch(r"\s*([0-9.eE+]+)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", text)
    if m is None:
        raise ConfigError(f"memory-budget: expected a size such as 6GiB or 512MiB, got {text!r}")
    try:
        value = float(m.group(1)) * _UNITS[m.group(2).lower()]
    except ValueError:
        raise ConfigError(f"memory-budget: expected a size such as 6GiB, got {text!r}") from None
    if not 1 <= value < 1 << 60:
        raise ConfigError(f"memory-budget: expected a positive size, got {text!r}")
    return int(value)


#: Counts and sizes from this on are written in scientific notation (``6.3e+301``): a route
#: file or a header can ask for any number, and a refusal must stay one short line.
_COMPACT_FROM = 1e15


def format_count(n: float) -> str:
    """``124,021,032`` below 10^15, ``6.3e+301`` from there on (and ``inf``, ``nan``)."""
    if not abs(n) < _COMPACT_FROM:  # also inf and NaN
        return f"{n:.1e}"
    return f"{n:,.0f}"


def format_bytes(n: float) -> str:
    """``7.4 GiB``; beyond 1024 TiB, ``6.3e+301 B`` (never hundreds of digits)."""
    if not n < 1024 * (1 << 40):  # also inf and NaN
        return f"{n:.1e} B"
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n:.0f} B"


@dataclass(frozen=True)
class Budget:
    """The memory budget in bytes and the bounds derived from it (module docstring)."""

    memory_bytes: int

    @classmethod
    def default(cls) -> Budget:
        env = os.environ.get("CEAMCL_MEMORY_BUDGET")
        return cls(parse_bytes(env) if env else default_memory_bytes())

    @property
    def line_bytes(self) -> int:
        return int(min(max(self.memory_bytes // 1024, _MIB), 64 * _MIB))

    @property
    def stream_bytes(self) -> int:
        return self.memory_bytes

    def describe(self) -> str:
        return (
            f"memory budget {format_bytes(self.memory_bytes)} (line {format_bytes(self.line_bytes)}"
            f", stream {format_bytes(self.stream_bytes)})"
        )


_current: Budget | None = None


def current() -> Budget:
    """The budget in force: set by :func:`use`, else the default."""
    global _current
    if _current is None:
        _current = Budget.default()
    return _current


def install(budget: Budget) -> None:
    """Make ``budget`` the one in force in this process from now on (a worker process takes
    its command's budget so: :mod:`ceamcl.experiments.executors`)."""
    global _current
    _current = budget


@contextmanager
def use(budget: Budget) -> Iterator[Budget]:
    """Make ``budget`` the one in force inside the block."""
    global _current
    before = _current
    _current = budget
    try:
        yield budget
    finally:
        _current = before


def require(field: str, count: float, bytes_each: float, what: str) -> None:
    """Refuse ``count`` elements of ``bytes_each`` bytes when they exceed the budget.

    ``field`` names where the size came from (a file and key, a flag), ``what`` the elements
    (``"map cells"``). The check happens before anything of that size is allocated.
    """
    budget = current().memory_bytes
    need = float(count) * float(bytes_each)
    if not need <= budget:  # also catches NaN
        raise BudgetError(
            f"{field}: {format_count(float(count))} {what} would need {format_bytes(need)}, "
            f"over the memory budget of {format_bytes(budget)} (raise it with --memory-budget)"
        )
