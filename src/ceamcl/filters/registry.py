"""The one registry of localisation algorithms: name -> config type and factory.

Each algorithm module declares what it offers as an :class:`~ceamcl.filters.base.Algorithm`
(its name, config type, default config and how a particle budget maps onto that config); the
line below that lists it is the only place that knows it exists. The CLI, the experiments, the
bench and the tests look algorithms up here and build them with :func:`make_filter`.

Adding an algorithm: write its module (say ``filters/my_filter.py``, with ``ALGORITHM =
Algorithm("my-filter", MyConfig, MyFilter, ...)``) and add ``my_filter.ALGORITHM`` to
:data:`_BUILT_IN`. An algorithm outside the core (a peer in an optional extra) is listed in
:data:`_LAZY` by module name: its module is imported only when it is asked for.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from ceamcl.errors import ConfigError, check_rng
from ceamcl.filters import gmcl, kld_amcl, mcl
from ceamcl.filters.base import Algorithm, LocalisationFilter, check_grid
from ceamcl.filters.ceamcl import filter as ceamcl_filter
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryMotionModel, OdometryNoise
from ceamcl.sensors.base import SensorModel, with_settings
from ceamcl.sensors.beam_model import BeamModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel

#: The project's own algorithms, in the order experiments run and tables list them.
_BUILT_IN: tuple[Algorithm, ...] = (
    ceamcl_filter.ALGORITHM,
    gmcl.ALGORITHM,
    mcl.ALGORITHM,
    kld_amcl.ALGORITHM,
    kld_amcl.RECOVERY_ALGORITHM,
)
#: Presets: the baselines as the tuning sweep found them best (docs/tuning.md); the filters of
#: :data:`_BUILT_IN` with other configs and sensor settings. Experiments run them too.
_PRESETS: tuple[Algorithm, ...] = (
    gmcl.TUNED_ALGORITHM,
    mcl.TUNED_ALGORITHM,
    kld_amcl.TUNED_ALGORITHM,
)
#: Algorithms outside the core: name -> module whose ``ALGORITHM`` declares it.
_LAZY: dict[str, str] = {"nav2-amcl": "ceamcl.peers.nav2_amcl"}

#: The project's own algorithms (always available).
ALGORITHMS: tuple[str, ...] = tuple(a.name for a in _BUILT_IN)
#: The tuned presets of the baselines (always available).
PRESETS: tuple[str, ...] = tuple(a.name for a in _PRESETS)
#: Sensor models by name (``make_sensor``).
SENSOR_MODELS: tuple[str, ...] = ("likelihood-field", "beam")
#: The sensor model filters get unless told otherwise: ROS amcl's and Nav2's default too.
DEFAULT_SENSOR = "likelihood-field"

_BY_NAME: dict[str, Algorithm] = {a.name: a for a in (*_BUILT_IN, *_PRESETS)}


def names() -> tuple[str, ...]:
    """Every registered algorithm: the project's own, the presets, then those outside the
    core."""
    return (*ALGORITHMS, *PRESETS, *_LAZY)


def get(name: str) -> Algorithm:
    """The registered algorithm ``name``; a :class:`ConfigError` naming the choices otherwise."""
    if name in _BY_NAME:
        return _BY_NAME[name]
    if name in _LAZY:
        module = importlib.import_module(_LAZY[name])
        algorithm: Algorithm = module.ALGORITHM
        _BY_NAME[name] = algorithm
        return algorithm
    raise ConfigError(
        f"algorithm: unknown algorithm {name!r}; expected one of {', '.join(names())}"
    )


def unavailable_reason(name: str) -> str | None:
    """Why ``name`` cannot run here (a peer that is not installed), or ``None`` when it can."""
    if name in _BY_NAME and name not in _LAZY:
        return None
    try:
        algorithm = get(name)
    except ImportError as exc:
        return f"{_LAZY.get(name, name)} cannot be imported ({exc})"
    try:
        return algorithm.unavailable()
    except Exception as exc:  # a broken optional install must not stop the other algorithms
        return f"{name}: checking whether it can run failed: {exc}"


def resolve(wanted: Iterable[str] | None) -> tuple[list[str], dict[str, str]]:
    """The algorithms to run (in the order given, duplicates dropped; default: every one) and
    those skipped with the reason (an optional peer that is not installed).

    An unknown name, or an empty selection given explicitly, is a :class:`ConfigError`.
    """
    chosen = list(names()) if wanted is None else list(dict.fromkeys(wanted))
    if not chosen:
        raise ConfigError(f"algorithms: expected at least one of {', '.join(names())}")
    unknown = [n for n in chosen if n not in names()]
    if unknown:
        raise ConfigError(
            f"algorithms: unknown algorithm {unknown[0]!r}; expected some of {', '.join(names())}"
        )
    skipped = {n: r for n in chosen if (r := unavailable_reason(n)) is not None}
    return [n for n in chosen if n not in skipped], skipped


def check_sensor(name: str) -> None:
    """Refuse an unknown sensor model's name (:class:`ConfigError`), before anything runs."""
    if name not in SENSOR_MODELS:
        raise ConfigError(
            f"sensor: unknown sensor model {name!r}; expected one of {', '.join(SENSOR_MODELS)}"
        )


