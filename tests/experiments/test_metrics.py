"""The measures of docs/experiments.md on hand-made per-step records."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ceamcl.experiments.metrics import (
    StepPrecision,
    confidently_wrong,
    converged_step,
    covers,
    expired_step,
    image_index,
    likelihood_evaluations,
    nearest_error,
    precision_summary,
    recovery_step,
    step_coverage,
    trial_metrics,
    weight_shares,
)
from ceamcl.filters.base import StepDiagnostics, StepRecord
from ceamcl.maps.worlds import symmetric_images


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


def _precision(
    n: int, heaviest: np.ndarray | None = None, evaluations: np.ndarray | None = None
) -> StepPrecision:
    return StepPrecision(
        true_image_weight=np.linspace(0.5, 0.9, n),
        spurious_weight=np.linspace(0.5, 0.1, n),
        truth_weight=np.linspace(0.1, 0.3, n),
        heaviest_weight=np.full(n, 0.25) if heaviest is None else heaviest,
        nearest_position_error=np.linspace(1.0, 0.1, n),
        nearest_heading_error=np.linspace(0.5, 0.05, n),
        likelihood_evaluations=evaluations,
    )


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
        _precision(n),
        single_estimate=False,
        hold_s=0.5,
    )
    assert np.isclose(m.converged_s, 0.5)
    assert np.isclose(m.expired_s, 2.0)
    assert m.success and m.kept_all is False
    assert np.isclose(m.final_position_error_m, np.hypot(0.3, 0.35))
    assert m.final_estimate_ok
    assert m.mean_particles == 100


# ---------------------------------------------------------------- the precision side
HALL_TRUTH = np.array([3.75, 3.75, np.pi / 2])  # room 0's centre, facing north


def hall_hypotheses(rows: list[tuple[int | None, float]]) -> np.ndarray:
    """Hypotheses ``(H, 5)`` of the given weights: at symmetric image ``k`` of HALL_TRUTH
    (0: the truth itself), offset by 0.2 m and 0.1 rad (inside the tolerances), or, for
    ``None``, at the truth's place with a heading 90 degrees off (spurious)."""
    images = symmetric_images(HALL_TRUTH)
    out = []
    for k, w in rows:
        if k is None:
            pose = HALL_TRUTH + np.array([0.0, 0.0, np.pi / 2])
        else:
            pose = images[k] + np.array([0.2, 0.0, 0.1])
        out.append([*pose, w, 1.0])
    return np.array(out)


def test_weight_at_symmetric_images_is_true_and_the_rest_spurious() -> None:
    images = symmetric_images(HALL_TRUTH)
    hyps = hall_hypotheses([(2, 0.3), (0, 0.2), (None, 0.4), (3, 0.1)])
    w = weight_shares(hyps, images)
    assert w.true_images == pytest.approx(0.6)  # images 2, 0 and 3
    assert w.spurious == pytest.approx(0.4)  # right place, wrong heading
    assert w.heaviest == pytest.approx(0.4)
    assert w.truth == pytest.approx(0.2)  # image 0 only
    # only the truth as an image (a world without symmetry): images 2 and 3 become spurious
    alone = weight_shares(hyps, images[:1])
    assert alone.true_images == pytest.approx(0.2) and alone.spurious == pytest.approx(0.8)


def test_weight_shares_are_normalised_and_empty_holds_nothing() -> None:
    images = symmetric_images(HALL_TRUTH)
    hyps = hall_hypotheses([(1, 3.0), (None, 1.0)])  # weights not summing to 1
    w = weight_shares(hyps, images)
    assert (w.true_images, w.spurious, w.heaviest, w.truth) == pytest.approx((0.75, 0.25, 0.75, 0))
    for empty in (np.zeros((0, 5)), hall_hypotheses([(0, 0.0)])):
        z = weight_shares(empty, images)
        assert (z.true_images, z.spurious, z.heaviest, z.truth) == (0.0, 0.0, 0.0, 0.0)


def test_a_hypothesis_just_outside_the_tolerance_is_spurious() -> None:
    images = symmetric_images(HALL_TRUTH)

    def at(offset: tuple[float, float, float]) -> np.ndarray:
        return np.array([[*(images[1] + np.array(offset)), 0.5, 1.0]])

    near, far, turned = at((0.49, 0.0, 0.0)), at((0.51, 0.0, 0.0)), at((0.0, 0.0, 0.31))
    assert weight_shares(near, images).true_images == 1.0
    assert weight_shares(far, images).spurious == 1.0
    assert weight_shares(turned, images).spurious == 1.0


def test_nearest_error_is_the_hypothesis_nearest_in_position() -> None:
    truth = np.array([1.0, 1.0, 0.0])
    hyps = np.array(
        [
            [9.0, 1.0, 0.0, 0.9, 1.0],  # heaviest, 8 m away
            [1.3, 1.4, 0.2, 0.05, 1.0],  # 0.5 m, 0.2 rad: the nearest
            [1.0, 1.6, 0.0, 0.05, 1.0],  # 0.6 m
        ]
    )
    pos, head = nearest_error(hyps, truth)
    assert pos == pytest.approx(0.5) and head == pytest.approx(0.2)
    assert all(math.isnan(v) for v in nearest_error(np.zeros((0, 5)), truth))


def test_confidently_wrong_needs_a_wrong_estimate_and_a_dominant_hypothesis() -> None:
    ok = np.array([True, False, False, False])
    heaviest = np.array([0.95, 0.95, 0.89, 0.9])
    assert confidently_wrong(ok, heaviest).tolist() == [False, True, False, True]
    assert bool(confidently_wrong(False, 0.5, share=0.5))


