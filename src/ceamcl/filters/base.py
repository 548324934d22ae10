"""The interface every localisation filter implements, and the records it produces.

A filter is built with a map, a motion model, a sensor model, a frozen config and a
``numpy.random.Generator``; after that it is driven by three calls:

* ``initialise_global(scan)``: no idea where the robot is; the first scan is the only clue;
* ``initialise_pose(pose, covariance)``: pose tracking from a known start;
* ``step(increment, scan)``: odometry since the last step, then the new scan.

Once initialised, it can be asked at any time for ``estimate()`` (the pose it believes),
``hypotheses()`` (every distinct pose it still entertains, best first), ``state()`` (LOCALISED,
AMBIGUOUS, LOST or INITIALISING: whether to trust the pose, :mod:`ceamcl.filters.state`) and
``particles()`` (for plotting). Stepping or asking a filter before its first
``initialise_global`` or ``initialise_pose`` raises :class:`~ceamcl.errors.FilterStateError`
(a filter built from a map knows nothing of the robot yet). Each call
to ``initialise_global`` and ``step`` returns the filter's :class:`StepRecord`; the runner
(:func:`ceamcl.runner.run_filter`) adds what it measures into a :class:`StepDiagnostics`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.errors import FilterStateError, wrong_type
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.sensors.scan import LaserScan

if TYPE_CHECKING:
    from ceamcl.filters.state import LocalisationState
    from ceamcl.motion.odometry import OdometryMotionModel
    from ceamcl.sensors.base import SensorModel


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """The filter's pose ``(x, y, theta)`` and its ``3 x 3`` covariance."""

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """One distinct pose hypothesis: a species (CEAMCL) or a particle cluster (MCL, GMCL).

    ``weight``: its share of the probability mass (sums to 1 over hypotheses);
    ``fitness``: its mean fitness in (0, 1] for the last scan (see ``sensors.base.fitness``).
    """

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    n_particles: int
    weight: float
    fitness: float
    label: int


@dataclass(frozen=True, eq=False)
class ParticleSnapshot:
    """Particles for plotting: poses ``(N, 3)``, normalised weights ``(N,)``, labels ``(N,)``
    (species id for CEAMCL, cluster id otherwise)."""

    poses: NDArray[np.float64]
    weights: NDArray[np.float64]
    labels: NDArray[np.int64]


@dataclass(frozen=True)
class StepRecord:
    """What a filter says about one of its steps; each filter returns its own subclass with
    typed fields of its own (``KLDAMCLRecord``, ``CEAMCLRecord``). Time, particle count and
    ESS are measured by the runner (:class:`StepDiagnostics`).

    resampled: the step resampled. likelihood_evaluations: poses scored against a scan.
    reinitialised: the filter started again (every particle impossible, every species
    extinct, a kidnap detected).
    """

    resampled: bool = False
    likelihood_evaluations: int = 0
    reinitialised: bool = False

    def columns(self) -> dict[str, float | int | bool]:
        """The record's scalar fields by name (CSV columns)."""
        out: dict[str, float | int | bool] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool | int | float):
                out[f.name] = value
        return out


@dataclass(frozen=True)
class StepDiagnostics:
    """One step of a run, as the runner records it: what it measured (time, particle count,
    ESS of the normalised weights) and the filter's own :class:`StepRecord`.

    stepped: the filter was stepped (updated) with this scan. False when the runner's update
    policy held the scan back (:func:`ceamcl.runner.run_filter` with ``update_when``): the
    odometry then accumulates into the next update, and ``record`` is an empty
    :class:`StepRecord`.

    state: the filter's :class:`~ceamcl.filters.state.LocalisationState` after the step (the
    last update's when the step was held back); ``None`` when not asked.

    state_ms: the time of reading that state after the step (the filter's hypotheses and
    ``state()``), which ``step_ms`` does not include; 0 when not read. CEAMCL reads its state
    inside its step (docs/ceamcl.md, departure 10) and hands it over, a particle filter
    clusters its particles here: a comparison of update times that leaves this out compares
    unequal work (docs/performance.md)."""

    step: int
    n_particles: int
    ess: float
    step_ms: float
    record: StepRecord
    stepped: bool = True
    state: LocalisationState | None = None
    state_ms: float = 0.0

    @property
    def resampled(self) -> bool:
        return self.record.resampled

    @property
    def likelihood_evaluations(self) -> int:
        return self.record.likelihood_evaluations

    @property
    def reinitialised(self) -> bool:
        return self.record.reinitialised

    def row(self) -> dict[str, float | int | bool | str]:
        """A flat record for CSV: step, particle count, ESS, resampled, evaluations, step time,
        whether the filter was stepped, the state (``state``, ``state_confidence``,
        ``state_hypotheses``) when known, then the filter's own fields."""
        out: dict[str, float | int | bool | str] = {
            "step": self.step,
            "n_particles": self.n_particles,
            "ess": self.ess,
        }
        record = self.record.columns()
        out.update(
            (k, record.pop(k)) for k in ("resampled", "likelihood_evaluations") if k in record
        )
        out["step_ms"] = self.step_ms
        out["stepped"] = self.stepped
        if self.state is not None:
            out.update(self.state.row())
        out.update(record)
        return out


