"""Tempering: how much one scan counts (a calibrated likelihood, docs/sensor-models.md).

The beam and likelihood-field models multiply per-beam likelihoods as if the beams were
independent. They are not: neighbouring beams see the same wall, and the map's errors and the
robot's pose error are shared by every beam. A product of ~60 beams with ``sigma_hit`` 0.2 m
gives a posterior a few centimetres wide, far narrower than the real error of the pose, so a
particle filter is overconfident: the truth lies outside its 2-sigma ellipse in about half of
the steps while tracking, and one unlucky scan can wipe out a correct hypothesis.

Both models therefore return ``temper * sum_k log p(z_k | x)``: the product raised to the power
``temper`` in (0, 1], as if the scan held ``temper x beams`` independent beams. The default was
chosen by measuring calibration (how often the truth lies inside the 2-sigma ellipse while
tracking, docs/sensor-models.md gives the figures); ``temper = 1`` is the textbook product.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

#: The exponent every sensor model applies to the product of beam likelihoods by default.
DEFAULT_TEMPER = 0.2


def resolve_temper(value: float | None, scoring: str) -> float:
    """The exponent in use: ``value``, or when it is ``None`` the default for the scoring
    (:data:`DEFAULT_TEMPER` for the product, 1 for amcl's sum of cubes, which takes none)."""
    if value is not None:
        return value
    return 1.0 if scoring == "ros" else DEFAULT_TEMPER


def check_temper(value: float | None) -> None:
    """A :class:`ValueError` naming the field unless ``value`` is ``None`` or ``0 < value <= 1``."""
    if value is None:
        return
    if not 0.0 < value <= 1.0:
        raise ValueError(f"temper: expected a number in (0, 1], got {value}")


def tempered(log_likelihood: NDArray[np.float64], temper: float) -> NDArray[np.float64]:
    """``temper * log_likelihood`` (the array itself when ``temper == 1``)."""
    if temper == 1.0:
        return log_likelihood
    return np.multiply(log_likelihood, temper)


class CombinedBeams:
    """What the beam model and the likelihood field share: how the per-beam values of a scan
    combine into one score (``config.scoring``: the tempered log-product, or amcl's
    ``log(1 + sum pz^3)``, :mod:`ceamcl.sensors.scoring`) and how much a scan counts
    (``config.temper``). A model's kernel returns the per-beam sum; :meth:`_combined` turns it
    into the score."""

    config: Any  # a frozen config with ``temper`` and ``scoring`` fields

    @property
    def temper(self) -> float:
        """The exponent on the product of beam likelihoods (docs/sensor-models.md)."""
        return resolve_temper(self.config.temper, self.config.scoring)

    @property
    def scoring(self) -> str:
        """How beams combine: ``"product"`` or ``"ros"`` (:mod:`ceamcl.sensors.scoring`)."""
        return str(self.config.scoring)

    def _combined(self, summed: NDArray[np.float64]) -> NDArray[np.float64]:
        """The score from the per-beam sum: tempered log-product, or ``log(1 + sum pz^3)``."""
        if self.config.scoring == "ros":
            return np.log1p(summed)
        return tempered(summed, self.temper)
