"""The measures of the experiments, as pure functions of a trial's per-step record.

Definitions (docs/experiments.md gives the reasons):

* A hypothesis (or, for single-estimate algorithms, the estimate) *covers* a pose when it is
  within :data:`POSITION_TOL_M` = 0.5 m and :data:`HEADING_TOL_RAD` = 0.3 rad of it.
* *Converged* at the first step where every symmetric image of the true pose is covered and
  the hypotheses that cover an image hold at least :data:`GATHERED_SHARE` = 90 % of the
  weight (the samples have gathered at the images). Single-estimate algorithms: the first step
  the estimate covers any image.
* *Expired* at the first step after convergence where an image stops being covered for at
  least :data:`HOLD_S` = 1 s (or until the end of the run); never otherwise. Single-estimate:
  the estimate covers no image for that long.
* *Success*: the true pose is covered at the last step (the goal).
* *Kept all*: every image is covered at the last step (hypothesis algorithms only).

The precision side (:func:`weight_shares`, :func:`nearest_error`, :func:`confidently_wrong`),
at every step and reported at the goal:

* The *true image set*: the hypotheses that cover the truth or one of its symmetric images;
  every other hypothesis is *spurious*. Their weight shares are over the hypotheses' total
  weight (0 and 0 when there is none); the *weight at the truth* is the part of the true
  image set's that covers the truth itself.
* *Confidently wrong*: the estimate does not cover the truth while one hypothesis holds at
  least :data:`CONFIDENT_SHARE` = 90 % of the weight.
* The *nearest hypothesis*: the one nearest the truth in position; its position and heading
  errors.
* *Likelihood evaluations*: the poses scored against a scan over the whole run, the global
  initialisation (step 0) included (:func:`likelihood_evaluations`).

Real logs (``ceamcl run``, ``ceamcl evaluate-log``), as :func:`score_errors` computes it. A
step is *inside* when the estimate is within ``pos_tol_m`` (0.5 m) and ``head_tol_rad``
(0.3 rad) of the truth. The run *converges* at the first step ``c`` from which every later step
of the window is inside; it *succeeds* when that inside stretch lasts at least ``hold`` steps
(default :data:`HOLD_STEPS` = 10) and so is not a lucky last step. Time and scans to converge
are ``t[c] - t[0]`` and ``c``; the RMSEs are over steps ``c..end``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.base import StepDiagnostics
from ceamcl.motion.odometry import apply_increment, increment_between
from ceamcl.pose import heading_error, position_error

POSITION_TOL_M = 0.5
HEADING_TOL_RAD = 0.3
GATHERED_SHARE = 0.9
#: A filter is *confident* when one hypothesis holds at least this share of the weight.
CONFIDENT_SHARE = 0.9
HOLD_S = 1.0
#: Steps a real-log run must stay inside the tolerances at the end to count as a success
#: (``--hold N``), ...
HOLD_STEPS = 10
#: ... or metres of travel (``--hold-m``, evaluate-log's default: scans are 0.1-1 m apart).
DEFAULT_HOLD_M = 5.0


def within(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    position_tol: float = POSITION_TOL_M,
    heading_tol: float = HEADING_TOL_RAD,
) -> NDArray[np.bool_]:
    """Element-wise (poses ``(..., 3)`` broadcast): is ``a`` within the tolerances of ``b``?"""
    return (position_error(a, b) <= position_tol) & (heading_error(a, b) <= heading_tol)


def covers(
    poses: NDArray[np.float64],
    targets: NDArray[np.float64],
    position_tol: float = POSITION_TOL_M,
    heading_tol: float = HEADING_TOL_RAD,
) -> NDArray[np.bool_]:
    """``(P, T)``: does pose ``p`` lie within the tolerances of target ``t``?"""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    return within(p[:, None, :], t[None, :, :], position_tol, heading_tol)


def step_coverage(
    hypotheses: NDArray[np.float64], images: NDArray[np.float64]
) -> tuple[NDArray[np.bool_], float]:
    """For one step: which images ``(K,)`` some hypothesis covers, and the weight share of the
    hypotheses that cover some image. ``hypotheses`` is ``(H, >=4)``: x, y, theta, weight."""
    if hypotheses.shape[0] == 0:
        return np.zeros(images.shape[0], dtype=bool), 0.0
    c = covers(hypotheses[:, :3], images)
    w = hypotheses[:, 3]
    total = float(w.sum())
    gathered = float(w[c.any(axis=1)].sum() / total) if total > 0 else 0.0
    any_cover: NDArray[np.bool_] = np.asarray(c.any(axis=0), dtype=bool)
    return any_cover, gathered


@dataclass(frozen=True)
class WeightShares:
    """Weight shares of one step's hypotheses (:func:`weight_shares`)."""

    true_images: float  # held by hypotheses that cover the truth or one of its images
    spurious: float  # held by the others
    heaviest: float  # held by the heaviest single hypothesis
    truth: float  # held by hypotheses that cover the truth itself (part of true_images)


