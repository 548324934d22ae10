"""The ground truth judged against its own map (:mod:`ceamcl.io.truth_check`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ceamcl.io.truth_check import doubtful_truth, truth_fit
from ceamcl.maps.worlds import get_world
from ceamcl.sensors.scan import LaserScan
from ceamcl.simulation.scenarios import office_scenario
from ceamcl.simulation.simulator import SimulatedLog


@dataclass
class _Moved:
    """A simulated log whose true poses were replaced (a SLAM error, in effect)."""

    base: SimulatedLog
    true_poses: NDArray[np.float64] | None

    def __len__(self) -> int:
        return len(self.base)

    def scan(self, k: int) -> LaserScan:
        return self.base.scan(k)


def test_a_true_truth_explains_its_scans_and_a_wrong_stretch_is_found() -> None:
    log = office_scenario().simulate(np.random.default_rng(1))
    world = get_world("small-office")
    shares = truth_fit(log, world)
    assert np.all(np.isfinite(shares))
    assert np.median(shares) > 0.9
    clean = doubtful_truth(log, world)
    assert clean.stretches == ()
    assert "no stretch below 50 %" in clean.summary()
    # scans 100-119 placed 1.5 m off and turned 0.4 rad: the scans no longer fit the map there
    truth = log.true_poses.copy()
    truth[100:120] += np.array([1.5, -1.0, 0.4])
    truth[150] = np.nan  # a scan without truth is not judged
    moved = _Moved(log, truth)
    doubt = doubtful_truth(moved, world)
    assert math.isnan(truth_fit(moved, world)[150])
    ((first, last, lowest),) = doubt.stretches
    assert 100 <= first <= 102 and 117 <= last <= 119
    assert lowest < 0.5
    assert f"{first}-{last}" in doubt.summary()
    mask = doubt.mask(len(log))
    assert mask.sum() == last - first + 1 and mask[first] and mask[last] and not mask[first - 1]
    assert not clean.mask(len(log)).any()


def test_a_log_without_truth_has_nothing_to_judge() -> None:
    log = office_scenario().simulate(np.random.default_rng(1))
    doubt = doubtful_truth(_Moved(log, None), get_world("small-office"))
    assert math.isnan(doubt.median) and doubt.stretches == ()
    assert "no scan with a true pose" in doubt.summary()
