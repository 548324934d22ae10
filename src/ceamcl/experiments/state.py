"""``ceamcl experiment state``: is the localisation state a filter reports right? (issue 14)

Each step of each run gets a *true* state, from the truth and what the filter holds:

* LOST: no hypothesis is within 0.5 m and 0.3 rad of the truth (the issue's "no hypothesis
  near the truth");
* AMBIGUOUS: a hypothesis is near the truth and at least one wrong place (a hypothesis outside
  the tolerances of the truth) holds weight, a share of at least ``weight_min`` (the threshold
  the filter's state uses);
* LOCALISED: a hypothesis is near the truth, no wrong place holds weight, and the estimate is
  within the tolerances (otherwise LOST).

A filter that shows only an estimate (the Nav2 peer) has one hypothesis, its estimate: true
LOCALISED when it is within the tolerances, LOST otherwise. Steps at which the filter says
INITIALISING are not scored. For each algorithm and state ``S``: precision = the share of the
steps where it said ``S`` at which the truth was ``S``; recall = the share of the steps whose
truth was ``S`` at which it said ``S``; support = the steps whose truth was ``S``.

Scenarios: the kidnapped robot on ``small-office``, the four rooms of ``symmetric-hall`` and of
``marked-hall`` (the paper's protocol), each ``--trials`` times per route from ``--seed``; and
the real logs of ``../shared/data`` (:data:`REAL_LOGS`), one global localisation from the first
scan per algorithm: the corrected logs of ``carmen/`` (truth: their SLAM-corrected poses;
odometry: synthetic from those poses, seeded; every scan an update) and the raw logs of
``carmen-raw/`` (the robot's own odometry and every scan, updates at Nav2's pace as
``ceamcl run`` makes them; truth: the corrected log's poses at the scans the two share, as
``--truth-from`` pairs them). The map is built from the corrected log, as ``ceamcl run`` does.
On a paced log the state is scored at the filter's steps, as everywhere: at each update whose
scan has a true pose (between updates the filter reads no scan and its state is the last
update's, its estimate carried along by the odometry; Nav2 publishes ``amcl_pose`` at updates
too). A log that is absent is skipped and the reason written to ``state.md``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ceamcl.experiments.common import (
    ExperimentSettings,
    group_by,
    make_trials,
    markdown_table,
    metadata_markdown,
    write_csv,
    write_text,
)
from ceamcl.experiments.executors import ProgressCallback, map_trials, open_executor
from ceamcl.experiments.metrics import HEADING_TOL_RAD, POSITION_TOL_M, within
from ceamcl.experiments.routes import Course, kidnapped_course, paper_course
from ceamcl.experiments.trials import Trial, localise_trial
from ceamcl.filters import registry
from ceamcl.filters.state import DEFAULT_THRESHOLDS, STATES, State
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.results import ensure_output_dir
from ceamcl.maps.grid import OccupancyGrid

if TYPE_CHECKING:  # replay imports the experiments' metrics: imported where used
    from ceamcl.replay import UpdatePace

#: The algorithms the issue asks for, when ``--algorithms`` is not given.
DEFAULT_ALGORITHMS = ("ceamcl", "kld-amcl-recovery", "nav2-amcl")
#: A kidnap counts as noticed when the filter says LOST within this time of it.
LOST_WITHIN_S = 2.0
#: State codes in the per-step arrays (index into :data:`STATES`; -1: not scored).
_CODE = {s: i for i, s in enumerate(STATES)}


@dataclass(frozen=True)
class RealLog:
    """A real log the experiment scores: its label, its path under :data:`DATA_DIR`, and for a
    raw log the corrected log of the same run that gives its truth (``--truth-from``)."""

    label: str
    path: str
    truth_from: str | None = None


#: The real logs scored (``../shared/data``). freiburg-079-corrected (4,791 scans, every one
#: an update with synthetic odometry) is left out to keep the experiment within minutes; its
#: run is scored through the raw log fr079, at Nav2's pace.
REAL_LOGS = (
    RealLog("intel-corrected", "carmen/intel-corrected.log.gz"),
    RealLog("fhw-corrected", "carmen/fhw-corrected.log.gz"),
    RealLog("intel-raw", "carmen-raw/intel.clf.gz", "carmen/intel-corrected.log.gz"),
    RealLog("fr079-raw", "carmen-raw/fr079.clf.gz", "carmen/freiburg-079-corrected.log.gz"),
)
#: Where the real logs are: ``../shared/data``, beside the project's folder (the source
#: tree's root: ``src/ceamcl/experiments`` -> three levels up).
DATA_DIR = Path(__file__).resolve().parents[3].parent / "shared" / "data"
#: The true state of a step that is not scored (no true pose, or no update on a paced log).
NOT_SCORED = -1


def default_courses() -> tuple[Course, ...]:
    """The issue's scenarios: kidnapped small-office, symmetric-hall, marked-hall."""
    return (kidnapped_course(), paper_course("symmetric-hall"), paper_course("marked-hall"))


