"""What CEAMCL reports as its pose: the leading species' mean (the default), or the species
read at the scan's untempered likelihood (``CEAMCLConfig.estimate_likelihood="full"``,
docs/ceamcl.md departure 35). The real-log claim of ``"full"`` (closer to the truth than the
species' mean on intel raw) is in ``tests/test_raw_logs.py``."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.resampling import normalise_log_weights
from ceamcl.motion.odometry import increment_between
from ceamcl.pose import pose_mean
from ceamcl.simulation.scenarios import office_scenario

FULL = CEAMCLConfig(estimate_likelihood="full")


def tracked(steps: int = 12, config: CEAMCLConfig | None = None, **sensor: object) -> CEAMCL:
    """CEAMCL tracking the simulated small office from its true start for ``steps`` updates."""
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(3), grid)
    f = make_filter(
        "ceamcl",
        grid,
        np.random.default_rng(4),
        config=config,
        sensor_settings=sensor or None,
    )
    assert isinstance(f, CEAMCL)
    f.initialise_pose(log.true_poses[0], np.diag([0.01, 0.01, 0.005]))
    for k in range(1, steps + 1):
        f.step(increment_between(log.odometry[k - 1], log.odometry[k]), log.scan(k))
    return f


def test_full_weighs_the_leader_by_the_untempered_likelihood() -> None:
    f = tracked(config=FULL)
    lead = f.fittest()
    assert lead is not None
    temper = f.sensor.temper
    assert temper < 1.0  # the default sensor tempers its product
    ll = f.particle_set.loglik[lead.members]
    _, weights, ok = normalise_log_weights(ll / temper)  # exp(ll / temper), normalised
    assert ok
    expected = pose_mean(f.particle_set.poses[lead.members], weights)
    est = f.estimate()
    np.testing.assert_array_equal(est.pose, expected)
    np.testing.assert_array_equal(est.covariance, lead.covariance)
    # it is not the species' mean (the weights are sharper), and it stays among the samples
    assert not np.array_equal(est.pose, lead.mean)
    assert np.hypot(*(est.pose[:2] - lead.mean[:2])) < 2.0 * np.sqrt(lead.cov_xy.trace())
    # the hypotheses keep the species' means (what the state and the competition read)
    assert np.array_equal(f.hypotheses()[0].pose, lead.mean)


def test_the_default_reads_the_species_mean() -> None:
    assert CEAMCLConfig().estimate_likelihood == "tempered"
    f = tracked()
    lead = f.fittest()
    assert lead is not None
    assert np.array_equal(f.estimate().pose, lead.mean)


def test_with_amcls_scoring_there_is_no_tempering_to_undo() -> None:
    """amcl's sum of cubes takes no temper (1): ``"full"`` reads the species' mean."""
    f = tracked(config=FULL, scoring="ros")
    lead = f.fittest()
    assert lead is not None and f.sensor.temper == 1.0
    assert np.array_equal(f.estimate().pose, lead.mean)


def test_a_species_no_sample_of_which_fits_still_gives_a_finite_estimate() -> None:
    f = tracked(steps=3, config=FULL)
    lead = f.fittest()
    assert lead is not None
    f.particle_set.loglik[:] = -np.inf  # every sample impossible under the last scan
    est = f.estimate()
    assert np.all(np.isfinite(est.pose))
    assert np.array_equal(est.pose, lead.mean)


def test_an_unknown_reading_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match="estimate_likelihood"):
        CEAMCLConfig(estimate_likelihood="mode")
