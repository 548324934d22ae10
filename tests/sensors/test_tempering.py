"""Tempering (sensors/tempering.py): the log-likelihood scales by ``temper``; fitness does not."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.maps.worlds import symmetric_hall
from ceamcl.sensors.base import fitness
from ceamcl.sensors.beam_model import BeamModel, BeamModelConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel
from ceamcl.sensors.scan import LaserGeometry


@pytest.mark.parametrize("kind", ["beam", "likelihood-field"])
def test_temper_scales_the_log_likelihood_and_leaves_fitness_alone(kind: str) -> None:
    grid = symmetric_hall()
    rng = np.random.default_rng(3)
    free = np.argwhere(grid.free_mask)[rng.choice(int(grid.free_mask.sum()), 50)]
    x, y = grid.cell_to_world(free[:, 1], free[:, 0])
    poses = np.column_stack([x, y, rng.uniform(-np.pi, np.pi, 50)])
    geometry = LaserGeometry.covering(np.pi, 181, 8.0)
    scan = geometry.scan(rng.uniform(0.5, 8.0, geometry.n_beams))

    def model(temper: float):
        if kind == "beam":
            return BeamModel(grid, BeamModelConfig(temper=temper))
        return LikelihoodFieldModel(grid, LikelihoodFieldConfig(temper=temper))

    full, soft = model(1.0), model(0.1)
    prepared = full.prepare(scan)
    ll_full = full.log_likelihood(poses, prepared)
    ll_soft = soft.log_likelihood(poses, prepared)
    np.testing.assert_allclose(ll_soft, 0.1 * ll_full, rtol=1e-12)
    np.testing.assert_allclose(soft.log_likelihood_reference(poses, prepared), ll_soft, rtol=1e-9)
    np.testing.assert_allclose(
        fitness(ll_soft, prepared, soft), fitness(ll_full, prepared, full), rtol=1e-9
    )


@pytest.mark.parametrize("bad", [0.0, -0.5, 1.5, float("nan")])
def test_temper_outside_zero_one_is_refused_naming_the_field(bad: float) -> None:
    with pytest.raises(ValueError, match="temper"):
        BeamModelConfig(temper=bad)
    with pytest.raises(ValueError, match="temper"):
        LikelihoodFieldConfig(temper=bad)
