"""make_filter: names, configs and sample sizes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ceamcl.errors import ConfigError
from ceamcl.filters import (
    CEAMCL,
    GMCL,
    MCL,
    CEAMCLConfig,
    GMCLConfig,
    MCLConfig,
    make_filter,
)
from ceamcl.maps.worlds import get_world


def test_a_config_reaches_its_filter() -> None:
    grid = get_world("small-office")
    f = make_filter("ceamcl", grid, np.random.default_rng(0), config=CEAMCLConfig(delta_per_m2=40))
    assert isinstance(f, CEAMCL) and f.config.delta_per_m2 == 40
    g = make_filter("gmcl", grid, np.random.default_rng(0), config=GMCLConfig(), n_particles=77)
    assert isinstance(g, GMCL) and g.config.n_particles == 77


def test_a_config_of_another_filter_is_refused() -> None:
    grid = get_world("small-office")
    with pytest.raises(ConfigError, match="mcl takes a MCLConfig, got GMCLConfig"):
        make_filter("mcl", grid, np.random.default_rng(0), config=GMCLConfig())
    with pytest.raises(ConfigError, match="config: ceamcl"):
        make_filter("ceamcl", grid, np.random.default_rng(0), config=MCLConfig())
    assert type(make_filter("mcl", grid, np.random.default_rng(0))) is MCL


def test_an_unknown_sensor_model_is_refused_before_any_run(tmp_path: Path) -> None:
    """``--sensor`` in the library: a name outside ``SENSOR_MODELS`` is a ConfigError naming
    the field and the choices, from the registry and from the runs that take it (before any
    window is cut or file written)."""
    from ceamcl.experiments.evaluate_log import evaluate_log
    from ceamcl.filters.registry import SENSOR_MODELS, check_sensor

    grid = get_world("small-office")
    for call in (
        lambda: check_sensor("sonar"),
        lambda: make_filter("mcl", grid, np.random.default_rng(0), sensor="sonar"),
        lambda: evaluate_log(None, grid, ["mcl"], sensor="sonar", out=tmp_path),  # type: ignore[arg-type]
    ):
        with pytest.raises(ConfigError, match="sensor: unknown sensor model 'sonar'") as info:
            call()
        assert all(name in str(info.value) for name in SENSOR_MODELS)
    assert not any(tmp_path.iterdir())  # nothing written
    for name in SENSOR_MODELS:
        check_sensor(name)


def test_a_run_names_the_sensor_model_its_algorithm_weighs_with() -> None:
    """``ceamcl run`` and ``summary.json`` name the model the filter weighs with: the one
    asked for, but for the Nav2 wheel, which weighs with its own beam model whatever it is
    given (as the comparisons' reports say)."""
    from ceamcl.filters.registry import SENSOR_MODELS, describe_sensor, sensor_of

    for name in SENSOR_MODELS:
        assert sensor_of("ceamcl", name) == sensor_of("mcl-tuned", name) == name
        assert sensor_of("nav2-amcl", name) == "the wheel's own beam model"
        assert describe_sensor(name) == (
            f"{name} for every algorithm but nav2-amcl (the wheel's own beam model)"
        )
