"""The measures of docs/experiments.md on hand-made per-step records."""

from __future__ import annotations

import numpy as np

from ceamcl.experiments.metrics import (
    converged_step,
    covers,
    expired_step,
    recovery_step,
    step_coverage,
    trial_metrics,
)


def test_covers_needs_both_position_and_heading() -> None:
    target = np.array([[1.0, 1.0, 3.1]])
    poses = np.array(
        [
            [1.3, 1.3, -3.1],  # 0.42 m, 0.08 rad across the +-pi seam: covers
            [1.4, 1.4, 3.1],  # 0.57 m: too far
            [1.0, 1.0, 2.7],  # 0.4 rad: wrong heading
        ]
    )
    assert covers(poses, target)[:, 0].tolist() == [True, False, False]


def test_step_coverage_counts_images_and_weight_share() -> None:
    images = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]])
    hyps = np.array(
        [
            [0.1, 0.0, 0.05, 0.5, 1.0],  # at image 0
            [10.0, 0.2, 0.0, 0.3, 1.0],  # at image 1
            [5.0, 5.0, 0.0, 0.2, 1.0],  # nowhere
        ]
    )
    covered, gathered = step_coverage(hyps, images)
    assert covered.tolist() == [True, True, False]
    assert np.isclose(gathered, 0.8)
    none, share = step_coverage(np.zeros((0, 5)), images)
    assert not none.any() and share == 0.0


def _record(pattern: list[str]) -> np.ndarray:
    """Rows like '11', '10': coverage of two images per step."""
    return np.array([[c == "1" for c in row] for row in pattern])


def test_converged_needs_all_images_and_gathered_mass() -> None:
    cov = _record(["10", "11", "11", "11"])
    gathered = np.array([1.0, 0.5, 0.95, 0.95])
    assert converged_step(cov, gathered) == 2
    assert converged_step(cov, gathered, single_estimate=True) == 0
    assert converged_step(_record(["10", "01"]), np.ones(2)) is None


def test_short_flicker_does_not_expire_but_a_held_gap_does() -> None:
    cov = _record(["11", "11", "10", "11", "11", "10", "10", "10", "11", "11"])
    # gap of 1 step at 2, gap of 3 steps at 5..7
    assert expired_step(cov, 0, hold_steps=2) == 5
    assert expired_step(cov, 0, hold_steps=4) is None
    assert expired_step(cov, None, hold_steps=1) is None


def test_gap_running_to_the_end_expires() -> None:
    cov = _record(["11", "11", "11", "01"])
    assert expired_step(cov, 0, hold_steps=10) == 3


def test_single_estimate_expires_when_it_covers_no_image() -> None:
    cov = _record(["10", "01", "00", "00", "10"])
    assert expired_step(cov, 0, hold_steps=2, single_estimate=True) == 2
    assert expired_step(cov, 0, hold_steps=2) == 1  # hypothesis mode: image 0 lost at 1


def test_recovery_needs_to_stay_localised_to_the_end() -> None:
    loc = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], dtype=bool)
    assert recovery_step(loc, 2, window_steps=10) == 6  # 4 does not stay
    assert recovery_step(loc, 2, window_steps=3) is None  # 6 is outside the window
    assert recovery_step(np.zeros(5, dtype=bool), 1, 10) is None


def test_trial_metrics_times_success_and_errors() -> None:
    n = 30
    times = np.arange(n) * 0.1
    truth = np.zeros((n, 3))
    truth[:, 0] = np.linspace(0, 3, n)
    est = truth.copy()
    est[-1, :2] += (0.3, 0.35)
    cov = np.ones((n, 2), dtype=bool)
    cov[:5] = False
    cov[20:, 1] = False
    m = trial_metrics(
        times,
        truth,
        est,
        cov,
        np.ones(n),
        np.full(n, 100, dtype=np.int64),
        np.linspace(1.0, 2.0, n),
        single_estimate=False,
        hold_s=0.5,
    )
    assert np.isclose(m.converged_s, 0.5)
    assert np.isclose(m.expired_s, 2.0)
    assert m.success and m.kept_all is False
    assert np.isclose(m.final_position_error_m, np.hypot(0.3, 0.35))
    assert m.final_estimate_ok
    assert m.mean_particles == 100
