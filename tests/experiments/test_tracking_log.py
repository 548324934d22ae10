"""Tracking mode of ``evaluate-log`` (``ceamcl.experiments.tracking_log``): every algorithm
from the same perturbed true pose, scored by the APE at the scans with truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ceamcl.experiments.tracking_log import (
    START_OFFSET_M,
    START_TURN_RAD,
    TrackingTrial,
    perturbed_start,
    run_tracking_trial,
    tracking_filter,
)
from ceamcl.filters.registry import SENSOR_MODELS
from ceamcl.pose import heading_error, position_error
from ceamcl.replay import UpdatePace
from ceamcl.sensors import BeamModel, LikelihoodFieldModel
from ceamcl.simulation import office_scenario


def test_the_start_is_the_truth_moved_half_a_metre_and_turned_and_seeded() -> None:
    truth = np.array([3.0, -2.0, 3.0])
    a, b, c = perturbed_start(truth, 5), perturbed_start(truth, 5), perturbed_start(truth, 6)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert position_error(a, truth) == pytest.approx(START_OFFSET_M)
    assert heading_error(a, truth) == pytest.approx(START_TURN_RAD)


@pytest.mark.parametrize("algorithm", ["mcl", "ceamcl", "kld-amcl"])
def test_tracking_corrects_the_start_error_on_a_simulated_log(algorithm: str) -> None:
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(7), grid)
    start = perturbed_start(log.true_poses[0], 0)
    trial = TrackingTrial(algorithm, grid, log, start, 500, 0, UpdatePace(0.2, 0.2))
    r = run_tracking_trial(trial)  # type: ignore[arg-type]
    assert r.scored_scans == len(log)
    # A filter that ignored the scans would keep the 0.5 m start error (or drift further):
    # the scans must pull the estimate onto the truth and keep it there.
    assert r.ape_median_m < 0.2 and r.ape_rmse_m < 0.3
    assert r.position_errors[-10:].max() < 0.3
    assert 0 < r.updates < len(log) - 1


def test_the_rmse_outside_doubtful_truth_leaves_out_only_those_scans() -> None:
    """The figure beside the APE RMSE: the RMSE over the scored scans outside the stretches
    where the truth is doubtful (the truth check's), the same scans and errors otherwise."""
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(7), grid)
    start = perturbed_start(log.true_poses[0], 0)
    plain = run_tracking_trial(
        TrackingTrial("ceamcl", grid, log, start, 500, 0, UpdatePace(0.2, 0.2))  # type: ignore[arg-type]
    )
    assert plain.ape_rmse_outside_doubtful_m == plain.ape_rmse_m  # nothing doubtful
    doubtful = np.zeros(len(log), dtype=bool)
    doubtful[:15] = True  # the start, where the 0.5 m start error is being corrected
    marked = run_tracking_trial(
        TrackingTrial("ceamcl", grid, log, start, 500, 0, UpdatePace(0.2, 0.2), doubtful)  # type: ignore[arg-type]
    )
    pos = marked.position_errors
    assert marked.ape_rmse_m == plain.ape_rmse_m  # the run itself is the same
    assert marked.ape_rmse_outside_doubtful_m == pytest.approx(np.sqrt(np.mean(pos[15:] ** 2)))
    assert marked.ape_rmse_outside_doubtful_m < marked.ape_rmse_m


@pytest.mark.parametrize("algorithm", ["mcl", "ceamcl", "kld-amcl"])
@pytest.mark.parametrize(
    ("sensor", "model"), [("likelihood-field", LikelihoodFieldModel), ("beam", BeamModel)]
)
def test_tracking_weighs_with_the_sensor_model_it_is_given(
    algorithm: str, sensor: str, model: type
) -> None:
    """``evaluate-log --sensor``: the filter of a tracking trial weighs with that model (as
    Nav2's ``laser_model_type`` chooses), on the same map, whatever the algorithm's budget."""
    assert sensor in SENSOR_MODELS
    grid = office_scenario().grid()
    f = tracking_filter(algorithm, grid, np.random.default_rng(0), 200, sensor)
    assert type(f.sensor) is model  # type: ignore[attr-defined]
    assert f.sensor.grid is grid  # type: ignore[attr-defined]


def test_tracking_with_the_beam_model_corrects_the_start_error() -> None:
    """The beam model, chosen for a tracking trial, is what the filter weighs with: it pulls
    the perturbed start onto the truth as the default field does, and the run differs from the
    field's (the same seed and start)."""
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(7), grid)
    start = perturbed_start(log.true_poses[0], 0)
    runs = {
        sensor: run_tracking_trial(
            TrackingTrial("ceamcl", grid, log, start, 200, 0, UpdatePace(0.2, 0.2), sensor=sensor)  # type: ignore[arg-type]
        )
        for sensor in ("likelihood-field", "beam")
    }
    beam = runs["beam"]
    assert beam.ape_median_m < 0.2 and beam.ape_rmse_m < 0.3
    assert beam.position_errors[-10:].max() < 0.3
    assert not np.array_equal(beam.estimates, runs["likelihood-field"].estimates)


def test_tracking_into_a_used_folder_leaves_no_trajectory_of_an_earlier_run(
    tmp_path: Path,
) -> None:
    """A second ``--tracking`` run with fewer algorithms left the first's ``tracking-mcl.tum``
    (another seed) beside its own ``groundtruth.tum``, for evo_ape to compare without a word."""
    from ceamcl.cli import main
    from tests.robustness.hostile_cases import box_log_lines, write_lines

    write_lines("box.log", box_log_lines(30, neff=True))(tmp_path)
    out = tmp_path / "tr"
    args = ["evaluate-log", str(tmp_path / "box.log"), "--tracking", "--particles", "100"]
    args += ["--executor", "serial", "--quiet", "--out", str(out)]
    assert main([*args, "--algorithms", "mcl,kld-amcl"]) == 0
    assert {p.name for p in out.glob("tracking-*.tum")} == {
        "tracking-mcl.tum",
        "tracking-kld-amcl.tum",
    }
    (out / "notes.tum").write_text("mine\n")
    assert main([*args, "--algorithms", "kld-amcl", "--seed", "1"]) == 0
    assert {p.name for p in out.glob("*.tum")} == {
        "groundtruth.tum",
        "tracking-kld-amcl.tum",
        "notes.tum",  # not a file of the command's: left alone
    }