#: Algorithms that weigh with a sensor model of their own whatever they are given, and it.
OWN_SENSOR: dict[str, str] = {"nav2-amcl": "the wheel's own beam model"}


def describe_sensor(name: str) -> str:
    """The sensor model of a run or comparison, in words, for its report."""
    own = ", ".join(f"{a} ({m})" for a, m in OWN_SENSOR.items())
    return f"{name} for every algorithm but {own}"


def sensor_of(algorithm: str, name: str) -> str:
    """The sensor model ``algorithm`` weighs with when it is given the one called ``name``."""
    return OWN_SENSOR.get(algorithm, name)


#: Algorithms without a global localisation of their own, and why: their figures of global
#: localisation (success, convergence, the precision side) are not comparable with the
#: others', and tables print :data:`NOT_COMPARABLE` in their place (the measured values stay
#: in the CSV files).
NO_GLOBAL_LOCALISATION: dict[str, str] = {
    "nav2-amcl": "its Python wheel has no uniform global initialisation; it starts from one "
    "Gaussian over the map's free space (ceamcl.peers.nav2_amcl)"
}
#: What a table prints for such a figure.
NOT_COMPARABLE = "not comparable"
#: Algorithms that hide their particle count: what is recorded is their upper bound
#: (``max_particles``), and tables print it as one.
HIDDEN_PARTICLE_COUNT = frozenset({"nav2-amcl"})


def particles_cell(algorithm: str, cell: str) -> str:
    """A table cell holding a particle count: ``cell``, or ``"<= cell"`` for an algorithm
    whose count is hidden (its ``max_particles`` stands in for it)."""
    return f"<= {cell}" if algorithm in HIDDEN_PARTICLE_COUNT and cell != "-" else cell


def localises_globally(algorithm: str) -> bool:
    """Whether ``algorithm``'s global-localisation figures compare with the others'."""
    return algorithm not in NO_GLOBAL_LOCALISATION


def global_cell(algorithm: str, cell: str, instead: str = NOT_COMPARABLE) -> str:
    """A table cell holding a figure of global localisation: ``cell``, or ``instead`` (by
    default :data:`NOT_COMPARABLE`; a table that says so in its success column passes "-" for
    the columns that follow from it) for an algorithm without a global localisation of its
    own."""
    return cell if localises_globally(algorithm) else instead


def global_cells(algorithm: str, cells: Iterable[str]) -> list[str]:
    """A run of table cells measuring global localisation, the first its headline (a success
    rate, a weight): as they are, or :data:`NOT_COMPARABLE` then "-" for an algorithm
    without a global localisation of its own."""
    cells = list(cells)
    if localises_globally(algorithm):
        return cells
    return [NOT_COMPARABLE, *("-" for _ in cells[1:])]


def global_notes(algorithms: Iterable[str]) -> list[str]:
    """One line per algorithm of ``algorithms`` whose global-localisation figures a table
    marks :data:`NOT_COMPARABLE`, saying why."""
    return [
        f"{a}: global localisation {NOT_COMPARABLE}: {NO_GLOBAL_LOCALISATION[a]}"
        for a in dict.fromkeys(algorithms)
        if not localises_globally(a)
    ]


