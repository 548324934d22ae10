"""``ceamcl experiment state``: the true state of a step, the precision/recall arithmetic, and
a smoke run of the command (runs cut short)."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.experiments.state import (
    DATA_DIR,
    NOT_SCORED,
    REAL_LOGS,
    LogStateTrial,
    StateRun,
    _doubtful_section,
    kidnap_figures,
    real_log_trials,
    run_log_state_trial,
    score,
    true_states,
)
from ceamcl.filters.state import STATES, State

C = {s: i for i, s in enumerate(STATES)}
TRUTH = np.array([[1.0, 1.0, 0.0]])


def _h(*rows: tuple[float, float, float, float]) -> np.ndarray:
    return np.array([[x, y, th, w, 0.9] for x, y, th, w in rows])


def test_true_state_of_a_step() -> None:
    est = np.array([[1.1, 1.0, 0.0]])
    assert true_states(est, TRUTH, [_h((1.1, 1.0, 0.0, 1.0))], False)[0] == C[State.LOCALISED]
    # the truth and a wrong place both hold weight
    both = _h((1.1, 1.0, 0.0, 0.5), (5.0, 5.0, 0.0, 0.5))
    assert true_states(est, TRUTH, [both], False)[0] == C[State.AMBIGUOUS]
    # the truth is a minor hypothesis while a wrong place leads: still ambiguous
    minor = _h((5.0, 5.0, 0.0, 0.97), (1.1, 1.0, 0.0, 0.03))
    assert true_states(np.array([[5.0, 5.0, 0.0]]), TRUTH, [minor], False)[0] == C[State.AMBIGUOUS]
    # no hypothesis near the truth (position or heading off)
    wrong = _h((5.0, 5.0, 0.0, 0.9), (1.0, 1.0, 1.0, 0.1))
    assert true_states(est, TRUTH, [wrong], False)[0] == C[State.LOST]
    # a wrong place holding less than weight_min does not make it ambiguous
    tiny = _h((1.1, 1.0, 0.0, 0.98), (5.0, 5.0, 0.0, 0.02))
    assert true_states(est, TRUTH, [tiny], False)[0] == C[State.LOCALISED]
    # one estimate only (the Nav2 peer): localised or lost
    far = np.array([[3.0, 1.0, 0.0]])
    assert true_states(far, TRUTH, [_h((3.0, 1.0, 0.0, 1.0))], True)[0] == C[State.LOST]
    assert true_states(est, TRUTH, [_h((1.1, 1.0, 0.0, 1.0))], True)[0] == C[State.LOCALISED]


_FIELDS = [f.name for f in dataclasses.fields(StateRun)]


def _run(said: list[State], truth: list[State], kidnapped_at: tuple[int, ...] = ()) -> StateRun:
    n = len(said)
    return StateRun(
        "alg",
        "course",
        "route",
        0,
        0,
        np.arange(n) * 0.1,
        np.array([C[s] for s in said]),
        np.array([C[s] for s in truth]),
        np.zeros(n),
        np.zeros(n, dtype=np.int64),
        kidnapped_at,
    )


def test_precision_recall_and_support_skip_initialising_steps() -> None:
    L, A, X, I = State.LOCALISED, State.AMBIGUOUS, State.LOST, State.INITIALISING  # noqa: E741
    run = _run([I, A, A, L, L, L, X, L], [X, A, L, L, L, L, X, X])
    by = {s.state: s for s in score([run])}
    assert by["LOCALISED"].precision == pytest.approx(3 / 4)  # the last L was wrong
    assert by["LOCALISED"].recall == pytest.approx(3 / 4)  # one true L was called A
    assert by["LOCALISED"].support == 4
    assert by["AMBIGUOUS"].precision == pytest.approx(1 / 2)
    assert by["AMBIGUOUS"].recall == pytest.approx(1.0)
    assert by["LOST"].precision == pytest.approx(1.0)
    assert by["LOST"].recall == pytest.approx(1 / 2)  # step 0 is INITIALISING: not scored
    assert by["LOST"].support == 2


def test_steps_without_a_true_pose_are_not_scored() -> None:
    L, X = State.LOCALISED, State.LOST
    run = _run([L, L, X, L], [L, L, X, X])
    truth = run.truth.copy()
    truth[3] = NOT_SCORED  # a raw log's scan that its corrected log does not hold
    unscored = StateRun(*[truth if f == "truth" else getattr(run, f) for f in _FIELDS])
    by = {s.state: s for s in score([unscored])}
    assert by["LOCALISED"].precision == 1.0 and by["LOCALISED"].said == 2
    assert by["LOST"].recall == 1.0 and by["LOST"].support == 1
    # the same steps scored: the last LOCALISED was wrong
    assert {s.state: s for s in score([run])}["LOCALISED"].precision == pytest.approx(2 / 3)


def test_steps_where_the_truth_is_doubtful_are_reported_apart() -> None:
    L = State.LOCALISED
    run = _run([L, L, L, L], [L, L, L, State.LOST])
    doubtful = np.array([False, False, False, True])
    marked = dataclasses.replace(run, doubtful=doubtful)
    # scored as they are in the main tables ...
    assert {s.state: s for s in score([marked])}["LOCALISED"].precision == pytest.approx(3 / 4)
    # ... and without them beside: the one wrong LOCALISED lay where the truth is doubtful
    clean = {s.state: s for s in score([marked.without_doubtful()])}
    assert clean["LOCALISED"].precision == 1.0 and clean["LOST"].support == 0
    text = "\n".join(_doubtful_section([marked]))
    assert "doubtful at scans 3-3" in text and "1 scored steps of a run lie there" in text
    assert "| alg | LOCALISED | 100.0 % |" in text
    assert _doubtful_section([run]) == []  # a simulated run has no doubtful steps


def test_absent_real_logs_are_skipped_with_the_path(tmp_path: Path) -> None:
    trials, skipped = real_log_trials(["ceamcl"], 0, tmp_path)
    assert trials == []
    assert [name for name, _ in skipped] == [r.label for r in REAL_LOGS]
    assert all(str(tmp_path) in why and "absent" in why for _, why in skipped)
    # a raw log whose corrected log is missing is skipped for that one
    raw = next(r for r in REAL_LOGS if r.truth_from is not None)
    (tmp_path / raw.path).parent.mkdir(parents=True)
    (tmp_path / raw.path).write_text("")
    _, skipped = real_log_trials(["ceamcl"], 0, tmp_path)
    assert str(tmp_path / str(raw.truth_from)) in dict(skipped)[raw.label]


def test_a_raw_log_is_scored_at_its_scans_with_truth_at_nav2s_pace() -> None:
    """fr079 raw, its first 500 scans: the filter reads the robot's own odometry and updates at
    Nav2's pace; the state is scored at its updates whose scan has a true pose."""
    for r in REAL_LOGS:
        for path in (r.path, r.truth_from):
            if path is not None and not (DATA_DIR / path).is_file():
                pytest.skip(
                    f"real log {DATA_DIR / path} is absent (the shared data folder is not mounted)"
                )
    trials, skipped = real_log_trials(["ceamcl"], 0)
    assert skipped == []
    by_name = {t.name: t for t in trials}
    assert by_name["intel-corrected"].pace is None  # synthetic odometry: every scan
    raw = by_name["fr079-raw"]
    assert raw.pace is not None and raw.pace.min_d == 0.25
    short = LogStateTrial(raw.name, raw.algorithm, raw.grid, raw.log.window(0, 500), 0, raw.pace)
    run = run_log_state_trial(short)
    known = np.all(np.isfinite(short.log.true_poses), axis=1)
    assert 0 < known.sum() < known.size
    assert np.all(run.truth[~known] == NOT_SCORED)
    # held-back scans are not scored either: far fewer steps than scans with a true pose
    scored = run.truth != NOT_SCORED
    assert 20 < scored.sum() < known.sum() / 2
    by = {s.state: s for s in score([run])}
    assert by["LOCALISED"].said > 0


