"""make_filter: names, configs and sample sizes."""

from __future__ import annotations

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