def test_four_equal_images_are_not_confidently_wrong_but_one_wrong_image_is() -> None:
    images = symmetric_images(HALL_TRUTH)
    equal = hall_hypotheses([(2, 0.25), (0, 0.25), (1, 0.25), (3, 0.25)])
    # the estimate is the fittest (first) hypothesis, image 2: wrong, but not confident
    ok = bool(covers(equal[:1, :3], HALL_TRUTH[None, :])[0, 0])
    assert not ok
    assert not confidently_wrong(ok, weight_shares(equal, images).heaviest)
    committed = hall_hypotheses([(2, 0.93), (0, 0.07)])
    assert confidently_wrong(ok, weight_shares(committed, images).heaviest)
    # committed to the truth: confident and right
    right = hall_hypotheses([(0, 0.93), (2, 0.07)])
    ok_right = bool(covers(right[:1, :3], HALL_TRUTH[None, :])[0, 0])
    assert ok_right and not confidently_wrong(ok_right, weight_shares(right, images).heaviest)


def _diag(step: int, evaluations: int, record: StepRecord | None = None) -> StepDiagnostics:
    return StepDiagnostics(step, 10, 5.0, 1.0, record or StepRecord(False, evaluations, False))


def test_likelihood_evaluations_count_the_initialisation_step() -> None:
    diags = [_diag(0, 1_000_000), _diag(1, 300), _diag(2, 0), _diag(3, 280)]
    evals = likelihood_evaluations(diags)
    assert evals is not None and evals.tolist() == [1_000_000, 300, 0, 280]


def test_likelihood_evaluations_not_counted_is_none_not_zero() -> None:
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Hidden(StepRecord):
        likelihood_evaluations_counted: bool = False

    assert likelihood_evaluations([_diag(0, 0), _diag(1, 0, Hidden())]) is None


def test_trial_metrics_report_the_precision_side_at_the_goal() -> None:
    n = 10
    times = np.arange(n) * 0.1
    truth = np.zeros((n, 3))
    est = truth.copy()
    est[6:, 0] = 7.5  # the estimate jumps to another image for the last 4 steps
    heaviest = np.full(n, 0.95)
    heaviest[8] = 0.5  # not confident at step 8
    evals = np.array([1_000_000] + [500] * (n - 1), dtype=np.int64)
    m = trial_metrics(
        times,
        truth,
        est,
        np.ones((n, 1), dtype=bool),
        np.ones(n),
        np.full(n, 100, dtype=np.int64),
        np.ones(n),
        _precision(n, heaviest, evals),
        single_estimate=False,
    )
    assert m.confidently_wrong and not m.final_estimate_ok
    assert m.confidently_wrong_share == pytest.approx(0.3)  # steps 6, 7 and 9
    assert m.true_image_weight == pytest.approx(0.9)
    assert m.spurious_weight == pytest.approx(0.1)
    assert m.truth_weight == pytest.approx(0.3)
    assert m.heaviest_weight == pytest.approx(0.95)
    assert m.nearest_position_error_m == pytest.approx(0.1)
    assert m.nearest_heading_error_rad == pytest.approx(0.05)
    assert m.likelihood_evaluations == 1_000_000 + 500 * (n - 1)
    assert m.initialisation_likelihood_evaluations == 1_000_000
    none = trial_metrics(
        times,
        truth,
        truth,
        np.ones((n, 1), dtype=bool),
        np.ones(n),
        np.full(n, 100, dtype=np.int64),
        np.ones(n),
        _precision(n, heaviest, None),
        single_estimate=True,
    )
    assert none.likelihood_evaluations is None and not none.confidently_wrong


def test_precision_summary_means_rates_and_uncounted_evaluations() -> None:
    n = 4
    times = np.arange(n) * 0.1
    truth = np.zeros((n, 3))
    runs = []
    for shift, evals in ((0.0, 1000), (7.5, 3000)):
        est = truth.copy()
        est[:, 0] += shift
        runs.append(
            trial_metrics(
                times,
                truth,
                est,
                np.ones((n, 1), dtype=bool),
                np.ones(n),
                np.full(n, 10, dtype=np.int64),
                np.ones(n),
                _precision(n, np.full(n, 0.95), np.full(n, evals // n, dtype=np.int64)),
                single_estimate=False,
            )
        )
    p = precision_summary(runs)
    assert p.confidently_wrong_rate == pytest.approx(0.5)  # the run whose estimate is off
    assert p.likelihood_evaluations == pytest.approx(2000)
    assert p.initialisation_likelihood_evaluations == pytest.approx(500)
    assert p.spurious_weight == pytest.approx(0.1)
    uncounted = trial_metrics(
        times,
        truth,
        truth,
        np.ones((n, 1), dtype=bool),
        np.ones(n),
        np.full(n, 10, dtype=np.int64),
        np.ones(n),
        _precision(n),
        single_estimate=True,
    )
    assert precision_summary([*runs, uncounted]).likelihood_evaluations is None
    with pytest.raises(ValueError, match="no runs"):
        precision_summary([])


def test_image_index_names_the_image_each_hypothesis_sits_at() -> None:
    images = symmetric_images(HALL_TRUTH)
    hyps = hall_hypotheses([(2, 0.3), (0, 0.2), (None, 0.4), (3, 0.1)])
    assert image_index(hyps, images).tolist() == [2, 0, -1, 3]
    assert image_index(hyps, images[:1]).tolist() == [-1, 0, -1, -1]
    assert image_index(np.zeros((0, 5)), images).size == 0