def true_states(
    estimates: NDArray[np.float64],
    truth: NDArray[np.float64],
    hypotheses: Sequence[NDArray[np.float64]],
    single_estimate: bool,
    weight_min: float = DEFAULT_THRESHOLDS.weight_min,
) -> NDArray[np.int64]:
    """The true state code of each step (see the module docstring); ``hypotheses[k]`` rows
    ``x, y, theta, weight, ...`` as :class:`~ceamcl.runner.RunResult` keeps them."""
    n = truth.shape[0]
    out = np.full(n, _CODE[State.LOST], dtype=np.int64)
    ok = within(estimates, truth)
    for k in range(n):
        if single_estimate:
            out[k] = _CODE[State.LOCALISED] if ok[k] else _CODE[State.LOST]
            continue
        h = hypotheses[k]
        if h.shape[0] == 0:
            continue
        w = np.nan_to_num(h[:, 3])
        total = w.sum()
        w = w / total if total > 0 else w
        near = within(h[:, :3], truth[k][None, :])
        holds = w >= weight_min
        if not np.any(near):
            out[k] = _CODE[State.LOST]
        elif np.any(~near & holds):
            out[k] = _CODE[State.AMBIGUOUS]
        else:
            out[k] = _CODE[State.LOCALISED] if ok[k] else _CODE[State.LOST]
    return out


@dataclass(frozen=True, eq=False)
class StateRun:
    """One run: what the filter said and what was true, step by step."""

    algorithm: str
    course: str
    route: str
    repetition: int
    seed: int
    times: NDArray[np.float64]
    said: NDArray[np.int64]  # (T,) state codes (index into STATES)
    truth: NDArray[np.int64]  # (T,) true state codes
    position_error: NDArray[np.float64]  # (T,) of the estimate, m
    hypotheses: NDArray[np.int64]  # (T,) the state's hypothesis count
    kidnapped_at: tuple[int, ...]
    #: (T,) steps where a real log's truth is doubtful (:mod:`ceamcl.io.truth_check`); scored
    #: like the others, and reported apart in ``state.md``
    doubtful: NDArray[np.bool_] | None = None

    def without_doubtful(self) -> StateRun:
        """This run with its doubtful steps not scored."""
        if self.doubtful is None:
            return self
        truth = self.truth.copy()
        truth[self.doubtful] = NOT_SCORED
        return replace(self, truth=truth, doubtful=None)


def run_state_trial(trial: Trial) -> StateRun:
    """Simulate, localise globally, and record the filter's state and the true state."""
    log, result = localise_trial(trial)
    single = registry.get(trial.algorithm).reports == "estimate"
    truth = np.asarray(log.true_poses, dtype=np.float64)
    said = np.array(
        [_CODE[s.state] if s is not None else -1 for s in result.states], dtype=np.int64
    )
    counts = np.array([s.n_hypotheses if s is not None else 0 for s in result.states])
    errors = result.position_errors
    assert errors is not None  # a simulated log always has its truth
    return StateRun(
        algorithm=trial.algorithm,
        course=trial.course.name,
        route=trial.route,
        repetition=trial.repetition,
        seed=trial.seed,
        times=result.times,
        said=said,
        truth=true_states(result.estimates, truth, result.hypotheses, single),
        position_error=errors,
        hypotheses=counts,
        kidnapped_at=tuple(log.kidnapped_at),
    )


@dataclass(frozen=True, eq=False)
class LogStateTrial:
    """Global localisation with ``algorithm`` over a whole real log with its truth."""

    name: str
    algorithm: str
    grid: OccupancyGrid
    log: RecordedLog
    seed: int
    #: Nav2's update pace on a log with the robot's own odometry; ``None``: every scan
    pace: UpdatePace | None = None
    #: the scans of ``log`` where the truth is doubtful
    #: (:meth:`ceamcl.io.truth_check.TruthDoubt.mask`); ``None``: none
    doubtful: NDArray[np.bool_] | None = None


