"""Ground truth from a second log: pair the scans of a raw log with those of its SLAM-corrected
counterpart (``ceamcl run|evaluate-log RAW --truth-from CORRECTED``).

A raw log holds every scan with the robot's own (drifting) odometry; the corrected log of the
same run keeps a subset of those scans with SLAM-corrected poses. A corrected scan and its raw
twin have the *same ranges* (the files print them differently, so they are compared as numbers,
rounded to ``decimals`` digits, or to the fewer digits one of the two logs prints: a raw log of
millimetres pairs with a corrected log written in centimetres, :func:`printed_decimals`), and
their timestamps agree up to a clock offset (the raw log's IPC timestamps are the wall clock,
the corrected log's are the logger's, which starts at 0).

Pairing, in order:

1. every scan gets a key, its beam count and rounded ranges;
2. corrected scans whose key names exactly one raw scan measure the clock offset. The raw
   logs' IPC timestamps jitter around the logger's clock (fr079: 1 % of scans by more than
   0.1 s, one by 0.44 s), so the offset at any corrected time is interpolated between these
   anchors, each the running median of 5 anchors (robust to a late scan and to the odd
   unlucky unique match);
3. walking through the corrected scans in order, each is paired with the raw scan of the same
   key that comes after the last pair and lies closest in offset-corrected time, if within
   ``time_tol_s``. A robot standing still repeats a scan; the time decides which repeat it is.

**Timestamps that cannot check.** Some corrected logs print their timestamps too coarsely to
check anything (GMapping's ``.gfs.log`` of the Belgioioso castle writes ``1.01893e+09``: ten
thousand seconds a step) or on another clock. When most of the corrected log's timestamps
repeat the one before, or more than half of the corrected scans whose ranges name exactly one
raw scan lie beyond ``time_tol_s`` of the clock offset (with usable timestamps: none of 910 on
intel, none of 4,791 on fr079), the timestamps are not used: each
corrected scan is paired with the first raw scan of the same key after the last pair, ranges
and order alone (a repeat is a robot standing still, so the first repeat is where it stood).
The summary says so (``TruthPairing.times_used``).

The result says how many scans matched; the filter then reads the raw log's odometry and every
scan, and is scored at the matched scans, where the corrected pose is the truth.

**Whose pose.** A filter estimates the pose of the raw log's robot, whose laser sits at the raw
log's mount (fr079: 4 cm behind the centre, ``laser pose - robot pose`` in its ``FLASER``
lines). The corrected log places its scans at its own poses and mount (0 in the shared logs:
its laser pose is its robot pose), and the map built from it puts the walls where those scans
see them. So the truth of the raw robot is the corrected log's *laser* pose moved back by the
raw log's mount: ``truth = (corrected pose + corrected mount) - raw mount``. Scored against the
corrected pose itself, every filter on fr079 raw carried a 4 cm bias along its heading (the
mount), whatever it did. Where the two mounts agree the corrected pose is kept as it is.

**Which mount the data suggest.** A log may give no mount (intel raw says 0) or a wrong one.
Between consecutive pairs the robot's axis moves as the raw odometry says, and the corrected
laser poses move as a point at the mount ``m`` on that robot: a turn in place carries a laser
ahead of the axis sideways. In the robot frame of the first pose of a pair,
``(Rot(dtheta) - I) m = Rot(-theta) dL - du`` (``dL`` the laser's displacement, ``du`` the
odometry's, ``dtheta`` the turn), which is linear in ``m``; :func:`suggest_mount` solves it by
least squares over every pair, once more without the worst tenth of the pairs (the odometry's
glitches). ``TruthPairing.suggested_mount`` carries the answer and the summary prints it beside
the log's: ``--laser-mount`` sets the one the filter uses (intel raw: about 9 cm ahead of the
axis; fr079 raw: about 1 cm behind, where its log says 4 cm).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ceamcl.angles import wrap
from ceamcl.errors import LogFormatError
from ceamcl.io.recorded import RecordedLog
from ceamcl.pose import relative_poses
from ceamcl.sensors.scan import laser_poses

#: Ranges are compared after rounding to millimetres (the logs print centimetres or finer).
DEFAULT_DECIMALS = 3
#: A pair's timestamps may differ from the estimated clock offset by at most this much.
DEFAULT_TIME_TOL_S = 0.5
#: A corrected log whose robot pose lies farther than this from its laser pose keeps something
#: else there (GMapping's logs of some buildings: the raw odometry); the truth is the laser pose.
LASER_MOUNT_MAX_M = 1.0


@dataclass(frozen=True, eq=False)
class TruthPairing:
    """Which raw scans have a corrected twin.

    raw_index, truth_index: the pairs, increasing in both (``truth_index[k]`` is the corrected
        scan whose pose is the truth at raw scan ``raw_index[k]``).
    truth_poses: the raw log's robot pose at each pair (module docstring, "whose pose").
    clock_offset_s: raw time minus corrected time, as estimated (median over the run).
    max_time_residual_s: the largest ``|raw_t - offset - truth_t|`` among the pairs.
    times_used: the timestamps checked the pairs, within ``time_tol_s``; ``False`` when they
        could not (module docstring, "Timestamps that cannot check"): paired by ranges and
        order alone.
    mount_moved: pairs whose two laser mounts differ, where the truth was moved by them.
    mount_shift_m: the largest distance the truth was moved (0 when none).
    suggested_mount: the laser's position ``(x, y)`` on the robot that the corrected poses and
        the raw odometry agree on (:func:`suggest_mount`; ``None``: the robot never turned
        enough to tell). raw_mount: the raw log's (at its first pair).
    """

    raw_path: str
    truth_path: str
    n_raw: int
    n_truth: int
    raw_index: NDArray[np.intp]
    truth_index: NDArray[np.intp]
    truth_poses: NDArray[np.float64]
    clock_offset_s: float
    max_time_residual_s: float
    times_used: bool = True
    time_tol_s: float = DEFAULT_TIME_TOL_S
    mount_moved: int = 0
    mount_shift_m: float = 0.0
    suggested_mount: tuple[float, float] | None = None
    raw_mount: tuple[float, float] = (0.0, 0.0)

    @property
    def n_matched(self) -> int:
        return int(self.raw_index.size)

    def truth_at_raw_scans(self) -> NDArray[np.float64]:
        """``(n_raw, 3)`` true poses, NaN at raw scans without a corrected twin."""
        out = np.full((self.n_raw, 3), np.nan)
        out[self.raw_index] = self.truth_poses
        return out

    def summary(self) -> str:
        moved = (
            f"; the truth moved to the raw log's robot at {self.mount_moved} pairs, whose "
            f"laser mounts differ (by up to {self.mount_shift_m:.3f} m)"
            if self.mount_moved
            else ""
        )
        if self.mount_moved and self.mount_shift_m > LASER_MOUNT_MAX_M:
            # a corrected log whose FLASER lines keep the raw odometry as the robot pose
            moved = (
                f"; the truth is the corrected log's laser pose, moved to the raw log's robot "
                f"(its robot pose lies up to {self.mount_shift_m:.3f} m from its laser pose at "
                f"{self.mount_moved} pairs: odometry, not a laser mount)"
            )
        suggested = self.mount_suggestion()
        if suggested:
            rx, ry = self.raw_mount
            suggested += f", where the raw log says ({rx:.3f}, {ry:.3f})"
        clock = (
            f"clock offset {self.clock_offset_s:.3f} s, largest residual "
            f"{self.max_time_residual_s:.3f} s"
            if self.times_used
            else "paired by ranges and order alone: the corrected log's timestamps cannot check "
            "the pairs (most repeat the one before, or most scans with a unique twin lie more "
            f"than {self.time_tol_s:g} s from the clock offset: too coarse or of another clock)"
        )
        return (
            f"{self.n_matched} of {self.n_truth} scans of {self.truth_path} matched among "
            f"{self.n_raw} scans of {self.raw_path} ({clock}{moved}{suggested})"
        )

    def mount_suggestion(self) -> str:
        """``"; ..."``: the mount the corrected poses and the raw odometry agree on, in the
        words the pairing's summary and the reports' ground-truth line use ("" without one)."""
        if self.suggested_mount is None:
            return ""
        x, y = self.suggested_mount
        return (
            f"; the corrected poses and the odometry suggest a laser at ({x:.3f}, {y:.3f}) m "
            "on the robot (--laser-mount sets it)"
        )


def printed_decimals(log: RecordedLog, limit: int = DEFAULT_DECIMALS, sample: int = 20_000) -> int:
    """The fewest decimal digits (at most ``limit``) that every finite range of the log's first
    ``sample`` readings has: 2 for a log that prints centimetres (``1.23``, ``7.3``), ``limit``
    for one of float32 readings (a bag's)."""
    r = np.asarray(log.ranges_flat[:sample], dtype=np.float64)
    r = np.abs(r[np.isfinite(r)])
    for k in range(limit):
        scaled = r * 10.0**k
        # a float parsed from k printed digits is k digits within rounding (float32 included)
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-6 * np.maximum(scaled, 1.0)):
            return k
    return limit


