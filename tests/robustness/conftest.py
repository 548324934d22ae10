"""Robustness suite: bad input, scan semantics, numerics, fuzzing, soak, determinism.

``@pytest.mark.slow`` tests here (the 100,000-step soak) run only when selected with
``-m slow`` or with ``CEAMCL_SLOW=1`` in the environment.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from ceamcl.maps.grid import FREE, OCCUPIED, OccupancyGrid


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if "slow" in (config.getoption("-m") or "") or os.environ.get("CEAMCL_SLOW") == "1":
        return
    skip = pytest.mark.skip(reason="slow soak: select with -m slow or CEAMCL_SLOW=1")
    here = os.path.dirname(__file__)
    for item in items:
        if "slow" in item.keywords and str(item.path).startswith(here):
            item.add_marker(skip)


def box_grid(size: int = 40, resolution: float = 0.1) -> OccupancyGrid:
    """A walled square room with one pillar off-centre (so poses are distinguishable)."""
    data = np.full((size, size), FREE, dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = OCCUPIED
    data[size // 4 : size // 4 + 3, size // 5 : size // 5 + 3] = OCCUPIED
    return OccupancyGrid(data, resolution, (0.0, 0.0, 0.0), name="box")