def run_log_state_trial(trial: LogStateTrial) -> StateRun:
    """A real log: the filter's state and the true state at every step (:data:`NOT_SCORED`
    where the scan has no true pose, a raw log's scan its corrected log does not hold, and on
    a paced log where the filter did not update)."""
    from ceamcl.replay import filter_rng, make_paced_filter
    from ceamcl.runner import run_filter

    f = make_paced_filter(trial.algorithm, trial.grid, filter_rng(trial.seed, 0, trial.algorithm))
    result = run_filter(
        f, trial.log, update_when=None if trial.pace is None else trial.pace.policy()
    )
    assert result.truth is not None and result.position_errors is not None
    single = registry.get(trial.algorithm).reports == "estimate"
    truth = true_states(result.estimates, result.truth, result.hypotheses, single)
    stepped = np.array([d.stepped for d in result.diagnostics], dtype=bool)
    truth[~(result.truth_known & stepped)] = NOT_SCORED
    return StateRun(
        algorithm=trial.algorithm,
        course=trial.name,
        route="whole log",
        repetition=0,
        seed=trial.seed,
        times=result.times,
        said=np.array(
            [_CODE[s.state] if s is not None else -1 for s in result.states], dtype=np.int64
        ),
        truth=truth,
        position_error=result.position_errors,
        hypotheses=np.array([s.n_hypotheses if s is not None else 0 for s in result.states]),
        kidnapped_at=(),
        doubtful=trial.doubtful,
    )


def present_real_logs(data_dir: Path = DATA_DIR) -> list[RealLog]:
    """The real logs whose files are all present (:func:`real_log_trials` runs them)."""
    return [
        real
        for real in REAL_LOGS
        if all((data_dir / p).is_file() for p in (real.path, real.truth_from) if p is not None)
    ]


def real_log_trials(
    algorithms: Sequence[str], seed: int, data_dir: Path = DATA_DIR
) -> tuple[list[LogStateTrial], list[tuple[str, str]]]:
    """The trials of the real logs that are present, and ``(log, reason)`` for those skipped.
    Each log's truth is checked against its map (:func:`ceamcl.io.truth_check.doubtful_truth`)."""
    from ceamcl.io.truth_check import doubtful_truth
    from ceamcl.replay import choose_pace, obtain_map, prepare_log

    trials, skipped = [], []
    for real in REAL_LOGS:
        paths = [data_dir / real.path] + ([data_dir / real.truth_from] if real.truth_from else [])
        absent = [p for p in paths if not p.is_file()]
        if absent:
            skipped.append(
                (real.label, f"{absent[0]} is absent (the shared data folder is not mounted)")
            )
            continue
        truth_from = paths[1] if real.truth_from else None
        prepared = prepare_log(paths[0], seed=seed, truth_from=truth_from)
        if not prepared.has_truth:
            skipped.append((real.label, f"no ground truth: {prepared.truth_reason}"))
            continue
        grid, _ = obtain_map(prepared.map_log, None)
        pace = choose_pace(prepared)
        doubt = doubtful_truth(prepared.log, grid).mask(len(prepared.log))
        trials += [
            LogStateTrial(real.label, a, grid, prepared.log, seed, pace, doubt) for a in algorithms
        ]
    return trials, skipped


@dataclass(frozen=True)
class StateScore:
    """Precision and recall of one state for one algorithm (NaN when undefined)."""

    algorithm: str
    state: str
    precision: float
    recall: float
    support: int
    said: int


def score(runs: Sequence[StateRun]) -> list[StateScore]:
    """Per algorithm and state (INITIALISING is never scored): precision, recall, support."""
    out = []
    for alg, rs in group_by(runs, lambda r: r.algorithm).items():
        said = np.concatenate([r.said for r in rs])
        truth = np.concatenate([r.truth for r in rs])
        scored = (said != _CODE[State.INITIALISING]) & (truth != NOT_SCORED)
        said, truth = said[scored], truth[scored]
        for s in STATES[:3]:
            c = _CODE[s]
            hit = int(np.sum((said == c) & (truth == c)))
            n_said, n_true = int(np.sum(said == c)), int(np.sum(truth == c))
            out.append(
                StateScore(
                    alg,
                    s.name,
                    hit / n_said if n_said else float("nan"),
                    hit / n_true if n_true else float("nan"),
                    n_true,
                    n_said,
                )
            )
    return out


