"""Scan times that go backwards or are not numbers: refused with the line, or repaired on request.

A filter, the TUM trajectory and ``duration_s`` all read a log's clock as increasing. Real
logs jitter: the Radish intel logs step back by up to 0.86 s between scans (messages stamped
on different hosts). :func:`check_times` therefore accepts steps back of at most
:data:`BACKSTEP_TOLERANCE_S` (kept as recorded) and refuses a larger step back, or a time that
is not finite, naming the file and line (CARMEN) or the scan (bags). With ``repair=True``
(``--repair-times``) every time is instead raised to the latest time before it (a NaN takes
the previous scan's time), and ``info["repaired_times"]`` counts the scans changed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ceamcl.errors import LogFormatError
from ceamcl.io.recorded import RecordedLog

__all__ = ["BACKSTEP_TOLERANCE_S", "check_times"]

#: Largest step back of the clock between consecutive scans accepted as jitter.
BACKSTEP_TOLERANCE_S = 1.0


def _where(log: RecordedLog, k: int) -> str:
    lines = log.info.get("scan_lines")
    if lines is not None and len(lines) == len(log):
        return f"{log.path}:{int(lines[k])}"
    return f"{log.path}: scan {k}"


def check_times(log: RecordedLog, *, repair: bool = False) -> RecordedLog:
    """The log unchanged if its times are finite and never step back by more than the
    tolerance; else an error, or (``repair``) the log with non-decreasing times."""
    t = np.asarray(log.times, dtype=np.float64)
    not_finite = ~np.isfinite(t)
    back = np.zeros(t.size, dtype=bool)
    if t.size > 1:
        prev = np.fmax.accumulate(np.where(not_finite, -np.inf, t))[:-1]
        back[1:] = t[1:] < prev - BACKSTEP_TOLERANCE_S
    bad = not_finite | back
    if not bad.any():
        return log
    if not repair:
        k = int(np.flatnonzero(bad)[0])
        if not_finite[k]:
            what = f"scan time {t[k]}: expected a finite number of seconds"
        else:
            latest = float(np.nanmax(t[:k]))
            what = (
                f"scan time {t[k]:.6f} s is {latest - t[k]:.3f} s before an earlier scan's "
                f"{latest:.6f} s; expected times that do not go back by more than "
                f"{BACKSTEP_TOLERANCE_S:g} s"
            )
        raise LogFormatError(
            f"{_where(log, k)}: {what} (--repair-times raises such times to the latest before)"
        )
    fixed = np.where(not_finite, -np.inf, t)
    fixed = np.maximum.accumulate(fixed)
    fixed[np.isneginf(fixed)] = 0.0  # NaN before any finite time: the clock starts at 0
    changed = int(np.count_nonzero(fixed != t))
    return replace(log, times=fixed, info={**log.info, "repaired_times": changed})