def test_kidnap_noticed_within_two_seconds_and_false_lost() -> None:
    L, X = State.LOCALISED, State.LOST
    said = [L] * 10 + [L] * 25 + [X] + [L] * 4
    truth = [L] * 10 + [X] * 26 + [L] * 4
    late = kidnap_figures([_run(said, truth, (10,))])[0]
    assert late.kidnaps == 1 and late.lost_within_2s == 0.0  # LOST only 2.5 s after
    steps = [L] * 10 + [X] * 3 + [L] * 2
    (early,) = kidnap_figures([_run(steps, steps, (10,))])
    assert early.lost_within_2s == 1.0 and early.false_lost == 0.0


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_state_smoke(tmp_path: Path) -> None:
    out = tmp_path / "s"
    args = ["experiment", "state", "--trials", "1", "--executor", "serial", "--quiet"]
    args += ["--algorithms", "ceamcl,mcl", "--max-time", "2", "--start-routes", "0"]
    assert main([*args, "--world", "symmetric-hall", "--out", str(out)]) == 0
    rows = _read_csv(out / "state.csv")
    assert list(rows[0]) == ["algorithm", "state", "precision", "recall", "support", "said"]
    assert [(r["algorithm"], r["state"]) for r in rows] == [
        (a, s) for a in ("ceamcl", "mcl") for s in ("LOCALISED", "AMBIGUOUS", "LOST")
    ]
    assert (out / "state.png").stat().st_size > 0
    text = (out / "state.md").read_text()
    assert "symmetric-hall" in text and "| ceamcl | AMBIGUOUS |" in text
    assert not list(out.glob("*.tmp*"))