def make_sensor(name: str, grid: OccupancyGrid) -> SensorModel:
    """A sensor model by name, with its default (ROS amcl) parameters."""
    check_sensor(name)
    if name == "beam":
        return BeamModel(grid)
    return LikelihoodFieldModel(grid)


def make_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    *,
    sensor: str | SensorModel = DEFAULT_SENSOR,
    odometry_noise: OdometryNoise | None = None,
    n_particles: int | np.integer[Any] | None = None,
    config: Any = None,
    sensor_settings: Mapping[str, Any] | None = None,
    motion: OdometryMotionModel | None = None,
) -> LocalisationFilter:
    """A filter by name (see :func:`names`), with its default settings or ``config`` (the
    algorithm's own config class, e.g. ``CEAMCLConfig(delta_per_m2=40)``).

    ``n_particles`` is the particle budget: the sample size of fixed-size filters (MCL, GMCL),
    the upper bound ``max_particles`` of KLD-sampling; CEAMCL chooses its own (eq. 5) and
    ignores it. Algorithms outside the core may bring their own sensor model (the Nav2 peer
    uses the wheel's beam model) and ignore ``sensor``.

    The sensor model (named, or given) takes the algorithm's ``sensor_settings`` (a tuned
    preset's ``max_beams`` and ``temper``), then ``sensor_settings`` given here on top.

    ``motion``: the odometry motion model, in place of ``OdometryMotionModel(odometry_noise)``
    (e.g. ``OdometryMotionModel(stride_m=None)``, amcl's rule of Table 5.6 over a whole
    update; give the noise in it, not both). The Nav2 peer takes only its noise.
    """
    spec = get(algorithm)
    check_grid(grid)
    check_rng(rng)
    if n_particles is not None:
        # a whole number (numpy's too), not a bool: 100.5 passed and failed later in a reshape
        whole = isinstance(n_particles, int | np.integer) and not isinstance(n_particles, bool)
        if not whole or n_particles < 1:
            raise ConfigError(f"particles: expected a positive whole count, got {n_particles!r}")
        n_particles = int(n_particles)
    cfg = config if config is not None else spec.default()
    if type(cfg) is not spec.config_type:
        raise ConfigError(
            f"config: {algorithm} takes a {spec.config_type.__name__}, got {type(cfg).__name__}"
        )
    if n_particles is not None and spec.with_particles is not None:
        cfg = spec.with_particles(cfg, n_particles)
    sensor_model = make_sensor(sensor, grid) if isinstance(sensor, str) else sensor
    sensor_model = with_settings(sensor_model, {**spec.sensor_settings, **(sensor_settings or {})})
    if motion is None:
        motion = OdometryMotionModel(odometry_noise or OdometryNoise())
    elif not isinstance(motion, OdometryMotionModel):
        raise ConfigError(f"motion: expected an OdometryMotionModel, got {type(motion).__name__}")
    elif odometry_noise is not None:
        raise ConfigError("motion: give the odometry noise inside the motion model, not both")
    return spec.build(grid, motion, sensor_model, cfg, rng)


def with_config(algorithm: str, **changes: Any) -> Any:
    """``algorithm``'s default config with ``changes`` (e.g. ``delta_per_m2=40``)."""
    spec = get(algorithm)
    try:
        return replace(spec.default(), **changes)
    except TypeError as exc:
        raise ConfigError(f"config: {algorithm}: {exc}") from None


__all__ = [
    "ALGORITHMS",
    "DEFAULT_SENSOR",
    "HIDDEN_PARTICLE_COUNT",
    "NOT_COMPARABLE",
    "NO_GLOBAL_LOCALISATION",
    "OWN_SENSOR",
    "PRESETS",
    "SENSOR_MODELS",
    "check_sensor",
    "describe_sensor",
    "get",
    "global_cell",
    "global_cells",
    "global_notes",
    "localises_globally",
    "make_filter",
    "make_sensor",
    "names",
    "particles_cell",
    "resolve",
    "sensor_of",
    "unavailable_reason",
    "with_config",
]
