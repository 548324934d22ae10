"""Other people's localisers behind our :class:`~ceamcl.filters.base.LocalisationFilter` interface.

Peers live in optional extras and are imported lazily, inside functions, so the core never
depends on them. Today there is one: Nav2's AMCL through the ``amcl`` wheel (GPL-3.0; install
with ``pip install 'ceamcl[peers]'``), see :mod:`ceamcl.peers.nav2_amcl`.
"""

from __future__ import annotations

import importlib.util

PEERS: tuple[str, ...] = ("nav2-amcl",)


def available() -> bool:
    """Whether the Nav2 AMCL wheel (module ``amcl``) can be imported."""
    try:
        if importlib.util.find_spec("amcl") is None:
            return False
        importlib.import_module("amcl")
    except (ImportError, ValueError, OSError):
        return False
    return True


__all__ = ["PEERS", "available"]