def scan_keys(log: RecordedLog, decimals: int = DEFAULT_DECIMALS) -> list[bytes]:
    """One hashable key per scan: its beam count and its ranges rounded to ``decimals``.

    Ranges are rounded as ``printf("%.{decimals}f")`` rounds them, from their exact binary
    value: a tie in the scaled product (``1.245 * 100`` is 124.5 in floating point, 124 by
    NumPy's rounding, while the double 1.245 lies above the tie and prints as ``1.25``) is
    rounded again by Python's correctly rounded ``round``. Ranges that are not finite (NaN,
    inf) keep a key of their own per kind."""
    scale = 10.0**decimals
    r = np.asarray(log.ranges_flat, dtype=np.float64)
    scaled = r * scale
    rounded = np.round(scaled)
    tie = np.isfinite(scaled) & (np.abs(np.abs(scaled - np.floor(scaled)) - 0.5) < 1e-6)
    for i in np.flatnonzero(tie):
        rounded[i] = round(round(float(r[i]), decimals) * scale)
    rounded = np.where(np.isfinite(r), rounded, np.where(np.isnan(r), -1.0, -2.0))
    ints = rounded.astype(np.int64)
    counts = np.diff(log.offsets)
    return [
        int(n).to_bytes(4, "little") + ints[a:b].tobytes()
        for n, a, b in zip(counts, log.offsets[:-1], log.offsets[1:], strict=True)
    ]