@dataclass(frozen=True)
class KidnapFigures:
    """The issue's kidnap targets for one algorithm: kidnaps noticed (LOST within
    :data:`LOST_WITHIN_S`), and false LOST among the tracking steps (true LOCALISED)."""

    algorithm: str
    kidnaps: int
    lost_within_2s: float
    tracking_steps: int
    false_lost: float


def kidnap_figures(runs: Sequence[StateRun]) -> list[KidnapFigures]:
    out = []
    for alg, rs in group_by(runs, lambda r: r.algorithm).items():
        noticed, kidnaps, tracking, false_lost = 0, 0, 0, 0
        for r in rs:
            lost = r.said == _CODE[State.LOST]
            loc = r.truth == _CODE[State.LOCALISED]
            tracking += int(loc.sum())
            false_lost += int((lost & loc).sum())
            for k in r.kidnapped_at:
                kidnaps += 1
                window = (r.times >= r.times[k]) & (r.times <= r.times[k] + LOST_WITHIN_S)
                noticed += bool(np.any(lost & window))
        if kidnaps:
            out.append(
                KidnapFigures(
                    alg,
                    kidnaps,
                    noticed / kidnaps,
                    tracking,
                    false_lost / tracking if tracking else float("nan"),
                )
            )
    return out


@dataclass
class StateResult:
    settings: ExperimentSettings
    courses: tuple[str, ...]
    runs: list[StateRun]
    scores: list[StateScore]
    by_course: dict[str, list[StateScore]]
    kidnaps: list[KidnapFigures]
    #: real logs not scored, with the reason
    skipped_logs: list[tuple[str, str]]

    @property
    def records(self) -> list[Any]:
        """No :class:`~ceamcl.experiments.trials.TrialRecord`: the runs are :class:`StateRun`s
        (the visual outputs of ``--gif`` and the like are not drawn for this experiment)."""
        return []


def run_state(
    settings: ExperimentSettings,
    courses: Sequence[Course] | None = None,
    *,
    real_logs: bool = True,
    data_dir: Path = DATA_DIR,
    progress: ProgressCallback | None = None,
    quiet: bool = False,
) -> StateResult:
    """Every algorithm on every route of ``courses`` (default :func:`default_courses`),
    ``settings.trials`` times each, then (``real_logs``) once on each real log of
    ``data_dir``, with a progress bar."""
    courses = tuple(courses) if courses is not None else default_courses()
    trials = [
        t for course in courses for t in make_trials("state", replace(settings, course=course))
    ]
    log_trials: list[LogStateTrial] = []
    skipped: list[tuple[str, str]] = []
    if real_logs:
        log_trials, skipped = real_log_trials(settings.algorithms, settings.seed, data_dir)
    report = None if quiet else progress
    with open_executor(settings.executor, settings.workers, progress=report) as ex:
        runs = map_trials(
            ex, run_state_trial, trials, label="state trials", progress=progress, quiet=quiet
        )
        if log_trials:
            runs += map_trials(
                ex,
                run_log_state_trial,
                log_trials,
                label="state on real logs",
                progress=progress,
                quiet=quiet,
            )
    by_course = {c: score(rs) for c, rs in group_by(runs, lambda r: r.course).items()}
    names = tuple(c.name for c in courses) + tuple(dict.fromkeys(t.name for t in log_trials))
    return StateResult(
        settings,
        names,
        runs,
        score(runs),
        by_course,
        kidnap_figures(runs),
        skipped,
    )