def weight_shares(
    hypotheses: NDArray[np.float64],
    images: NDArray[np.float64],
    position_tol: float = POSITION_TOL_M,
    heading_tol: float = HEADING_TOL_RAD,
) -> WeightShares:
    """Shares of the hypotheses' total weight held by the true image set (the hypotheses
    within the tolerances of one of ``images``, the truth first), by the spurious rest, and by
    the heaviest hypothesis, and the share of those at the truth itself (``images[0]``).
    ``hypotheses`` is ``(H, >=4)``: x, y, theta, weight. No hypothesis or no weight: every
    share is 0 (there is nothing to hold)."""
    h = np.asarray(hypotheses, dtype=np.float64)
    if h.shape[0] == 0:
        return WeightShares(0.0, 0.0, 0.0, 0.0)
    w = h[:, 3]
    total = float(w.sum())
    if not total > 0:
        return WeightShares(0.0, 0.0, 0.0, 0.0)
    c = covers(h[:, :3], images, position_tol, heading_tol)
    at_image = c.any(axis=1)
    return WeightShares(
        true_images=float(w[at_image].sum() / total),
        spurious=float(w[~at_image].sum() / total),
        heaviest=float(w.max() / total),
        truth=float(w[c[:, 0]].sum() / total),
    )


def image_index(
    hypotheses: NDArray[np.float64],
    images: NDArray[np.float64],
    position_tol: float = POSITION_TOL_M,
    heading_tol: float = HEADING_TOL_RAD,
) -> NDArray[np.int64]:
    """Per hypothesis ``(H,)``: the index of the image (``images[0]`` is the truth) it lies
    within the tolerances of, the nearest in position if several; -1 for a spurious one."""
    h = np.asarray(hypotheses, dtype=np.float64)
    if h.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    imgs = np.asarray(images, dtype=np.float64).reshape(-1, 3)
    c = covers(h[:, :3], imgs, position_tol, heading_tol)
    d = np.where(c, position_error(h[:, None, :3], imgs[None, :, :]), np.inf)
    return np.where(c.any(axis=1), np.argmin(d, axis=1), -1).astype(np.int64)


def nearest_error(
    hypotheses: NDArray[np.float64], truth: NDArray[np.float64]
) -> tuple[float, float]:
    """Position (m) and heading (rad) error of the hypothesis nearest ``truth`` in position
    (the first of equals); NaN, NaN without hypotheses."""
    h = np.asarray(hypotheses, dtype=np.float64).reshape(-1, hypotheses.shape[-1])
    if h.shape[0] == 0:
        return math.nan, math.nan
    d = position_error(h[:, :3], truth)
    i = int(np.argmin(d))
    return float(d[i]), float(heading_error(h[i, :3], truth))


def confidently_wrong(
    estimate_ok: NDArray[np.bool_] | bool,
    heaviest: NDArray[np.float64] | float,
    share: float = CONFIDENT_SHARE,
) -> NDArray[np.bool_]:
    """Element-wise: the estimate is wrong (does not cover the truth) while one hypothesis
    holds at least ``share`` of the weight."""
    return np.asarray(~np.asarray(estimate_ok, dtype=bool) & (np.asarray(heaviest) >= share))


def likelihood_evaluations(diagnostics: Sequence[StepDiagnostics]) -> NDArray[np.int64] | None:
    """Per step ``(T,)``: the poses scored against a scan, step 0 being the global
    initialisation (its test poses count there); their sum is the run's. ``None`` when a
    step's record says its filter does not count them (``likelihood_evaluations_counted``
    False: the Nav2 peer, whose wheel hides them)."""
    if any(not getattr(d.record, "likelihood_evaluations_counted", True) for d in diagnostics):
        return None
    return np.array([d.likelihood_evaluations for d in diagnostics], dtype=np.int64)


