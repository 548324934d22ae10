"""The project's own error types.

Every error raised on bad input derives from :class:`CeamclError`, names where the problem is
(file and line, or field) and says what was expected. The CLI turns these into a one-line
message and a non-zero exit, without a traceback.
"""

from __future__ import annotations


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


class InputWarning(UserWarning):
    """Input that is accepted but probably not what was meant (the CLI prints one line)."""
