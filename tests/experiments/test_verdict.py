"""The verdict of a real-log run (``ceamcl run``): one sentence that agrees with the error
series and with :func:`score_errors`; and the estimate jumps beside it."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.experiments.metrics import (
    HOLD_STEPS,
    JUMP_M,
    convergence_verdict,
    estimate_jumps,
    restarts,
    score_errors,
)


def _series(inside: list[bool]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.where(np.array(inside), 0.2, 5.0)
    return np.arange(len(inside)) * 2.0, pos, np.zeros(len(inside))


@pytest.mark.parametrize(
    ("inside", "status"),
    [
        ([False] * 5 + [True] * 20, "converged"),
        ([False] * 5 + [True] * 8 + [False] * 4 + [True] * 12, "converged"),
        ([False] * 5 + [True] * 30 + [False] * 10 + [True] * 6, "not held"),
        ([False] * 5 + [True] * 30 + [False] * 3, "lost"),
        ([False] * 40, "never"),
    ],
)
def test_verdict_agrees_with_the_errors_and_the_score(inside: list[bool], status: str) -> None:
    t, pos, head = _series(inside)
    v = convergence_verdict(t, (pos <= 0.5) & (head <= 0.3), float(pos[-1]))
    score = score_errors(t, pos, head)
    assert v.status == status
    assert (v.status == "converged") == score.success
    assert v.converged_scan == score.scans_to_converge
    assert v.scans_inside == sum(inside) and v.scans == len(inside)
    final = len(inside) - (max(i for i, x in enumerate(inside) if not x) + 1)
    assert v.final_stretch == final
    if status == "never":
        assert v.first_localised_scan is None and v.text.startswith("never localised")
        return
    assert v.first_localised_scan == inside.index(True) == 5
    assert v.first_localised_s == pytest.approx(10.0)
    assert "scan 5 (t = 10.0 s)" in v.text
    if status == "converged" and v.converged_scan == 5:
        assert v.text.startswith("converged at scan 5 (t = 10.0 s) and held to the end")
    elif status == "converged":  # localised, lost, back for good at scan 17
        assert v.text.startswith("converged at scan 17 (t = 34.0 s) and held to the end")
        assert "first localised at scan 5 (t = 10.0 s), inside 20 of 29 scans" in v.text
    elif status == "not held":
        # the intel case: right at the end, but not for long enough to call it converged
        assert f"only for the last 6 scans (fewer than {HOLD_STEPS})" in v.text
        assert v.longest_stretch == (5, 30)
    else:
        assert "lost at the end (final error 5.00 m)" in v.text


def test_heading_outside_the_tolerance_is_not_localised() -> None:
    t, pos, head = _series([True] * 20)
    head[:] = 0.5
    assert convergence_verdict(t, (pos <= 0.5) & (head <= 0.3), 0.2).status == "never"


def test_jumps_are_motion_the_odometry_does_not_explain() -> None:
    # The robot drives 1 m per scan along x; the estimate follows, except at scan 6, where
    # it hops 10 m sideways, and comes back at scan 7.
    odo = np.column_stack([np.arange(10.0), np.zeros(10), np.zeros(10)])
    est = odo + np.array([3.0, 2.0, 0.0])  # an offset the odometry cannot see: no jump
    est[6, 1] += 10.0
    j = estimate_jumps(est, odo)
    assert j.largest_m == pytest.approx(10.0)
    assert j.largest_at_scan in (6, 7)
    assert j.over_threshold == 2
    # From scan 7 on only the hop back is counted.
    later = estimate_jumps(est, odo, from_scan=6)
    assert later.largest_at_scan == 7 and later.over_threshold == 1
    # A turn: odometry rotates by 90 degrees and moves 1 m; the estimate, rotated too, follows.
    odo2 = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, np.pi / 2]])
    est2 = np.array([[5.0, 5.0, np.pi / 2], [4.0, 5.0, np.pi]])
    assert estimate_jumps(est2, odo2).largest_m == pytest.approx(0.0, abs=1e-9)
    assert estimate_jumps(est2, odo2).over_threshold == 0 < JUMP_M


def test_no_jump_measured_on_one_scan() -> None:
    j = estimate_jumps(np.zeros((1, 3)), np.zeros((1, 3)))
    assert j.largest_at_scan is None and j.over_threshold == 0


def test_restarts_count_every_reinitialisation_after_the_first() -> None:
    from ceamcl.filters.base import StepDiagnostics, StepRecord
    from ceamcl.filters.ceamcl.records import CEAMCLRecord, Events

    steps = [
        StepDiagnostics(0, 10, 1.0, 1.0, CEAMCLRecord()),  # the first initialisation
        StepDiagnostics(1, 10, 1.0, 1.0, CEAMCLRecord()),
        StepDiagnostics(2, 10, 1.0, 1.0, CEAMCLRecord(reinitialised=True)),  # species extinct
        StepDiagnostics(3, 10, 1.0, 1.0, CEAMCLRecord()),
        StepDiagnostics(
            4, 10, 1.0, 1.0, CEAMCLRecord(reinitialised=True, events=Events(recoveries=1))
        ),
    ]
    assert restarts(steps) == {"restarts": 2, "restart_scans": [2, 4], "kidnap_recoveries": 1}
    mcl = [StepDiagnostics(k, 5, 1.0, 1.0, StepRecord(reinitialised=k == 3)) for k in range(5)]
    assert restarts(mcl) == {"restarts": 1, "restart_scans": [3], "kidnap_recoveries": 0}
