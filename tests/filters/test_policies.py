"""Tests of the update and resampling policies (``ceamcl.filters.policies``)."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters.particles import ParticleSet
from ceamcl.filters.policies import Context, ess_below, every_n, on_motion


def test_on_motion_tests_each_axis_and_the_wrapped_turn() -> None:
    p = on_motion(0.25, 0.2)
    assert not p(Context(np.array([0.2, -0.2, 0.1])))
    assert p(Context(np.array([0.26, 0.0, 0.0])))
    assert p(Context(np.array([0.0, -0.26, 0.0])))
    assert p(Context(np.array([0.0, 0.0, -0.21])))
    # A full turn and a bit is a small turn.
    assert not p(Context(np.array([0.0, 0.0, 2 * np.pi + 0.1])))


def test_every_n_fires_on_multiples() -> None:
    p = every_n(3)
    assert [p(Context(count=k)) for k in range(1, 8)] == [False, False, True] * 2 + [False]
    with pytest.raises(ValueError, match="n >= 1"):
        every_n(0)


def test_ess_below_and_combinations() -> None:
    ps = ParticleSet.from_poses(np.zeros((4, 3)))
    even = Context(particles=ps)
    assert not ess_below(0.5)(even)  # ESS = N
    ps.log_weights = np.log([0.97, 0.01, 0.01, 0.01])
    skewed = Context(particles=ps, count=2)
    assert ess_below(0.5)(skewed)
    assert (ess_below(0.5) & every_n(2))(skewed)
    assert not (ess_below(0.5) & every_n(3))(skewed)
    assert (every_n(3) | ess_below(0.5))(skewed)
    assert not (every_n(3) | on_motion(1.0, 1.0))(skewed)
