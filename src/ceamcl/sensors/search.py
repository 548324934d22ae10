"""What scores a global search's test poses when the filter's own model casts rays.

A global initialisation weighs hundreds of thousands to a million test poses against the first
scan. The beam model ray-casts every beam of every pose and spends seconds on them (4.3-4.6 s
on fhw's 1,015 m^2 at 150 test poses a square metre, against 0.15-0.27 s with the likelihood
field), so a filter weighing with it searches with ROS amcl's likelihood field on the same map,
with the same hit model, beams and tempering, and its own model *judges* the best of those
poses: the best :data:`JUDGED_SHARE` of them under the field (at least :data:`JUDGED_MIN`) are
scored again with it, and only those scores decide (docs/ceamcl.md, departure 29, for CEAMCL's
section 3.1; :func:`ceamcl.filters.particles.importance_start` for the baselines'
``init_test_poses``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.beam_model import BeamModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel

#: With a search model other than the filter's (:func:`search_model`), the share of the test
#: poses, the best under the search model, that the filter's own model scores again (at least
#: :data:`JUDGED_MIN` of them).
JUDGED_SHARE = 0.05
JUDGED_MIN = 2_000


def search_model(sensor: SensorModel) -> SensorModel:
    """The model that scores a global search's test poses: the filter's own, unless it casts
    rays; for the beam model, the likelihood field with its ``z_hit``, ``z_rand``,
    ``sigma_hit_m``, ``max_beams``, ``temper`` and ``scoring`` (module docstring)."""
    if not isinstance(sensor, BeamModel):
        return sensor
    c = sensor.config
    return LikelihoodFieldModel(
        sensor.grid,
        LikelihoodFieldConfig(
            z_hit=c.z_hit,
            z_rand=c.z_rand,
            sigma_hit_m=c.sigma_hit_m,
            max_beams=c.max_beams,
            temper=c.temper,
            scoring=c.scoring,
        ),
    )


def judged_count(scored: int) -> int:
    """How many of ``scored`` test poses the filter's own model judges again."""
    return min(scored, max(JUDGED_MIN, math.ceil(JUDGED_SHARE * scored)))


def judged(scores: ArrayLike) -> NDArray[np.intp]:
    """The indices, in order, of the :func:`judged_count` best of ``scores`` (the search
    model's, one per test pose): the test poses the filter's own model scores again."""
    s = np.asarray(scores, dtype=np.float64)
    k = judged_count(s.size)
    return np.sort(np.argpartition(-s, k - 1)[:k])
