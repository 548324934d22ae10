"""Every compiled kernel ready before the robot moves.

Numba compiles a kernel the first time it is called with new argument types and keeps the
machine code in its on-disk cache (``cache=True``; beside the sources, or in
``NUMBA_CACHE_DIR``, or a user-wide folder where the package's own is read-only). In a process
whose cache is cold (the first run after an install, or every start of a container whose
cache is not kept) each kernel was compiled in the middle of the run, when the filter first
needed it. On fr079 raw (``ceamcl run``, 2 cores, 2026-12-01) that was 6.9 s in the global
initialisation, 3.1 s in update 19 (the first that evolved species) and 0.46 s in update 46
(the first that skipped beams): a robot driving at 1 m/s would have moved 3 m blind in one
update. With a warm cache the same updates take 0.13 s, 41 ms and 5 ms.

:func:`warm_up` loads every kernel the package calls from Python, for the argument types it
calls it with (:data:`KERNELS`), from the cache, compiling what is not there, before a run
starts: the ROS node does it when it is configured, the command line before it replays or
simulates (docs/performance.md, "Compiled before the run"). With a warm cache it costs nothing
measurable beyond what the run would load anyway; with a cold one it compiles for 14 s (the
likelihood field's runs) to 18 s (every kernel) on 2 cores, which the runs used to spend in
their first updates.
``ceamcl warm-up`` does it alone, for a container image or a read-only install to carry the
compiled kernels (``NUMBA_CACHE_DIR`` names where).

The list is checked against what the filters really call: ``tests/test_warmup.py`` runs every
algorithm, both sensor models, the mapper, the node's core and a real log's recoveries after
:func:`warm_up` and fails,
naming the kernel and the argument types, if any kernel met a signature the list lacks, if a
run with the likelihood field needed one of :data:`BEAM_MODEL_KERNELS`, or if the list holds a
signature no run called.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numba
from numba.core import types
from numba.core.registry import CPUDispatcher

__all__ = [
    "BEAM_MODEL_KERNELS",
    "KERNELS",
    "WarmUp",
    "kernels",
    "parse_signature",
    "signature_text",
    "warm_up",
]

# Argument types in Numba's own notation: ``float64[:, ::1]`` is a C-contiguous 2-D array,
# ``readonly(...)`` an array the caller cannot write (``scan._select``'s cached index).
_F1 = "float64[::1]"
_F2 = "float64[:, ::1]"
_I1 = "int64[::1]"
_B2 = "boolean[:, ::1]"
_LF = (
    f"({_F2}, {_F1}, {_F1}, {_F1}, float64, float64, uint16[:, ::1], {_F1}, float64, float64, "
    "float64)"
)
_BEAMS = f"{_F2}, {_F1}, {_F1}, {_F1}, {_F1}, float64, float64, float64"
_MIXTURE = "float64, float64, float64, boolean"
_THROUGH = f"({_F2}, {_F1}, {_F1}, {_F1}, {_F1}, {_B2}, {_F2}, float64, float64, float64)"
_FAN = f"({_F2}, {_F1}, {_B2}, {_F2}, float64, float64)"

#: ``(module, kernel names, signatures)``: the kernels the package calls from Python and the
#: argument types it calls them with. A name pair is a kernel's serial and parallel build
#: (``sensors/_compile.py``), chosen at run time by the problem's size, so both are listed.
KERNELS: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    ("ceamcl.sensors.likelihood_field", ("_lf_kernel_serial", "_lf_kernel_parallel"), (_LF,)),
    (
        "ceamcl.sensors.beam_model",
        ("_beam_table_serial", "_beam_table_parallel"),
        (
            f"({_BEAMS}, int32[:, ::1], float32[:, ::1], {_F1}, {_F1}, {_B2}, {_F2}, float64, "
            f"{_MIXTURE})",
        ),
    ),
    (
        "ceamcl.sensors.beam_model",
        ("_beam_kernel_serial", "_beam_kernel_parallel"),
        (f"({_BEAMS}, {_B2}, {_F2}, float64, {_MIXTURE})",),
    ),
    ("ceamcl.sensors.raycast", ("_cast_fan_serial", "_cast_fan_parallel"), (_FAN,)),
    (
        "ceamcl.sensors.raycast",
        ("_cast_many",),
        (f"({_F1}, {_F1}, {_F1}, {_B2}, {_F2}, float64, float64)",),
    ),
    (
        "ceamcl.sensors.raycast",
        ("_assign_rows",),
        (f"({_F2}, float64, float64, int32[:, ::1], float64, int64, int64)",),
    ),
    (
        "ceamcl.sensors.see_through",
        ("_through_walls_serial", "_through_walls_parallel"),
        (_THROUGH,),
    ),
    (
        "ceamcl.sensors.beam_skip",
        ("_near_obstacle",),
        (f"({_F2}, {_F1}, {_F1}, {_F1}, {_F1}, float64, {_F2}, float64)",),
    ),
    (
        "ceamcl.sensors.scan",
        ("_select",),
        (f"({_F1}, readonly({_I1}), float64, float64, boolean)",),
    ),
    ("ceamcl.maps.distance", ("_column_pass",), (f"({_B2},)",)),
    ("ceamcl.maps.distance", ("_row_pass",), ("(int32[:, ::1],)",)),
    (
        "ceamcl.mapping.occupancy",
        ("_trace",),
        (
            f"({_F1}, {_F1}, {_F1}, {_F1}, boolean[::1], float32[:, ::1], float64, float64, "
            "float64)",
        ),
    ),
    (
        "ceamcl.filters.resampling",
        ("_systematic_positions",),
        (f"({_F1}, {_I1}, {_I1}, {_I1}, {_F1})",),
    ),
    ("ceamcl.filters.clustering", ("_cell_keys",), (f"({_F2}, float64, int64)",)),
    ("ceamcl.filters.clustering", ("_label_sorted",), (f"({_I1}, {_I1}, int64, int64)",)),
    ("ceamcl.filters.evolution", ("_mutants",), (f"({_F2}, {_I1}, {_F2}, {_F1})",)),
    (
        "ceamcl.filters.evolution",
        ("_mutation_select",),
        (f"({_F2}, {_F1}, {_I1}, {_F2}, {_F1}, {_F1}, boolean, {_F1}, boolean)",),
    ),
    ("ceamcl.filters.evolution", ("_crossover_children",), (f"({_F2}, {_I1}, {_I1}, {_F1})",)),
    (
        "ceamcl.filters.evolution",
        ("_crossover_select",),
        (f"({_F2}, {_F1}, {_I1}, {_I1}, {_F2}, {_F1}, {_F1}, boolean, {_F1}, boolean)",),
    ),
    (
        "ceamcl.filters.headings",
        ("_facing_length_kernel",),
        (f"({_F1}, " + ", ".join(["float64"] * 10) + ")",),
    ),
    ("ceamcl.filters.ceamcl.species", ("_living_domains",), ("(float64[:, :, ::1],)",)),
    (
        "ceamcl.filters.ceamcl.species",
        ("_species_moments",),
        (f"({_F2}, {_F1}, {_F1}, {_I1}, {_I1})",),
    ),
    ("ceamcl.filters.ceamcl.initialisation", ("_smooth_kernel",), (f"({_F2}, int64)",)),
    ("ceamcl.filters.ceamcl.initialisation", ("_skiz_kernel",), ("(int32[:, ::1],)",)),
    ("ceamcl.filters.ceamcl.initialisation", ("_scale_kernel",), (f"({_F1}, float64)",)),
    (
        "ceamcl.filters.ceamcl.initialisation",
        ("_top_k_mean_kernel",),
        (f"({_I1}, {_F1}, int64, int64)",),
    ),
)


#: The beam model's kernels (its table and exact ray casting), which a run with the likelihood
#: field never calls: readied only for the beam model (4 s of a cold warm-up's 18 s).
BEAM_MODEL_KERNELS = frozenset(
    {
        "ceamcl.sensors.beam_model._beam_table_serial",
        "ceamcl.sensors.beam_model._beam_table_parallel",
        "ceamcl.sensors.beam_model._beam_kernel_serial",
        "ceamcl.sensors.beam_model._beam_kernel_parallel",
        "ceamcl.sensors.raycast._assign_rows",
    }
)


def _readonly(array: types.Array) -> types.Array:
    return array.copy(readonly=True)


_NAMESPACE: dict[str, Any] = {
    name: getattr(types, name) for name in dir(types) if not name.startswith("_")
}
_NAMESPACE["readonly"] = _readonly


def parse_signature(text: str) -> tuple[types.Type, ...]:
    """The argument types of ``text``, a tuple in Numba's notation (:data:`KERNELS`)."""
    value = eval(text, {"__builtins__": {}}, _NAMESPACE)
    if not isinstance(value, tuple) or not all(isinstance(t, types.Type) for t in value):
        raise ValueError(f"{text!r}: expected a tuple of Numba types")
    return value