def _running_median(x: NDArray[np.float64], width: int) -> NDArray[np.float64]:
    """Median of each value and its neighbours, ``width`` values in all (fewer at the ends)."""
    half = width // 2
    return np.array([np.median(x[max(i - half, 0) : i + half + 1]) for i in range(x.size)])


def pair_truth(
    raw: RecordedLog,
    truth: RecordedLog,
    *,
    decimals: int = DEFAULT_DECIMALS,
    time_tol_s: float = DEFAULT_TIME_TOL_S,
) -> TruthPairing:
    """Pair the scans of ``raw`` with those of ``truth`` (module docstring), their ranges
    compared at ``decimals`` digits or at the fewer digits either log prints.

    Raises:
        LogFormatError: no scan of ``truth`` has a twin in ``raw`` (not logs of the same run).
    """
    decimals = min(printed_decimals(raw, decimals), printed_decimals(truth, decimals))
    raw_keys = scan_keys(raw, decimals)
    truth_keys = scan_keys(truth, decimals)
    where: dict[bytes, list[int]] = defaultdict(list)
    for i, key in enumerate(raw_keys):
        where[key].append(i)
    raw_t = np.asarray(raw.times, dtype=np.float64)
    truth_t = np.asarray(truth.times, dtype=np.float64)

    unique = [(where[k][0], j) for j, k in enumerate(truth_keys) if len(where.get(k, ())) == 1]
    if not unique and not any(k in where for k in truth_keys):
        raise LogFormatError(
            f"{truth.path}: none of its {len(truth)} scans has the ranges of a scan of "
            f"{raw.path} ({len(raw)} scans): are they logs of the same run and laser?"
        )
    if unique:
        ri, tj = np.array(unique).T
        anchor_t, diffs = truth_t[tj], raw_t[ri] - truth_t[tj]
    else:  # every matching scan repeats: take the first candidates' differences
        tj = np.array([j for j, k in enumerate(truth_keys) if k in where])
        anchor_t = truth_t[tj]
        diffs = np.array([raw_t[where[truth_keys[j]][0]] for j in tj]) - anchor_t
    smooth = _running_median(diffs, 5)
    order = np.argsort(anchor_t, kind="stable")
    offsets = np.interp(truth_t, anchor_t[order], smooth[order])
    offset = float(np.median(diffs))
    # the timestamps check the pairs only where they agree for most unique twins (docstring)
    times_used = True
    if truth_t.size > 1:  # a clock that cannot tell most consecutive scans apart
        times_used = bool(np.count_nonzero(np.diff(truth_t) > 0) * 2 > truth_t.size - 1)
    if unique and times_used:  # the residual the walk below would see at each unique twin
        late = np.abs(diffs - offsets[tj]) > time_tol_s
        times_used = bool(np.count_nonzero(late) * 2 <= late.size)

    pairs_raw: list[int] = []
    pairs_truth: list[int] = []
    residuals: list[float] = []
    last = -1
    for j, key in enumerate(truth_keys):
        candidates = np.asarray([i for i in where.get(key, ()) if i > last], dtype=np.intp)
        if candidates.size == 0:
            continue
        residual = np.abs(raw_t[candidates] - offsets[j] - truth_t[j])
        best = int(np.argmin(residual)) if times_used else 0
        if times_used and residual[best] > time_tol_s:
            continue
        last = int(candidates[best])
        pairs_raw.append(last)
        pairs_truth.append(j)
        residuals.append(float(residual[best]))
    if not pairs_raw:
        raise LogFormatError(
            f"{truth.path}: scans with the ranges of {raw.path}'s exist, but none within "
            f"{time_tol_s} s of the clock offset (about {offset:.3f} s): are the timestamps of "
            "one run?"
        )
    truth_index = np.asarray(pairs_truth, dtype=np.intp)
    raw_index = np.asarray(pairs_raw, dtype=np.intp)
    corrected = np.asarray(truth.poses, dtype=np.float64)[truth_index]
    truth_mounts = np.asarray(truth.laser_mount, dtype=np.float64)[truth_index]
    raw_mounts = np.asarray(raw.laser_mount, dtype=np.float64)[raw_index]
    poses, moved = raw_robot_truth(corrected, truth_mounts, raw_mounts)
    shift = np.hypot(*(poses - corrected)[moved, :2].T)
    suggested = suggest_mount(
        laser_poses(corrected, truth_mounts), np.asarray(raw.odometry, dtype=np.float64)[raw_index]
    )
    return TruthPairing(
        raw_path=raw.path,
        truth_path=truth.path,
        n_raw=len(raw),
        n_truth=len(truth),
        raw_index=raw_index,
        truth_index=truth_index,
        truth_poses=poses,
        clock_offset_s=offset,
        max_time_residual_s=max(residuals),
        times_used=times_used,
        time_tol_s=time_tol_s,
        mount_moved=int(np.count_nonzero(moved)),
        mount_shift_m=float(shift.max()) if shift.size else 0.0,
        suggested_mount=suggested,
        raw_mount=(float(raw_mounts[0, 0]), float(raw_mounts[0, 1])),
    )


