"""Algorithm names -> filters, in one place: the project's filters and the Nav2 peer.

``ceamcl.filters.ALGORITHMS`` lists the project's own filters (built by ``make_filter``);
``nav2-amcl`` is Nav2's C++ AMCL through ``ceamcl.peers.nav2_amcl``, imported only when asked
for and skipped, with the reason, when the peer is not installed.
"""

from __future__ import annotations

import importlib

import numpy as np

from ceamcl.errors import ConfigError
from ceamcl.filters import make_filter
from ceamcl.filters.base import LocalisationFilter
from ceamcl.filters.ceamcl import CEAMCLConfig
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryNoise

NAV2_AMCL = "nav2-amcl"

#: Algorithms that report one pose, not several hypotheses: the experiments measure their
#: estimate instead of their hypotheses (docs/experiments.md).
SINGLE_ESTIMATE: frozenset[str] = frozenset({NAV2_AMCL})


def filter_algorithms() -> tuple[str, ...]:
    """The project's filters, as ``ceamcl.filters`` lists them now."""
    from ceamcl import filters

    return tuple(filters.ALGORITHMS)


def all_algorithms() -> tuple[str, ...]:
    """Every algorithm an experiment can run: the project's filters, then the Nav2 peer."""
    return (*filter_algorithms(), NAV2_AMCL)


def peer_unavailable_reason() -> str | None:
    """Why ``nav2-amcl`` cannot run here, or ``None`` when it can."""
    try:
        peers = importlib.import_module("ceamcl.peers")
    except ImportError as exc:
        return f"ceamcl.peers cannot be imported ({exc})"
    try:
        ok = bool(peers.available())
    except Exception as exc:  # a broken peer install must not stop the other algorithms
        return f"ceamcl.peers.available() failed: {exc}"
    if not ok:
        return "Nav2's AMCL is not installed (pip install 'ceamcl[peers]')"
    return None


def resolve_algorithms(names: list[str] | None) -> tuple[list[str], dict[str, str]]:
    """The algorithms to run (in the order given, default all) and those skipped with why.

    An unknown name is a :class:`ConfigError`; an unavailable peer is skipped, not an error.
    """
    known = all_algorithms()
    wanted = list(known) if not names else list(dict.fromkeys(names))
    unknown = [n for n in wanted if n not in known]
    if unknown:
        raise ConfigError(
            f"algorithms: unknown algorithm {unknown[0]!r}; expected some of {', '.join(known)}"
        )
    skipped: dict[str, str] = {}
    if NAV2_AMCL in wanted:
        reason = peer_unavailable_reason()
        if reason is not None:
            skipped[NAV2_AMCL] = reason
    return [n for n in wanted if n not in skipped], skipped


def build_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    *,
    delta_per_m2: float | None = None,
    odometry_noise: OdometryNoise | None = None,
) -> LocalisationFilter:
    """A filter by name with default settings; ``delta_per_m2`` overrides CEAMCL's delta."""
    if algorithm == NAV2_AMCL:
        from ceamcl.peers.nav2_amcl import make_nav2_amcl  # type: ignore[import-not-found,unused-ignore]

        peer: LocalisationFilter = make_nav2_amcl(grid, rng, odometry_noise=odometry_noise)
        return peer
    if delta_per_m2 is not None:
        if algorithm != "ceamcl":
            raise ConfigError(f"delta: only CEAMCL has a delta, not {algorithm!r}")
        return make_filter(
            algorithm,
            grid,
            rng,
            odometry_noise=odometry_noise,
            config=CEAMCLConfig(delta_per_m2=delta_per_m2),
        )
    return make_filter(algorithm, grid, rng, odometry_noise=odometry_noise)
