"""The whole suite: ``make test`` runs it on two pytest-xdist workers (``-n 2``).

An xdist worker is started with ``COLUMNS=80`` and ``LINES=24`` in its environment (execnet
sets them for its child processes), which the command line reads as the user's terminal
width (:func:`ceamcl.cli.main`). The suite removes them in a worker, so a test sees
the environment of a serial run (no width set: tables of 100 columns, as a pipe gets).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest

if os.environ.get("PYTEST_XDIST_WORKER"):
    for name in ("COLUMNS", "LINES"):
        os.environ.pop(name, None)


@pytest.fixture
def model_evaluations(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Poses the beam model (``"beam"``) and the likelihood field (``"field"``) score from
    here on in the test, counted as their ``log_likelihood`` is called."""
    from ceamcl.sensors import BeamModel, LikelihoodFieldModel

    counts = {"beam": 0, "field": 0}
    for cls, key in ((BeamModel, "beam"), (LikelihoodFieldModel, "field")):
        real = cls.log_likelihood

        def counting(self: Any, poses: Any, prepared: Any, _r: Any = real, _k: str = key) -> Any:
            counts[_k] += int(np.asarray(poses).reshape(-1, 3).shape[0])
            return _r(self, poses, prepared)

        monkeypatch.setattr(cls, "log_likelihood", counting)
    return counts