#: :func:`suggest_mount` needs this much turning, ``sum(2 (1 - cos dtheta))`` over the pairs
#: (about 40 turns of 0.2 rad), to give an answer.
MIN_TURNING = 1.6
#: ... and drops this share of the pairs that fit worst before its second solve.
MOUNT_TRIM = 0.1


def suggest_mount(
    laser: NDArray[np.float64], odometry: NDArray[np.float64]
) -> tuple[float, float] | None:
    """The laser's position ``(x, y)`` on the robot that makes the laser poses ``laser``
    (world, one per pair, in time order) move between consecutive pairs as the odometry poses
    ``odometry`` of the same scans say the robot's axis moved (module docstring, "which mount
    the data suggest"): least squares, then again without the worst :data:`MOUNT_TRIM` of the
    pairs. ``None`` when the robot turned less than :data:`MIN_TURNING` in all (the mount is
    then not seen) or nothing is finite."""
    laser = np.asarray(laser, dtype=np.float64)
    odometry = np.asarray(odometry, dtype=np.float64)
    ok = np.all(np.isfinite(laser), axis=1) & np.all(np.isfinite(odometry), axis=1)
    laser, odometry = laser[ok], odometry[ok]
    if laser.shape[0] < 2:
        return None
    # each pair's step in the frame of its first pose: the laser's (dL), the odometry's (du)
    step = relative_poses(laser[:-1], laser[1:])
    du = relative_poses(odometry[:-1], odometry[1:])
    bx, by = step[:, 0] - du[:, 0], step[:, 1] - du[:, 1]
    # (Rot(dtheta) - I) m = b, one pair of rows a pair
    a11, a21 = np.cos(step[:, 2]) - 1.0, np.sin(step[:, 2])

    def solve(keep: NDArray[np.bool_]) -> NDArray[np.float64] | None:
        k11, k21, kx, ky = a11[keep], a21[keep], bx[keep], by[keep]
        turning = float(np.sum(k11**2 + k21**2))  # the normal matrix is turning x I
        if not turning >= MIN_TURNING:
            return None
        # A^T b with A = [[a11, -a21], [a21, a11]]
        return np.array([np.sum(k11 * kx + k21 * ky), np.sum(-k21 * kx + k11 * ky)]) / turning

    first = solve(np.ones(bx.size, dtype=bool))
    if first is None:
        return None
    rx = a11 * first[0] - a21 * first[1] - bx
    ry = a21 * first[0] + a11 * first[1] - by
    misfit = np.hypot(rx, ry)
    second = solve(misfit <= np.quantile(misfit, 1.0 - MOUNT_TRIM))
    m = first if second is None else second
    return float(m[0]), float(m[1])


def raw_robot_truth(
    truth_poses: NDArray[np.float64],
    truth_mounts: NDArray[np.float64],
    raw_mounts: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The raw robot's true pose at each pair (module docstring, "whose pose"): the corrected
    laser pose ``truth_poses + truth_mounts`` less the raw mount; and which pairs moved (their
    mounts differ; the others keep the corrected pose, bit for bit)."""
    moved = np.any(truth_mounts != raw_mounts, axis=1)
    out = truth_poses.copy()
    if moved.any():
        laser = laser_poses(truth_poses[moved], truth_mounts[moved])
        m = raw_mounts[moved]
        # the robot in the laser's frame: the origin seen from the mount
        robot = laser_poses(laser, relative_poses(m, np.zeros_like(m)))
        robot[:, 2] = wrap(robot[:, 2])
        out[moved] = robot
    return out, moved


__all__ = [
    "DEFAULT_DECIMALS",
    "DEFAULT_TIME_TOL_S",
    "TruthPairing",
    "pair_truth",
    "raw_robot_truth",
    "scan_keys",
    "suggest_mount",
]
