"""Small, cheap filters of every algorithm for the robustness tests."""

from __future__ import annotations

import numpy as np

from ceamcl.filters import LocalisationFilter, registry
from ceamcl.filters.ceamcl import CEAMCLConfig
from ceamcl.filters.registry import ALGORITHMS
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.sensors.base import SensorModel
from ceamcl.sensors.beam_model import BeamModel, BeamModelConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel

SMALL_N = 60
#: CEAMCL with a few hundred test poses.
SMALL_CEAMCL = {"n_test": 300, "test_batch": 300, "max_samples": 400, "tracking_samples": 30}


def small_sensor(name: str, grid: OccupancyGrid, max_beams: int = 30) -> SensorModel:
    if name == "beam":
        return BeamModel(grid, BeamModelConfig(max_beams=max_beams))
    return LikelihoodFieldModel(grid, LikelihoodFieldConfig(max_beams=max_beams))


def small_filter(
    algorithm: str,
    grid: OccupancyGrid,
    rng: np.random.Generator,
    sensor: SensorModel,
    *,
    resample_ess_fraction: float = 0.5,
    ceamcl_config: CEAMCLConfig | None = None,
) -> LocalisationFilter:
    """A filter with a few dozen particles (CEAMCL: a few hundred test poses), built by the
    registry like every other filter."""
    config = None
    if algorithm == "ceamcl":
        config = ceamcl_config or registry.with_config("ceamcl", **SMALL_CEAMCL)
    elif algorithm in ("mcl", "gmcl"):
        config = registry.with_config(algorithm, resample_ess_fraction=resample_ess_fraction)
    elif getattr(sensor, "config", None) is None:
        # KLD-AMCL rebuilds a model with amcl's scoring; a test double without a config cannot
        # be rebuilt, so the filter takes the double's own scoring.
        config = registry.with_config(algorithm, scoring=sensor.scoring)
    return registry.make_filter(
        algorithm, grid, rng, sensor=sensor, n_particles=SMALL_N, config=config
    )


def assert_all_finite(f: LocalisationFilter) -> None:
    """Poses, weights, estimate and hypotheses hold no NaN or inf."""
    snap = f.particles()
    assert np.all(np.isfinite(snap.poses)), f"{f.name}: non-finite particle pose"
    assert np.all(np.isfinite(snap.weights)), f"{f.name}: non-finite particle weight"
    if snap.weights.size:
        assert np.all(snap.weights >= 0)
        assert abs(float(snap.weights.sum()) - 1.0) < 1e-6
    est = f.estimate()
    assert np.all(np.isfinite(est.pose)), f"{f.name}: non-finite estimate"
    assert np.all(np.isfinite(est.covariance)), f"{f.name}: non-finite covariance"
    for h in f.hypotheses():
        assert np.all(np.isfinite(h.pose)) and np.isfinite(h.weight) and np.isfinite(h.fitness)


__all__ = ["ALGORITHMS", "SMALL_N", "assert_all_finite", "small_filter", "small_sensor"]
