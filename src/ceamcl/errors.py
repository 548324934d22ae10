"""The project's own error types.

Every error raised on bad input derives from :class:`CeamclError`, names where the problem is
(file and line, or field) and says what was expected. The CLI turns these into a one-line
message and a non-zero exit, without a traceback.
"""

from __future__ import annotations

import numpy as np


class CeamclError(Exception):
    """Base class of every error this package raises on bad input."""


class MapFormatError(CeamclError, ValueError):
    """A map file (YAML or image) is malformed or inconsistent."""


class LogFormatError(CeamclError, ValueError):
    """A robot log is malformed."""


class ConfigError(CeamclError, ValueError):
    """A configuration value or command-line argument is out of range or unknown."""


class FilterStateError(CeamclError, RuntimeError):
    """A filter was asked for something before it can give it: stepped or queried before
    ``initialise_global`` or ``initialise_pose``."""


class InputTypeError(CeamclError, TypeError):
    """An argument of the wrong type: a seed where a ``numpy.random.Generator`` is expected, an
    array where a ``LaserScan`` is."""


def _type_name(t: type) -> str:
    return "None" if t is type(None) else t.__name__


def type_name(value: object) -> str:
    """The name of ``value``'s type as a message shows it (``None`` for None)."""
    return _type_name(type(value))


def wrong_type(
    value: object, expected: type | tuple[type, ...], name: str, hint: str = ""
) -> InputTypeError:
    """The error of argument ``name`` holding ``value`` where ``expected`` was wanted: one line
    naming the argument, the type expected, the type given and ``hint``."""
    wanted = " or ".join(
        _type_name(t) for t in (expected if isinstance(expected, tuple) else (expected,))
    )
    got = _type_name(type(value))
    return InputTypeError(f"{name}: expected {wanted}, got {got}" + (f"; {hint}" if hint else ""))


def check_rng(rng: object, name: str = "rng") -> None:
    """Refuse anything but a ``numpy.random.Generator`` (a seed, ``None``, a ``RandomState``
    failed deep inside the first call that drew from it)."""
    if not isinstance(rng, np.random.Generator):
        got = _type_name(type(rng))
        raise InputTypeError(
            f"{name}: expected numpy.random.Generator, got {got}; "
            "use numpy.random.default_rng(seed)"
        )


class InputWarning(UserWarning):
    """Input that is accepted but probably not what was meant (the CLI prints one line)."""


class RunWarning(UserWarning):
    """Something a run met that its user should hear of while it goes on (a Dask worker that
    froze); the CLI prints one line."""