def converged_step(
    covered: NDArray[np.bool_],
    gathered: NDArray[np.float64],
    *,
    single_estimate: bool = False,
    share: float = GATHERED_SHARE,
) -> int | None:
    """First step at which the filter has converged (module docstring), or ``None``."""
    ok = covered.any(axis=1) if single_estimate else covered.all(axis=1) & (gathered >= share)
    idx = np.flatnonzero(ok)
    return int(idx[0]) if idx.size else None


def expired_step(
    covered: NDArray[np.bool_],
    converged: int | None,
    hold_steps: int,
    *,
    single_estimate: bool = False,
) -> int | None:
    """First step after ``converged`` that starts a gap of at least ``hold_steps`` steps (or
    one running to the end) in the coverage of some image; ``None`` when there is none."""
    if converged is None:
        return None
    hold = max(1, hold_steps)
    lost: NDArray[np.bool_] = np.asarray(
        ~covered.any(axis=1, keepdims=True) if single_estimate else ~covered, dtype=bool
    )
    n = lost.shape[0]
    best: int | None = None
    for j in range(lost.shape[1]):
        run = 0
        for k in range(converged + 1, n):
            run = run + 1 if lost[k, j] else 0
            if run >= hold or (run > 0 and k == n - 1):
                start = k - run + 1
                best = start if best is None else min(best, start)
                break
    return best


def recovery_step(localised: NDArray[np.bool_], kidnapped: int, window_steps: int) -> int | None:
    """Kidnapped robot: the first step ``r`` in ``[kidnapped, kidnapped + window_steps]`` from
    which the estimate covers the truth at every later step; ``None`` when there is none."""
    n = localised.shape[0]
    if not 0 <= kidnapped < n:
        return None
    # stays[k]: localised at k and at every later step.
    stays = np.flip(np.logical_and.accumulate(np.flip(localised)))
    last = min(n - 1, kidnapped + window_steps)
    idx = np.flatnonzero(stays[kidnapped : last + 1])
    return kidnapped + int(idx[0]) if idx.size else None


@dataclass(frozen=True)
class TrialMetrics:
    """The measures of one trial (times in seconds since the start of the run)."""

    converged_s: float | None
    expired_s: float | None
    success: bool
    kept_all: bool | None
    final_position_error_m: float
    final_heading_error_rad: float
    final_estimate_ok: bool
    mean_particles: float
    final_particles: int
    mean_step_ms: float
    median_step_ms: float
    # the precision side, at the goal (module docstring)
    true_image_weight: float
    spurious_weight: float
    truth_weight: float
    heaviest_weight: float
    confidently_wrong: bool
    confidently_wrong_share: float  # of the run's steps
    nearest_position_error_m: float
    nearest_heading_error_rad: float
    likelihood_evaluations: int | None  # whole run, initialisation included; None: not counted
    initialisation_likelihood_evaluations: int | None


@dataclass(frozen=True)
class StepPrecision:
    """The precision side of a run, one entry per step (``T`` steps)."""

    true_image_weight: NDArray[np.float64]  # (T,)
    spurious_weight: NDArray[np.float64]  # (T,)
    truth_weight: NDArray[np.float64]  # (T,)
    heaviest_weight: NDArray[np.float64]  # (T,)
    nearest_position_error: NDArray[np.float64]  # (T,) m
    nearest_heading_error: NDArray[np.float64]  # (T,) rad
    likelihood_evaluations: NDArray[np.int64] | None  # (T,); None: the filter does not count