def test_state_runs_on_each_of_its_own_scenarios_by_its_world(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--world small-office`` (the kidnapped robot, one of its three scenarios) was refused
    with "the paper's protocol runs on symmetric-hall or marked-hall"."""
    out = tmp_path / "s"
    args = ["experiment", "state", "--trials", "1", "--executor", "serial", "--quiet"]
    args += ["--algorithms", "mcl", "--max-time", "2"]
    assert main([*args, "--world", "small-office", "--out", str(out)]) == 0
    assert "small-office" in (out / "state.md").read_text()
    assert [r["algorithm"] for r in _read_csv(out / "state.csv")] == ["mcl"] * 3
    assert main([*args, "--world", "atlantis", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "the state experiment's scenarios run on small-office (the kidnapped robot)" in err
    assert "paper's protocol" not in err


def test_the_state_figure_joins_the_scans_that_have_a_true_pose(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A raw log has a true pose at some scans only (intel raw: about one in fifteen); its row
    of ``state.png`` joins those errors instead of drawing nothing between NaN gaps."""
    from ceamcl.experiments import figures

    drawn = []
    real_save = figures._save

    def keep(fig, path):  # type: ignore[no-untyped-def]
        drawn.append([line.get_xydata() for ax in fig.axes for line in ax.get_lines()])
        return real_save(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    err = np.full(30, np.nan)
    err[::10] = [0.1, 0.2, 0.3]
    codes = np.full(30, C[State.LOCALISED])
    assert figures.plot_state(
        [("raw", np.arange(30) * 0.1, codes, err)], tmp_path / "s.png"
    ).is_file()
    error_line = drawn[0][0]
    assert error_line.shape == (3, 2) and np.allclose(error_line[:, 1], [0.1, 0.2, 0.3])


def test_the_announced_run_count_includes_the_real_logs() -> None:
    """'N runs' left out the real logs' runs, which the experiment then ran too."""
    from ceamcl.cli import build_parser
    from ceamcl.cli.experiment import _state_courses, _state_runs
    from ceamcl.experiments.common import ExperimentSettings
    from ceamcl.experiments.state import present_real_logs

    args = build_parser().parse_args(["experiment", "state", "--algorithms", "ceamcl,mcl"])
    courses = _state_courses(args)
    settings = ExperimentSettings(courses[0], ("ceamcl", "mcl"), trials=3)
    simulated = sum(len(c.routes) for c in courses) * 3 * 2
    assert _state_runs(settings, args) == simulated + 2 * len(present_real_logs())
    quick = build_parser().parse_args(["experiment", "state", "--max-time", "2"])
    assert _state_runs(settings, quick) == simulated  # a quick check scores no real log
