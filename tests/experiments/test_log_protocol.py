"""The evaluate-log protocol (docs/real-data.md): non-overlapping windows, holds in metres of
travel, RMSE from the first convergence, distance to converge, "confidently wrong"."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from ceamcl.errors import ConfigError
from ceamcl.experiments.evaluate_log import (
    LogTrialResult,
    aggregate,
    confidently_wrong,
    paired_evaluations,
)
from ceamcl.experiments.log_windows import start_windows
from ceamcl.experiments.metrics import score_errors
from ceamcl.io.recorded import RecordedLog
from ceamcl.runner import RunResult


def straight_log(n: int, step_m: float) -> RecordedLog:
    poses = np.column_stack([np.arange(n) * step_m, np.zeros(n), np.zeros(n)])
    return RecordedLog(
        path="straight",
        times=np.arange(n, dtype=np.float64),
        poses=poses,
        ranges_flat=np.ones(n),
        offsets=np.arange(n + 1, dtype=np.intp),
        angle_min=np.zeros(n),
        angle_increment=np.full(n, 0.1),
        range_min=np.zeros(n),
        range_max=np.full(n, 30.0),
        laser_mount=np.zeros((n, 3)),
        true_poses=poses,
    )


def test_windows_never_overlap_and_fewer_starts_say_so() -> None:
    log = straight_log(101, 1.0)  # 100 m
    windows, what = start_windows(log, 3, window_m=30.0)
    assert len(windows) == 3 and "fit without overlap" not in what
    windows, what = start_windows(log, 10, window_m=30.0)
    assert len(windows) == 3 and "3 of the 10 starts requested fit without overlap" in what
    assert all(a[1] <= b[0] for a, b in itertools.pairwise(windows))


def test_a_window_shorter_than_the_scan_gap_is_refused_or_said_as_used() -> None:
    """``--window-s 0.001`` ran windows of 2 scans, 2-4 s long, under the title "windows of
    0.001 s"."""
    log = straight_log(21, 1.0)  # a scan a second, a metre apart
    with pytest.raises(ConfigError, match=r"window-s: 0.5 s is shorter than the gap between"):
        start_windows(log, 3, window_s=0.5)
    with pytest.raises(ConfigError, match=r"window-m: 0.5 m is shorter than the gap between"):
        start_windows(log, 3, window_m=0.5)
    # a scan every 0.1 s but for one gap of 4.1 s: the window before it is stretched, and the
    # description says which lengths were used
    times = np.r_[np.arange(10) * 0.1, 5.0 + np.arange(11) * 0.1]
    gappy = replace(log, times=times)
    windows, what = start_windows(gappy, 3, window_s=0.3)
    used = [times[e - 1] - times[s] for s, e in windows]
    assert max(used) > 4.0
    assert what.startswith(f"0.3 s ({min(used):.3g}-{max(used):.3g} s used: a window ends at")
    _, what = start_windows(log, 3, window_s=2.0)
    assert what == "2 s"  # nothing stretched: nothing added


def test_travelled_skips_scans_without_truth() -> None:
    log = straight_log(5, 1.0)
    truth = log.poses.copy()
    truth[2] = np.nan
    holey = replace(log, true_poses=truth)
    assert holey.travelled_m.tolist() == [0.0, 1.0, 1.0, 3.0, 4.0]
    assert holey.path_length_m == 4.0


def test_hold_in_metres_rmse_from_first_and_distance_to_converge() -> None:
    times = np.arange(8, dtype=np.float64)
    travelled = np.array([0, 1, 2, 3, 3, 3, 3, 3.5])  # the robot stands still from scan 3
    pos = np.array([2.0, 0.1, 0.1, 1.0, 0.1, 0.1, 0.1, 0.1])
    head = np.zeros(8)
    # 4 inside scans at the end: enough for a 3-scan hold, but only 0.5 m of travel
    assert score_errors(times, pos, head, hold=3).success
    metres = score_errors(times, pos, head, hold_m=1.0, travelled=travelled)
    assert not metres.success and metres.first_inside == 1
    held = score_errors(times, pos, head, hold_m=0.5, travelled=travelled)
    assert held.success and held.scans_to_converge == 4 and held.distance_to_converge_m == 3.0
    # the excursion at scan 3 counts in the RMSE from the first convergence, not in the other
    assert held.position_rmse_m == 0.1
    assert held.position_rmse_from_first_m == math.sqrt((6 * 0.01 + 1.0) / 7)


def result_with(hyps: np.ndarray, truth: np.ndarray) -> RunResult:
    return RunResult(
        algorithm="x",
        times=np.zeros(1),
        estimates=hyps[:1, :3],
        truth=truth[None, :],
        diagnostics=[],
        hypotheses=[hyps],
        final_particles=None,  # type: ignore[arg-type]
        initial_particles=None,  # type: ignore[arg-type]
    )


def test_confidently_wrong_needs_most_weight_on_a_wrong_hypothesis() -> None:
    truth = np.array([0.0, 0.0, 0.0])
    wrong_heavy = np.array([[5.0, 0, 0, 0.95, 1], [0.0, 0, 0, 0.05, 1]])
    wrong_unsure = np.array([[5.0, 0, 0, 0.6, 1], [0.0, 0, 0, 0.4, 1]])
    right_heavy = np.array([[0.1, 0, 0, 0.95, 1], [5.0, 0, 0, 0.05, 1]])
    assert confidently_wrong(result_with(wrong_heavy, truth))
    assert not confidently_wrong(result_with(wrong_unsure, truth))
    assert not confidently_wrong(result_with(right_heavy, truth))