def trial_metrics(
    times: NDArray[np.float64],
    truth: NDArray[np.float64],
    estimates: NDArray[np.float64],
    covered: NDArray[np.bool_],
    gathered: NDArray[np.float64],
    n_particles: NDArray[np.int64],
    step_ms: NDArray[np.float64],
    precision: StepPrecision,
    *,
    single_estimate: bool,
    hold_s: float = HOLD_S,
) -> TrialMetrics:
    """Every measure of one trial from its per-step record."""
    dt = float(np.median(np.diff(times))) if times.size > 1 else 1.0
    hold_steps = max(1, round(hold_s / dt)) if dt > 0 else 1
    conv = converged_step(covered, gathered, single_estimate=single_estimate)
    exp = expired_step(covered, conv, hold_steps, single_estimate=single_estimate)
    steps = step_ms[1:] if step_ms.size > 1 else step_ms
    ok = within(estimates, truth)
    wrong = confidently_wrong(ok, precision.heaviest_weight)
    evals = precision.likelihood_evaluations
    return TrialMetrics(
        converged_s=None if conv is None else float(times[conv] - times[0]),
        expired_s=None if exp is None else float(times[exp] - times[0]),
        success=bool(covered[-1, 0]),
        kept_all=None if single_estimate else bool(covered[-1].all()),
        final_position_error_m=float(position_error(estimates[-1], truth[-1])),
        final_heading_error_rad=float(heading_error(estimates[-1], truth[-1])),
        final_estimate_ok=bool(ok[-1]),
        mean_particles=float(np.mean(n_particles)),
        final_particles=int(n_particles[-1]),
        mean_step_ms=float(np.mean(steps)),
        median_step_ms=float(np.median(steps)),
        true_image_weight=float(precision.true_image_weight[-1]),
        spurious_weight=float(precision.spurious_weight[-1]),
        truth_weight=float(precision.truth_weight[-1]),
        heaviest_weight=float(precision.heaviest_weight[-1]),
        confidently_wrong=bool(wrong[-1]),
        confidently_wrong_share=float(np.mean(wrong)),
        nearest_position_error_m=float(precision.nearest_position_error[-1]),
        nearest_heading_error_rad=float(precision.nearest_heading_error[-1]),
        likelihood_evaluations=None if evals is None else int(evals.sum()),
        initialisation_likelihood_evaluations=None if evals is None else int(evals[0]),
    )


@dataclass(frozen=True)
class PrecisionSummary:
    """The precision side over runs (means over runs; ``None`` where no run has the number).

    likelihood_evaluations: mean per run, the initialisation included (``None``: the filter
    does not count them); initialisation_likelihood_evaluations: the initialisation's share.
    """

    true_image_weight: float
    spurious_weight: float
    truth_weight: float
    confidently_wrong_rate: float
    nearest_position_error_mean_m: float
    nearest_position_error_median_m: float
    nearest_heading_error_mean_rad: float
    likelihood_evaluations: float | None
    initialisation_likelihood_evaluations: float | None


def _mean_or_none(values: Sequence[int | None]) -> float | None:
    if not values or any(v is None for v in values):
        return None
    return float(np.mean(np.asarray(values, dtype=np.float64)))


def precision_summary(metrics: Sequence[TrialMetrics]) -> PrecisionSummary:
    """:class:`PrecisionSummary` of the runs ``metrics`` (at least one)."""
    if not metrics:
        raise ValueError("precision_summary: no runs")
    near = np.array([m.nearest_position_error_m for m in metrics])
    return PrecisionSummary(
        true_image_weight=float(np.mean([m.true_image_weight for m in metrics])),
        spurious_weight=float(np.mean([m.spurious_weight for m in metrics])),
        truth_weight=float(np.mean([m.truth_weight for m in metrics])),
        confidently_wrong_rate=float(np.mean([m.confidently_wrong for m in metrics])),
        nearest_position_error_mean_m=float(np.mean(near)),
        nearest_position_error_median_m=float(np.median(near)),
        nearest_heading_error_mean_rad=float(
            np.mean([m.nearest_heading_error_rad for m in metrics])
        ),
        likelihood_evaluations=_mean_or_none([m.likelihood_evaluations for m in metrics]),
        initialisation_likelihood_evaluations=_mean_or_none(
            [m.initialisation_likelihood_evaluations for m in metrics]
        ),
    )


def final_error(err: NDArray[np.float64]) -> float:
    """The error at the last step with a true pose (NaN elsewhere); NaN when there is none."""
    known = err[np.isfinite(err)]
    return float(known[-1]) if known.size else math.nan


@dataclass(frozen=True)
class Score:
    """Convergence of one run (module docstring). NaN/None where it did not converge.

    position_rmse_m, heading_rmse_rad: over the final inside stretch (from the convergence).
    first_inside: the first step inside the tolerances (``None``: never);
    position_rmse_from_first_m: the position RMSE from that step to the end, excursions
    included (a filter that converges, loses track and returns pays for the excursion here).
    distance_to_converge_m: metres travelled from the start to the convergence (NaN without a
    ``travelled`` series or without convergence).
    """

    success: bool
    scans_to_converge: int | None
    time_to_converge_s: float
    position_rmse_m: float
    heading_rmse_rad: float
    first_inside: int | None = None
    position_rmse_from_first_m: float = math.nan
    distance_to_converge_m: float = math.nan