def _pct(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{100 * x:.1f} %"


def score_rows(scores: Sequence[StateScore]) -> list[dict[str, Any]]:
    return [
        {
            "algorithm": s.algorithm,
            "state": s.state,
            "precision": s.precision,
            "recall": s.recall,
            "support": s.support,
            "said": s.said,
        }
        for s in scores
    ]


def score_cells(s: StateScore) -> tuple[str, str, str, str]:
    """Precision, recall, support and said as ``state.md`` and the console print them."""
    return _pct(s.precision), _pct(s.recall), str(s.support), str(s.said)


def _score_table(scores: Sequence[StateScore]) -> str:
    header = ["algorithm", "state", "precision", "recall", "support (true)", "said"]
    rows = [[s.algorithm, s.state, *score_cells(s)] for s in scores]
    return markdown_table(header, rows)


def state_markdown(result: StateResult, meta: dict[str, Any]) -> str:
    t = DEFAULT_THRESHOLDS
    lines = [
        "# The localisation state: precision and recall",
        "",
        f"Scenarios: {', '.join(result.courses)}; {result.settings.trials} trial(s) per route, "
        f"base seed {result.settings.seed}. A step's true state: LOST when no hypothesis is within "
        f"{POSITION_TOL_M} m and {HEADING_TOL_RAD} rad of the truth; AMBIGUOUS when one is and a "
        f"wrong place holds at least {t.weight_min:.0%} of the weight; LOCALISED when no wrong "
        "place holds weight and the estimate is within the tolerances. Steps the filter "
        "calls INITIALISING are not scored. Thresholds: `ceamcl.filters.state.StateThresholds` "
        "(chosen on seed 100 and on freiburg-079-corrected, which is not scored: disjoint from "
        "the seeds reported unless `--seed 100`). Real logs: "
        "one global localisation from the first scan per algorithm; a raw log reads the robot's "
        "own odometry, updates at Nav2's pace and is scored at its updates whose scan has a true "
        "pose (from its corrected log).",
        "",
        "## All scenarios",
        "",
        _score_table(result.scores),
    ]
    runs_of = group_by(result.runs, lambda r: r.course)
    for course, scores in result.by_course.items():
        lines += ["", f"## {course}", "", _score_table(scores)]
        lines += _doubtful_section(runs_of.get(course, []))
    for name, reason in result.skipped_logs:
        lines += ["", f"Real log {name} not scored: {reason}."]
    if result.kidnaps:
        lines += [
            "",
            f"## Kidnaps: LOST raised within {LOST_WITHIN_S:g} s, false LOST while tracking",
            "",
            markdown_table(
                ["algorithm", "kidnaps", "LOST within 2 s", "tracking steps", "false LOST"],
                [
                    [
                        k.algorithm,
                        str(k.kidnaps),
                        _pct(k.lost_within_2s),
                        str(k.tracking_steps),
                        _pct(k.false_lost),
                    ]
                    for k in result.kidnaps
                ],
            ),
        ]
    lines.append(metadata_markdown(meta, result.settings.skipped))
    return "\n".join(lines)


def _doubtful_section(runs: Sequence[StateRun]) -> list[str]:
    """For a real log whose truth is doubtful somewhere (:mod:`ceamcl.io.truth_check`): where,
    how many scored steps lie there, and the scores without them."""
    hit = [r for r in runs if r.doubtful is not None and r.doubtful.any()]
    if not hit:
        return []
    mask = hit[0].doubtful
    assert mask is not None
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    spans = ", ".join(f"{a}-{b - 1}" for a, b in zip(edges[::2], edges[1::2], strict=True))
    counts = sorted(
        {int(np.sum(r.doubtful & (r.truth != NOT_SCORED))) for r in hit if r.doubtful is not None}
    )
    inside = str(counts[0]) if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
    return [
        "",
        f"The truth is doubtful at scans {spans} (fewer than half of a scan's end points near "
        "the map's obstacles at the true pose: `ceamcl.io.truth_check`, docs/real-data.md); "
        f"{inside} scored steps of a run lie there, scored above. Without them:",
        "",
        _score_table(score([r.without_doubtful() for r in runs])),
    ]


def write_state(
    result: StateResult, out: str | os.PathLike[str], meta: dict[str, Any]
) -> list[Path]:
    """``state.csv`` (all scenarios, one row per algorithm and state), ``state_by_scenario.csv``,
    ``state.md`` and ``state.png`` (the state over time beside the true error)."""
    from ceamcl.experiments.figures import plot_state

    out_dir = ensure_output_dir(out)
    meta = {
        **meta,
        "course": ", ".join(result.courses),
        "routes": sorted({f"{r.course} {r.route}" for r in result.runs}),
    }
    by_course = [
        {"scenario": course, **row}
        for course, scores in result.by_course.items()
        for row in score_rows(scores)
    ]
    shown = _example_runs(result.runs)
    return [
        write_csv(out_dir / "state.csv", score_rows(result.scores)),
        write_csv(out_dir / "state_by_scenario.csv", by_course),
        write_text(out_dir / "state.md", state_markdown(result, meta)),
        plot_state(
            [
                (f"{r.algorithm} on {r.course} {r.route}", r.times, r.said, r.position_error)
                for r in shown
            ],
            out_dir / "state.png",
        ),
    ]


def _example_runs(runs: Sequence[StateRun]) -> list[StateRun]:
    """The first run of each algorithm on each scenario (the figure's rows)."""
    seen: dict[tuple[str, str], StateRun] = {}
    for r in runs:
        seen.setdefault((r.course, r.algorithm), r)
    return list(seen.values())