def _type_text(t: types.Type) -> str:
    if isinstance(t, types.Array):
        dims = ", ".join([":"] * (t.ndim - 1) + ["::1" if t.layout == "C" else ":"])
        if t.layout == "F":
            dims = ", ".join(["::1"] + [":"] * (t.ndim - 1))
        text = f"{t.dtype}[{dims}]".replace("bool[", "boolean[")
        return f"readonly({text})" if not t.mutable else text
    return "boolean" if t == types.boolean else str(t)


def signature_text(signature: tuple[types.Type, ...]) -> str:
    """``signature`` in the notation of :data:`KERNELS` (the inverse of
    :func:`parse_signature` for arrays and scalars)."""
    inner = ", ".join(_type_text(t) for t in signature)
    return f"({inner},)" if len(signature) == 1 else f"({inner})"


def kernels(beam_model: bool = True) -> list[tuple[str, CPUDispatcher, tuple[types.Type, ...]]]:
    """``(name, dispatcher, signature)`` for every entry of :data:`KERNELS` (without
    :data:`BEAM_MODEL_KERNELS` where ``beam_model`` is false)."""
    out = []
    for module_name, names, signatures in KERNELS:
        module = importlib.import_module(module_name)
        for name in names:
            if not beam_model and f"{module_name}.{name}" in BEAM_MODEL_KERNELS:
                continue
            dispatcher = getattr(module, name)
            if not isinstance(dispatcher, CPUDispatcher):
                raise TypeError(f"{module_name}.{name} is not a compiled kernel")
            for text in signatures:
                out.append((f"{module_name}.{name}", dispatcher, parse_signature(text)))
    return out