def _trial(algorithm: str, steps_ms: list[float]) -> LogTrialResult:
    steps = np.asarray(steps_ms, dtype=np.float64)
    nan = math.nan
    return LogTrialResult(
        name="t",
        algorithm=algorithm,
        start_index=0,
        start_time_s=0.0,
        scans=steps.size + 1,
        window_s=1.0,
        window_m=1.0,
        success=True,
        scans_to_converge=0,
        time_to_converge_s=0.0,
        distance_to_converge_m=0.0,
        position_rmse_m=0.1,
        position_rmse_from_first_m=0.1,
        confidently_wrong=False,
        heading_rmse_rad=0.01,
        final_position_error_m=0.1,
        final_heading_error_rad=0.01,
        mean_particles=100.0,
        mean_step_ms=float(steps.mean()),
        initialisation_ms=900.0,
        updates=steps.size,
        likelihood_evaluations=nan,
        elapsed_s=np.zeros(0),
        position_errors=np.zeros(0),
        heading_errors=np.zeros(0),
        step_ms=steps,
        update_ms=steps,
    )


def test_the_median_step_pools_every_scan_and_ignores_a_recovery_spike() -> None:
    """One recovery (a 2.5 s update) moves the mean step far more than the median a robot
    meets at most scans; the table gives both, the median over every scan of every run."""
    runs = [_trial("ceamcl", [1.0, 1.0, 2500.0, 1.0]), _trial("ceamcl", [2.0, 2.0, 2.0, 2.0])]
    (row,) = aggregate(runs, ["ceamcl"])
    assert row["median_step_ms"] == 2.0  # the 8 scans pooled: 1, 1, 1, 2, 2, 2, 2, 2500
    assert row["mean_step_ms"] == np.mean([np.mean([1.0, 1.0, 2500.0, 1.0]), 2.0])
    assert row["mean_step_ms"] > 100 * row["median_step_ms"]
    # every scan updated these filters: the updates pool the same way
    assert row["median_update_ms"] == 2.0 and row["mean_update_ms"] == row["mean_step_ms"]


def test_the_error_figure_keeps_every_window_to_its_end() -> None:
    """errors.png cut every run to the shortest window; now each run counts until its own
    end, its error held from one scored scan to the next."""
    from ceamcl.experiments.figures import errors_over_time

    short = (np.array([0.0, 1.0, 2.0]), np.array([3.0, 2.0, 1.0]))
    long = (np.array([0.0, 2.0, 4.0, 6.0]), np.array([5.0, 4.0, 0.2, 0.1]))
    t, err, going = errors_over_time([short, long], points=7)
    np.testing.assert_allclose(t, [0, 1, 2, 3, 4, 5, 6])
    np.testing.assert_array_equal(going, [2, 2, 2, 1, 1, 1, 1])
    np.testing.assert_array_equal(err[0, :3], [3.0, 2.0, 1.0])
    assert np.isnan(err[0, 3:]).all()
    np.testing.assert_array_equal(err[1], [5.0, 5.0, 4.0, 4.0, 0.2, 0.2, 0.1])


def test_evaluations_at_equal_success_count_only_the_windows_both_localised() -> None:
    """Issue 17 compares evaluations "at equal success": over the windows where both
    algorithms localised, not the means over every run, which count one's failures too."""
    from dataclasses import replace

    def run(algorithm: str, start: int, ok: bool, evaluations: float) -> LogTrialResult:
        return replace(
            _trial(algorithm, [1.0]),
            start_index=start,
            success=ok,
            likelihood_evaluations=evaluations,
        )

    runs = [
        run("ceamcl", 0, True, 100.0),
        run("mcl-tuned", 0, True, 1000.0),
        run("ceamcl", 1, True, 300.0),  # mcl-tuned failed here: not compared
        run("mcl-tuned", 1, False, 5000.0),
        run("ceamcl", 2, False, 900.0),  # ceamcl failed here: not compared
        run("mcl-tuned", 2, True, 2000.0),
        run("ceamcl", 3, True, 200.0),
        run("mcl-tuned", 3, True, 1000.0),
        run("nav2-amcl", 0, True, math.nan),  # no global localisation: never compared
    ]
    (row,) = paired_evaluations(runs, ["ceamcl", "mcl-tuned", "nav2-amcl"])
    assert (row["algorithm"], row["against"], row["windows"]) == ("ceamcl", "mcl-tuned", 2)
    assert row["evaluations"] == 150.0 and row["against_evaluations"] == 1000.0
    assert row["ratio"] == 0.15
    # over every run the means differ: the pairing is what changes the figure
    means = {
        r["algorithm"]: r["likelihood_evaluations"]
        for r in aggregate(runs, ["ceamcl", "mcl-tuned"])
    }
    assert means["ceamcl"] / means["mcl-tuned"] != row["ratio"]
    # the order names the reference; one algorithm alone compares with nothing
    (back,) = paired_evaluations(runs, ["mcl-tuned", "ceamcl"])
    assert back["ratio"] == 1000.0 / 150.0
    assert paired_evaluations(runs, ["ceamcl"]) == []
    assert paired_evaluations(runs, ["ceamcl", "nav2-amcl"]) == []
    # no window both localised: a row that says so, without a ratio
    (none,) = paired_evaluations(runs[4:6], ["ceamcl", "mcl-tuned"])
    assert none["windows"] == 0 and math.isnan(none["ratio"])