def score_errors(
    times: NDArray[np.float64],
    pos_err: NDArray[np.float64],
    head_err: NDArray[np.float64],
    *,
    pos_tol_m: float = POSITION_TOL_M,
    head_tol_rad: float = HEADING_TOL_RAD,
    hold: int = HOLD_STEPS,
    hold_m: float | None = None,
    travelled: NDArray[np.float64] | None = None,
) -> Score:
    """Convergence step, success and RMSE after convergence of an error series.

    Steps whose errors are NaN have no truth (a raw log scored at the scans it shares with its
    corrected log): scoring uses the steps with truth only, ``hold`` counts those, and the
    scans to converge count every step from the start.

    With ``hold_m`` (and ``travelled``, the metres travelled up to each step) the final inside
    stretch must cover ``hold_m`` metres of travel instead of ``hold`` steps (all of the window
    when it is shorter): 10 scans are 34 s on one log and 2.4 s on another."""
    known = np.flatnonzero(np.isfinite(pos_err) & np.isfinite(head_err))
    pos, head = pos_err[known], head_err[known]
    inside = (pos <= pos_tol_m) & (head <= head_tol_rad)
    n = inside.size
    outside = np.flatnonzero(~inside)
    c = 0 if outside.size == 0 else int(outside[-1]) + 1
    firsts = np.flatnonzero(inside)
    first = int(known[firsts[0]]) if firsts.size else None
    rmse_first = float(np.sqrt(np.mean(pos[firsts[0] :] ** 2))) if firsts.size else math.nan
    if hold_m is not None and travelled is None:
        raise ValueError("score_errors: hold_m needs the travelled distance of every step")
    if c >= n:
        held = False
    elif hold_m is not None and travelled is not None:
        trav = travelled[known]
        held = trav[-1] - trav[c] >= min(hold_m, trav[-1] - trav[0]) - 1e-9
    else:
        held = n - c >= min(hold, n)
    if not held:
        return Score(False, None, math.nan, math.nan, math.nan, first, rmse_first)
    step = int(known[c])
    return Score(
        True,
        step,
        float(times[step] - times[0]),
        float(np.sqrt(np.mean(pos[c:] ** 2))),
        float(np.sqrt(np.mean(head[c:] ** 2))),
        first,
        rmse_first,
        math.nan if travelled is None else float(travelled[step] - travelled[0]),
    )


#: An estimate *jumps* at a scan when it lands more than this far from where the previous
#: estimate moved by the odometry increment puts it.
JUMP_M = 1.0


@dataclass(frozen=True)
class Jumps:
    """Estimate jumps (:func:`estimate_jumps`) after scan ``from_scan``: the largest, at
    which scan (``None``: no scan measured), and how many exceed :data:`JUMP_M`."""

    from_scan: int
    largest_m: float
    largest_at_scan: int | None
    over_threshold: int


def estimate_jumps(
    estimates: NDArray[np.float64], odometry: NDArray[np.float64], from_scan: int = 0
) -> Jumps:
    """For scans ``k > from_scan``: how far the estimate ``e[k]`` lands from the previous
    estimate moved by the odometry increment, ``e[k-1] (+) (o[k-1] -> o[k])`` (eq. 5.34-5.36
    applied in the estimate's frame): the motion the odometry does not explain. A filter that
    tracks the robot moves its estimate by about the odometry increment; one that hops between
    hypotheses or restarts jumps by metres."""
    e = np.asarray(estimates, dtype=np.float64).reshape(-1, 3)
    o = np.asarray(odometry, dtype=np.float64).reshape(-1, 3)
    start = max(1, from_scan + 1)
    if e.shape[0] <= start:
        return Jumps(from_scan, 0.0, None, 0)
    incs = [increment_between(o[k - 1], o[k]) for k in range(start, e.shape[0])]
    predicted = apply_increment(
        e[start - 1 : -1],
        [i.rot1 for i in incs],
        [i.trans for i in incs],
        [i.rot2 for i in incs],
    )
    dist = np.hypot(*(e[start:, :2] - predicted[:, :2]).T)
    j = int(np.argmax(dist))
    return Jumps(from_scan, float(dist[j]), start + j, int(np.sum(dist > JUMP_M)))