class LocalisationFilter(Protocol):
    """The one interface of MCL, GMCL, CEAMCL, KLD-AMCL and the Nav2 peer.

    Build a filter (:func:`ceamcl.filters.make_filter`), initialise it once with
    :meth:`initialise_global` or :meth:`initialise_pose`, then call :meth:`step` with each
    odometry increment and scan; ask :meth:`estimate`, :meth:`hypotheses`, :meth:`state` or
    :meth:`particles` whenever needed. Every call but the two initialisations raises
    :class:`~ceamcl.errors.FilterStateError` before the first initialisation; arguments of
    the wrong type raise :class:`~ceamcl.errors.InputTypeError` before the filter changes.
    """

    #: the algorithm's registered name (``"ceamcl"``, ``"mcl-tuned"``, ...)
    name: str

    def initialise_global(self, scan: LaserScan) -> StepRecord:
        """Global localisation: forget everything and start from ``scan`` alone, the robot
        anywhere in the map's free space (particles or species spread over the places that fit
        the scan). May be called again at any time to start over.

        ``scan``: a :class:`~ceamcl.sensors.scan.LaserScan` (with no usable beam the start is
        spread over free space). Returns the filter's :class:`StepRecord` of the
        initialisation (its likelihood evaluations, whether it resampled).
        """
        ...

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """Pose tracking: forget everything and start around a known pose.

        ``pose``: ``(x, y, theta)`` in the map's world frame (m, rad); ``covariance``: its
        ``3 x 3`` covariance (finite, symmetric, positive semi-definite), from which the
        particles are drawn (our filters refuse other values with
        :class:`~ceamcl.errors.ConfigError`). No scan is used: the next :meth:`step` weighs the
        first one.
        """
        ...

    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepRecord:
        """One filter update: predict with the odometry ``increment`` since the last step
        (:func:`ceamcl.motion.increment_between` of two odometry poses), then correct with
        ``scan``.

        ``scan=None`` (no scan at this step), or a scan with no usable beam, only predicts: the
        weights stay as they are. Returns the filter's own :class:`StepRecord` subclass
        (``reinitialised=True`` when the filter had to start over). Before the first
        initialisation: :class:`~ceamcl.errors.FilterStateError`; a NaN or absurd increment:
        :class:`~ceamcl.errors.LogFormatError`, before any state changes.
        """
        ...

    def particle_weights(self) -> NDArray[np.float64]:
        """Normalised weights of the particles the filter holds now (the runner's particle
        count and ESS); NaN weights when the filter cannot show them (the Nav2 peer).
        Before the first initialisation: :class:`~ceamcl.errors.FilterStateError`."""
        ...

    def estimate(self) -> PoseEstimate:
        """The pose the filter believes now and its covariance: a :class:`PoseEstimate` of
        ``(x, y, theta)`` and a ``3 x 3`` matrix, in the map's world frame. In a symmetric
        world it is one of several equally good places; :meth:`hypotheses` lists them all
        and :meth:`state` says whether to trust it. Before the first initialisation:
        :class:`~ceamcl.errors.FilterStateError`."""
        ...

    def hypotheses(self) -> list[Hypothesis]:
        """Every distinct pose the filter still entertains, heaviest first: CEAMCL's species,
        the particle clusters of the other filters, the estimate alone for the Nav2 peer.
        Each :class:`Hypothesis` has a pose, covariance, particle count, weight (the weights
        sum to 1) and fitness for the last scan. Before the first initialisation:
        :class:`~ceamcl.errors.FilterStateError`."""
        ...

    def state(self, hypotheses: Sequence[Hypothesis] | None = None) -> LocalisationState:
        """Whether to trust the pose (:mod:`ceamcl.filters.state`): LOCALISED, AMBIGUOUS,
        LOST or INITIALISING (not yet stepped since the initialisation), with a confidence
        and the reason in words; only observes the filter.
        ``hypotheses``: this filter's :meth:`hypotheses` now, when the caller already has
        them (they are not computed twice). Before the first initialisation:
        :class:`~ceamcl.errors.FilterStateError`."""
        ...

    def particles(self) -> ParticleSnapshot:
        """A copy of the particles for plotting: poses ``(N, 3)``, normalised weights and a
        label each (species for CEAMCL, cluster otherwise; the Nav2 peer, which hides its
        particles, gives samples of its estimate). Before the first initialisation:
        :class:`~ceamcl.errors.FilterStateError`."""
        ...