@dataclass(frozen=True)
class WarmUp:
    """What :func:`warm_up` did."""

    #: kernel signatures made ready
    signatures: int
    #: of those, compiled here because Numba's cache lacked them
    compiled: int
    #: of those, loaded from Numba's cache (the rest were loaded already)
    from_cache: int
    seconds: float
    #: the folder of the first kernel's cache files
    cache_dir: str

    def describe(self) -> str:
        if self.signatures == 0:
            return "no kernel compiled: NUMBA_DISABLE_JIT is set, every kernel runs as Python"
        parts = [f"{self.compiled} compiled"] if self.compiled else []
        if self.from_cache:
            parts.append(f"{self.from_cache} from Numba's cache")
        loaded = self.signatures - self.compiled - self.from_cache
        if loaded:
            parts.append(f"{loaded} loaded already")
        return (
            f"{self.signatures} compiled-kernel signatures ready in {self.seconds:.1f} s "
            f"({', '.join(parts)})"
        )


def warm_up(
    progress: Callable[[int, int], None] | None = None, *, beam_model: bool = True
) -> WarmUp:
    """Load (or compile, where Numba's cache lacks them) every kernel of :data:`KERNELS` for
    its signatures, the beam model's only where ``beam_model`` (a run with the likelihood field
    calls none of them); ``progress(done, total)`` after each. A second call finds them
    loaded."""
    start = time.perf_counter()
    if getattr(numba.config, "DISABLE_JIT", False):  # plain Python functions (debugging)
        return WarmUp(0, 0, 0, 0.0, "")
    todo = kernels(beam_model)
    compiled = from_cache = 0
    for done, (_, dispatcher, signature) in enumerate(todo, start=1):
        if signature not in dispatcher.overloads:
            misses = sum(dispatcher.stats.cache_misses.values())
            dispatcher.compile(signature)
            if sum(dispatcher.stats.cache_misses.values()) > misses:
                compiled += 1
            else:
                from_cache += 1
        if progress is not None:
            progress(done, len(todo))
    cache_dir = str(todo[0][1].stats.cache_path) if todo else ""
    return WarmUp(len(todo), compiled, from_cache, time.perf_counter() - start, cache_dir)