@dataclass(frozen=True)
class Verdict:
    """What happened in a run with ground truth, in the terms of :func:`score_errors`.

    ``status``: ``"converged"`` (inside the tolerances from ``converged_scan`` to the end, at
    least ``hold`` scans), ``"not held"`` (inside at the end, but for fewer than ``hold``
    scans), ``"lost"`` (inside at some scan, outside at the end) or ``"never"``.
    ``final_stretch``: scans inside at the end; ``scans_inside``: scans inside anywhere;
    ``longest_stretch``: (first scan, length) of the longest run of scans inside.
    """

    status: str
    text: str
    first_localised_scan: int | None
    first_localised_s: float | None
    converged_scan: int | None
    converged_s: float | None
    final_stretch: int
    scans_inside: int
    scans: int
    longest_stretch: tuple[int, int] | None
    hold: int


def _stretches(inside: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(first index, length) of each run of True."""
    edges = np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b - a)) for a, b in zip(starts, ends, strict=True)]


def convergence_verdict(
    times: NDArray[np.float64],
    inside: NDArray[np.bool_],
    final_error_m: float,
    hold: int = HOLD_STEPS,
    scan_ids: NDArray[np.intp] | None = None,
) -> Verdict:
    """The verdict (:class:`Verdict`) on which steps were inside the tolerances (``inside``,
    as :func:`score_errors` finds them), in one sentence (``text``) that agrees with
    :func:`score_errors`: ``converged`` exactly when its ``success``.

    ``scan_ids``: where only some scans have a truth (a raw log scored at the scans it shares
    with its corrected log), ``inside[i]`` is about scan ``scan_ids[i]``; the verdict counts
    the scans with truth and names scans by their number in the log, times from its start
    (``times`` has one entry per scan of the log)."""
    ids = np.arange(inside.size) if scan_ids is None else np.asarray(scan_ids, dtype=np.intp)
    t_all = np.asarray(times, dtype=np.float64)
    t = t_all[ids] - t_all[0] if t_all.size else np.zeros(0)  # seconds from the log's start
    scans = "scans" if scan_ids is None else "scans with truth"
    n = int(inside.size)
    runs = _stretches(inside)
    if not runs:
        return Verdict(
            "never",
            "never localised: no scan within the tolerances of the truth",
            None,
            None,
            None,
            None,
            0,
            0,
            n,
            None,
            hold,
        )
    first = runs[0][0]
    first_s = float(t[first])
    longest = max(runs, key=lambda r: r[1])
    final = runs[-1][1] if runs[-1][0] + runs[-1][1] == n else 0
    share = f"inside {int(inside.sum())} of {n} {scans}"
    need = min(hold, n)
    if final >= need:
        c = n - final
        text = (
            f"converged at scan {ids[c]} (t = {t[c]:.1f} s) and held to the end "
            f"({final} {scans} within the tolerances)"
        )
        if c > first:  # localised earlier, then lost again: say so
            text += f"; first localised at scan {ids[first]} (t = {first_s:.1f} s), {share}"
        return Verdict(
            "converged",
            text,
            int(ids[first]),
            first_s,
            int(ids[c]),
            float(t[c]),
            final,
            int(inside.sum()),
            n,
            (int(ids[longest[0]]), longest[1]),
            hold,
        )
    where = f"first localised at scan {ids[first]} (t = {first_s:.1f} s), {share}"
    if final > 0:
        status = "not held"
        text = (
            f"not converged: localised at the end but only for the last {final} {scans} "
            f"(fewer than {need}); {where}, longest stretch {longest[1]} {scans} from scan "
            f"{ids[longest[0]]}"
        )
    else:
        status = "lost"
        text = (
            f"not converged: lost at the end (final error {final_error_m:.2f} m); "
            f"{where}, longest stretch {longest[1]} {scans} from scan {ids[longest[0]]}"
        )
    return Verdict(
        status,
        text,
        int(ids[first]),
        first_s,
        None,
        None,
        final,
        int(inside.sum()),
        n,
        (int(ids[longest[0]]), longest[1]),
        hold,
    )


def restarts(diagnostics: Sequence[StepDiagnostics]) -> dict[str, Any]:
    """The filter's restarts of global localisation after its first (a step whose record says
    ``reinitialised``): how many, at which steps, and how many of them were kidnap recoveries
    (CEAMCL's fitness collapse: the ``recoveries`` of its records). A restart throws the
    estimate anywhere."""
    steps = [d.step for d in diagnostics[1:] if d.reinitialised]
    recoveries = sum(int(d.record.columns().get("recoveries", 0)) for d in diagnostics)
    return {"restarts": len(steps), "restart_scans": steps, "kidnap_recoveries": recoveries}