def not_initialised(name: str, method: str) -> FilterStateError:
    """The error of a filter stepped or queried (``method``) before its first initialisation."""
    return FilterStateError(
        f"{name}: {method}() before the filter was initialised; call "
        "initialise_global(scan) or initialise_pose(pose, covariance) first"
    )


def require_initialised(f: object, method: str) -> None:
    """:func:`not_initialised` raised when filter ``f`` is not initialised yet (its
    ``_initialised`` flag; a filter without the flag counts as initialised)."""
    if not getattr(f, "_initialised", True):
        raise not_initialised(getattr(f, "name", type(f).__name__), method)


_INCREMENT_HINT = (
    "use ceamcl.motion.increment_between(odom_prev, odom_now) or "
    "OdometryIncrement(rot1, trans, rot2)"
)
_SCAN_HINT = (
    "wrap the ranges in ceamcl.sensors.LaserScan(ranges, angle_min, angle_increment, "
    "range_min, range_max)"
)


def check_step_arguments(increment: object, scan: object) -> None:
    """``step(increment, scan)``'s types: an :class:`OdometryIncrement` and a
    :class:`LaserScan` or ``None`` (two ``isinstance`` tests, before the filter changes)."""
    if not isinstance(increment, OdometryIncrement):
        raise wrong_type(increment, OdometryIncrement, "increment", _INCREMENT_HINT)
    if scan is not None and not isinstance(scan, LaserScan):
        raise wrong_type(scan, (LaserScan, type(None)), "scan", _SCAN_HINT)


def check_scan(scan: object) -> None:
    """``initialise_global(scan)``'s type: a :class:`LaserScan`."""
    if not isinstance(scan, LaserScan):
        raise wrong_type(scan, LaserScan, "scan", _SCAN_HINT)


def check_grid(grid: object) -> None:
    """A filter's map: an :class:`OccupancyGrid` (not its occupancy array)."""
    if not isinstance(grid, OccupancyGrid):
        raise wrong_type(
            grid,
            OccupancyGrid,
            "grid",
            "load one with ceamcl.maps.ros_io.load_map(path) or ceamcl.maps.worlds.get_world(name)",
        )


def _available() -> str | None:
    return None


@dataclass(frozen=True)
class Algorithm:
    """What an algorithm module declares to the registry (:mod:`ceamcl.filters.registry`).

    name: the name users type (``--algorithm``) and tables show.
    config_type: its frozen config dataclass; ``default_config()`` builds the default one
        (``config_type()`` unless given).
    factory: ``factory(grid, motion, sensor, config, rng=rng)`` builds the filter; a filter
        class whose constructor takes exactly that is its own factory.
    with_particles: how a particle budget ``n`` enters the config (``None``: the algorithm
        chooses its own sample size and ignores budgets).
    reports: ``"hypotheses"`` when :meth:`LocalisationFilter.hypotheses` lists every pose it
        entertains, ``"estimate"`` when it can only report one pose (the Nav2 peer).
    unavailable: why it cannot run here (an optional peer not installed), or ``None``.
    summary: one line for ``--help`` and the docs.
    sensor_settings: fields of the sensor model's config this algorithm sets on whichever
        model it is given (``{"max_beams": 30, "temper": 0.1}``; a tuned preset's), applied by
        ``registry.make_filter`` through :func:`ceamcl.sensors.base.with_settings`.
    """

    name: str
    config_type: type
    factory: Callable[..., LocalisationFilter]
    default_config: Callable[[], Any] | None = None
    with_particles: Callable[[Any, int], Any] | None = None
    reports: Literal["hypotheses", "estimate"] = "hypotheses"
    unavailable: Callable[[], str | None] = _available
    summary: str = ""
    sensor_settings: Mapping[str, Any] = field(default_factory=dict)

    def default(self) -> Any:
        """The default config."""
        return self.config_type() if self.default_config is None else self.default_config()

    def build(
        self,
        grid: OccupancyGrid,
        motion: OdometryMotionModel,
        sensor: SensorModel,
        config: Any,
        rng: np.random.Generator,
    ) -> LocalisationFilter:
        built = self.factory(grid, motion, sensor, config, rng=rng)
        if built.name != self.name:  # a preset runs its base filter under its own name
            built.name = self.name
        return built
