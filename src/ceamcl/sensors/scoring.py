"""How a sensor model combines its per-beam likelihoods into one score per pose.

``"product"`` (the default): the textbook product ``prod_k p(z_k | x)``, returned as
``temper * sum_k log p(z_k | x)`` (:mod:`ceamcl.sensors.tempering`). The per-beam ``p`` is a
density: its Gaussian keeps ``1 / (sqrt(2 pi) sigma_hit)``.

``"ros"``: what ROS and Nav2 ``amcl`` do (``nav2_amcl/src/sensors/laser/beam_model.cpp`` and
``likelihood_field_model.cpp``, "an ad-hoc weighting scheme for combining beam probs")::

    p(z | x) = 1 + sum_k pz_k^3

returned as ``log(1 + sum_k pz_k^3)``. amcl's ``pz`` has no Gaussian normaliser: its hit term
is ``z_hit * exp(-d^2 / (2 sigma_hit^2))`` in both models (the likelihood field says it
"should have a normalization of 1/(sqrt(2pi)*sigma)"), so ``pz <= 1`` with amcl's defaults.
The sum flattens the likelihood (a pose explaining every beam scores at most
``1 + n_beams`` times one explaining none), which is why tempering does not apply to it.

:func:`power_mean_fitness` turns either score into the fitness scale of
:func:`ceamcl.sensors.base.fitness`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: The ways beams combine: ``"product"`` (textbook) and ``"ros"`` (amcl's ``1 + sum pz^3``).
SCORINGS: tuple[str, ...] = ("product", "ros")


def check_scoring(scoring: str, temper: float) -> None:
    """A :class:`ValueError` naming the field unless ``scoring`` is one of :data:`SCORINGS`
    and, for ``"ros"``, ``temper`` is 1 (tempering applies to the product only)."""
    if scoring not in SCORINGS:
        raise ValueError(f"scoring: expected one of {', '.join(SCORINGS)}, got {scoring!r}")
    if scoring == "ros" and temper != 1.0:
        raise ValueError(
            f"temper: applies to scoring 'product' only; scoring 'ros' sums cubed beam "
            f"likelihoods and takes temper 1, got {temper}"
        )


def ros_fitness(
    log_score: NDArray[np.float64], n_beams: int, log_max_beam: float
) -> NDArray[np.float64]:
    """Fitness in [0, 1] of ``log(1 + sum_k pz_k^3)`` scores: the power mean of order 3 of
    ``pz_k / pz_max``, ``(sum_k pz_k^3 / (n_beams pz_max^3))^(1/3)``; 1 when every beam is as
    likely as a beam can be, whatever the number of beams (the product's fitness is the power
    mean of order 0, the geometric mean)."""
    cubes = np.maximum(np.expm1(log_score), 0.0)  # -inf (impossible) -> 0
    with np.errstate(over="ignore"):
        scale = n_beams * np.exp(3.0 * log_max_beam)
    return np.minimum(np.cbrt(cubes / scale), 1.0)


__all__ = ["SCORINGS", "check_scoring", "ros_fitness"]
