"""Where the runs of ``ceamcl evaluate-log`` start and stop: evenly spread windows of a log,
each a whole window of scans, seconds or metres of travel."""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from ceamcl.errors import ConfigError
from ceamcl.io.recorded import RecordedLog

#: Default window of each evaluation run: 50 m of travel along the true path.
DEFAULT_WINDOW_M = 50.0


def _progress(
    log: RecordedLog, scans: int | None, window_s: float | None, window_m: float | None
) -> tuple[NDArray[np.float64], float, str]:
    """What a window's length is measured in, the length, and its description."""
    if sum(v is not None for v in (scans, window_s, window_m)) > 1:
        raise ConfigError("window: give one of scans, window_s and window_m, not several")
    if scans is not None:
        if scans < 2:
            raise ConfigError(f"scans: expected at least 2 scans per window, got {scans}")
        return np.arange(len(log), dtype=np.float64), float(scans - 1), f"{scans} scans"
    if window_s is not None:
        if not window_s > 0:
            raise ConfigError(f"window-s: expected a positive duration, got {window_s}")
        # a log's clock may step back a little (intel-corrected does): measure forward time
        elapsed = np.maximum.accumulate(log.times - log.times[0])
        return elapsed, float(window_s), f"{window_s:g} s"
    dist_m = DEFAULT_WINDOW_M if window_m is None else window_m
    if not dist_m > 0:
        raise ConfigError(f"window-m: expected a positive distance, got {dist_m}")
    return log.travelled_m, float(dist_m), f"{dist_m:g} m of travel"


def start_windows(
    log: RecordedLog,
    starts: int,
    *,
    scans: int | None = None,
    window_s: float | None = None,
    window_m: float | None = None,
) -> tuple[list[tuple[int, int]], str]:
    """Up to ``starts`` non-overlapping windows ``(start, stop)`` with evenly spread starts
    (fewer, said in the description, when the log is too short for all), each a whole window
    (``scans`` scans, ``window_s`` seconds or ``window_m`` metres of travel; default
    :data:`DEFAULT_WINDOW_M`), and the window's description.

    A window ends at the first scan where the length is reached. The latest start is the last
    one whose whole window lies in the log.
    """
    progress, length, what = _progress(log, scans, window_s, window_m)
    fits = np.flatnonzero(progress[-1] - progress >= length - 1e-9)
    if fits.size == 0:
        raise ConfigError(
            f"{log.path}: the log ({len(log)} scans, {log.duration_s:.0f} s, "
            f"{log.path_length_m:.0f} m) is shorter than one evaluation window of {what}; "
            "choose a shorter --scans/--window-s/--window-m"
        )
    last = int(fits[-1])

    def spread(k: int) -> list[tuple[int, int]]:
        picks = np.unique(np.round(np.linspace(0, last, k)).astype(int))
        out = []
        for s in picks:
            stop = int(np.searchsorted(progress, progress[s] + length - 1e-9, side="left")) + 1
            out.append((int(s), max(stop, int(s) + 2)))
        return out

    # Windows must not overlap (runs sharing scans are not independent): fewer starts when the
    # log is too short for all of them.
    k = starts
    windows = spread(k)
    while k > 1 and any(a[1] > b[0] for a, b in itertools.pairwise(windows)):
        k -= 1
        windows = spread(k)
    if scans is None:
        what += _stretched(progress, length, windows, "s" if window_s is not None else "m")
    if len(windows) < starts:
        what += f" ({len(windows)} of the {starts} starts requested fit without overlap)"
    return windows, what


#: A window longer than this many times its length is said to be stretched (its description
#: gives the lengths used).
STRETCHED = 1.5


def _stretched(
    progress: NDArray[np.float64], length: float, windows: list[tuple[int, int]], unit: str
) -> str:
    """Windows of seconds or metres end at the first scan that reaches their length, so a scan
    gap longer than the length stretches them: refused when every window is its first two scans
    because of it (the length decided nothing; "windows of 0.001 s" were 2-4 s long), said in
    the description when some window is stretched ("" when none is)."""
    used = [float(progress[e - 1] - progress[s]) for s, e in windows]
    gaps = [float(progress[s + 1] - progress[s]) for s, _ in windows]
    flag = "window-s" if unit == "s" else "window-m"
    if all(e - s == 2 for s, e in windows) and all(g > length + 1e-9 for g in gaps):
        raise ConfigError(
            f"{flag}: {length:g} {unit} is shorter than the gap between the log's scans at every "
            f"start ({min(gaps):.3g}-{max(gaps):.3g} {unit}), so every window would be its first "
            f"2 scans, not {length:g} {unit}; expected at least {min(gaps):.3g} {unit}, or --scans"
        )
    if max(used) > STRETCHED * length:
        return (
            f" ({min(used):.3g}-{max(used):.3g} {unit} used: a window ends at the first scan "
            "that reaches its length)"
        )
    return ""
