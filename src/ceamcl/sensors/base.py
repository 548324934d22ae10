"""The sensor-model protocol and the fitness scale shared by every filter.

A sensor model scores poses against a scan in log space: ``log_likelihood`` returns, per
pose, ``temper`` times the sum over the evaluated beams of ``log p(z_k | x)``
(:mod:`ceamcl.sensors.tempering`: the beams are not independent), or with ``scoring == "ros"``
ROS amcl's ``log(1 + sum_k pz_k^3)`` (:mod:`ceamcl.sensors.scoring`). Filters use it as the
importance weight.

CEAMCL also needs a *fitness* ``w`` in (0, 1] that is comparable between species and between
scans (NOTES.md, "the scale of the fitness"). :func:`fitness` is the geometric mean of the
per-beam likelihoods divided by the largest value one beam can take, so a perfect match scores
1 whatever the number of beams (with ``"ros"`` scoring, the power mean of order 3 instead).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.errors import ConfigError
from ceamcl.sensors.scan import LaserScan, PreparedScan
from ceamcl.sensors.scoring import ros_fitness


class SensorModel(Protocol):
    """What a filter needs from a laser model."""

    @property
    def temper(self) -> float:
        """The exponent in (0, 1] on the product of beam likelihoods (1 with ``"ros"``)."""
        ...

    @property
    def scoring(self) -> str:
        """How beams combine: ``"product"`` or ``"ros"`` (:mod:`ceamcl.sensors.scoring`)."""
        ...

    def prepare(self, scan: LaserScan) -> PreparedScan:
        """Select and classify the beams once per scan."""
        ...

    def log_likelihood(self, poses: ArrayLike, prepared: PreparedScan) -> NDArray[np.float64]:
        """Per pose, ``temper * sum_k log p(z_k | x)`` over the prepared beams (``"ros"``:
        ``log(1 + sum_k pz_k^3)``); ``(N,)``."""
        ...

    def max_log_beam_likelihood(self, prepared: PreparedScan) -> float:
        """``log`` of the largest value one beam's likelihood can take for this scan."""
        ...


def fitness(
    log_likelihood: ArrayLike, prepared: PreparedScan, model: SensorModel
) -> NDArray[np.float64]:
    """Fitness in (0, 1]: geometric mean of per-beam likelihoods over their maximum (the
    tempering undone, so fitness does not depend on it). With ``"ros"`` scoring, the power
    mean of order 3 of the per-beam likelihoods over their maximum
    (:func:`~ceamcl.sensors.scoring.ros_fitness`).

    With no usable beam the scan says nothing and every pose scores 1.
    """
    ll = np.asarray(log_likelihood, dtype=np.float64)
    if prepared.n_beams == 0:
        return np.ones_like(ll)
    if model.scoring == "ros":
        return ros_fitness(ll, prepared.n_beams, model.max_log_beam_likelihood(prepared))
    per_beam = ll / (prepared.n_beams * model.temper) - model.max_log_beam_likelihood(prepared)
    return np.exp(np.minimum(per_beam, 0.0))


_MISSING = object()


def with_settings(model: SensorModel, settings: Mapping[str, Any]) -> SensorModel:
    """``model`` with fields of its config changed (e.g. ``{"max_beams": 30, "temper": 0.1}``
    or ``{"scoring": "ros"}``), on the same map; ``model`` itself when nothing changes.

    This is how an algorithm brings its own sensor settings to whichever sensor model it is
    given (``Algorithm.sensor_settings``, KLD-AMCL's ``scoring``). A model must have a frozen
    dataclass ``config`` and be built as ``type(model)(model.grid, config)``, as the beam model
    and the likelihood field are. A setting the model does not have, or a bad value, is a
    :class:`ConfigError` naming it.
    """
    if not settings:
        return model
    config = getattr(model, "config", None)
    if config is None and all(getattr(model, k, _MISSING) == v for k, v in settings.items()):
        return model  # a model without a config that already has these values (a test double)
    name = type(model).__name__
    if config is None or not dataclasses.is_dataclass(config) or isinstance(config, type):
        raise ConfigError(
            f"sensor: a {name} has no config to take the settings {', '.join(settings)}"
        )
    known = {f.name for f in dataclasses.fields(config)}
    unknown = [k for k in settings if k not in known]
    if unknown:
        raise ConfigError(
            f"sensor: {name} has no setting {unknown[0]!r}; expected some of {', '.join(known)}"
        )
    if all(getattr(config, k) == v for k, v in settings.items()):
        return model
    try:
        changed = dataclasses.replace(config, **settings)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"sensor: {name}: {exc}") from None
    built: SensorModel = type(model)(model.grid, changed)  # type: ignore[call-arg, attr-defined]
    return built
