"""Resampling schemes: functions from normalised weights to ancestor indices (as in
nchopin/particles' ``resampling.py``), registered by name in :data:`RESAMPLERS`; resampling
inside labels (CEAMCL's species); and the log-weight arithmetic every filter shares."""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: ``scheme(weights, n, rng) -> ancestor indices (n,)``.
Resampler = Callable[[ArrayLike, int, np.random.Generator], NDArray[np.intp]]


def systematic(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Low-variance (systematic) resampling, Probabilistic Robotics Table 4.4.

    One uniform offset, ``n`` evenly spaced pointers into the cumulative weights. Each index
    ``i`` is drawn ``floor(n w_i)`` or ``ceil(n w_i)`` times. NaN, infinite or negative
    weights count as 0; if no weight is left, every index is equally likely.
    """
    w = np.asarray(weights, dtype=np.float64)
    if n <= 0 or w.size == 0:
        return np.zeros(0, dtype=np.intp)
    cdf = _cdf(w)
    pointers = (rng.random() + np.arange(n)) / n
    idx = np.searchsorted(cdf, pointers, side="right")
    return np.minimum(idx, w.size - 1).astype(np.intp)


def multinomial(weights: ArrayLike, n: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Multinomial resampling: ``n`` independent draws from the weights (amcl's roulette
    wheel). Bad weights count as in :func:`systematic`."""
    w = np.asarray(weights, dtype=np.float64)
    if n <= 0 or w.size == 0:
        return np.zeros(0, dtype=np.intp)
    idx = np.searchsorted(_cdf(w), rng.random(n), side="right")
    return np.minimum(idx, w.size - 1).astype(np.intp)


def _cdf(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cumulative weights ending at 1; NaN, infinite or negative weights count as 0, and
    with no weight left every index is equally likely."""
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is repaired below
        cdf = np.cumsum(w)
    if not (np.isfinite(cdf[-1]) and cdf[-1] > 0.0) or np.any(w < 0):
        w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
        top = w.max() if w.size else 0.0
        cdf = np.cumsum(w / top) if top > 0.0 else np.cumsum(w)  # finite weights may overflow
        if not cdf[-1] > 0.0:
            cdf = np.arange(1.0, w.size + 1.0)
    cdf /= cdf[-1]
    return cdf


#: Resampling schemes by name.
RESAMPLERS: dict[str, Resampler] = {"systematic": systematic, "multinomial": multinomial}


def resampler(name: str) -> Resampler:
    """The resampling scheme ``name`` (see :data:`RESAMPLERS`)."""
    try:
        return RESAMPLERS[name]
    except KeyError:
        raise ValueError(
            f"resampling scheme: unknown {name!r}; expected one of {', '.join(RESAMPLERS)}"
        ) from None


def effective_sample_size(weights: ArrayLike) -> float:
    """``1 / sum w_i^2`` of normalised weights."""
    w = np.asarray(weights, dtype=np.float64)
    s = float(np.sum(w * w))
    return 1.0 / s if s > 0 else 0.0


def sanitise_log_likelihood(log_likelihood: ArrayLike) -> NDArray[np.float64]:
    """Log-likelihoods with NaN and +inf (a model's numerical failure) turned into -inf
    (impossible), so they can never spread into weights or poses."""
    ll = np.asarray(log_likelihood, dtype=np.float64)
    bad = np.isnan(ll) | (ll == np.inf)
    if bad.any():
        ll = np.where(bad, -np.inf, ll)
    return ll


def normalise_log_weights(
    log_weights: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Shift log-weights so the largest is 0 and return ``(log_w, w, ok)`` with ``w`` summing to 1.

    ``ok`` is False when no weight is finite (everything impossible or NaN); the weights are
    then uniform, so the caller never propagates NaN.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    lw = np.where(np.isnan(lw), -np.inf, lw)
    top = float(np.max(lw)) if lw.size else -np.inf
    if not np.isfinite(top):
        n = max(lw.size, 1)
        return np.zeros(lw.size), np.full(lw.size, 1.0 / n), False
    lw = lw - top
    w = np.exp(lw)
    total = float(w.sum())
    return lw - np.log(total), w / total, True


def label_segments(
    labels: NDArray[np.int64],
) -> tuple[NDArray[np.intp], NDArray[np.int64], NDArray[np.intp], NDArray[np.intp]]:
    """The particles sorted by label: ``(order, ids, starts, counts)``, so that label
    ``ids[k]`` (ascending) owns ``order[starts[k] : starts[k] + counts[k]]``."""
    if labels.size and labels[0] == labels[-1] and bool(np.all(labels == labels[0])):
        # one label (a lone species: CEAMCL tracking), the stable sort's answer without it
        first = np.zeros(1, dtype=np.intp)
        return np.arange(labels.size), labels[:1].copy(), first, np.array([labels.size])
    order = np.argsort(labels, kind="stable")
    ids, starts = np.unique(labels[order], return_index=True)
    counts = np.diff(np.append(starts, order.size))
    return order, ids, starts, counts


def c_library(fn: Callable[..., float], *args: NDArray[np.float64]) -> NDArray[np.float64]:
    """``fn``, a function of :mod:`math`, number by number: the C library's bits, which the
    compiled kernels get. NumPy's vectorised ``exp``, ``log``, ``sin``, ``cos`` and ``arctan2``
    differ from them in the last bit on CPUs with AVX-512, so the NumPy references that a kernel
    must equal bit for bit call this instead (slow: references and tests only). A domain error
    gives NaN and an overflow infinity, as NumPy does."""

    def safe(*values: float) -> float:
        try:
            return fn(*values)
        except ValueError:
            return math.nan
        except OverflowError:
            return math.inf

    columns = [np.asarray(a, dtype=np.float64).ravel().tolist() for a in args]
    shape = np.shape(args[0])
    return np.fromiter(map(safe, *columns), dtype=np.float64, count=len(columns[0])).reshape(shape)


def segment_weights(
    loglik: NDArray[np.float64], starts: NDArray[np.intp], seg: NDArray[np.intp]
) -> NDArray[np.float64]:
    """In-label importance weights of log-likelihoods sorted by label (segment ``seg[i]``
    of particle ``i`` begins at ``starts[seg[i]]``): each segment's weights sum to 1, never
    NaN; a segment with no finite log-likelihood gets uniform weights. For the NumPy
    references (its ``exp`` is the C library's, :func:`c_library`)."""
    ll = np.where(np.isnan(loglik), -np.inf, loglik)
    top = np.maximum.reduceat(ll, starts)
    finite_top = np.isfinite(top)
    w = c_library(math.exp, ll - np.where(finite_top, top, 0.0)[seg])
    w = np.where(finite_top[seg], w, 1.0)
    return np.asarray(w / np.add.reduceat(w, starts)[seg], dtype=np.float64)


def label_groups(labels: NDArray[np.int64]) -> dict[int, NDArray[np.intp]]:
    """Indices of the particles of each label (a species id), in ascending label order."""
    if labels.size == 0:
        return {}
    order, ids, starts, counts = label_segments(labels)
    return {int(i): order[s : s + c] for i, s, c in zip(ids, starts, counts, strict=True)}


def systematic_within_labels(
    labels: NDArray[np.int64],
    loglik: NDArray[np.float64],
    targets: dict[int, int],
    rng: np.random.Generator,
) -> tuple[NDArray[np.intp], dict[int, NDArray[np.intp]]]:
    """Low-variance resampling inside every label (species) at once: ``targets.get(id, size)``
    ancestors of each label, drawn from the in-label weights of ``loglik`` with one uniform
    offset per label (ascending ids), as :func:`systematic` would draw them label by label.

    Returns ``(ancestors, members)``: the ancestors' indices, grouped by label in ascending
    order, and the members of each surviving label among the resampled particles (contiguous
    ranges, what :func:`label_groups` would return for them). The weights, cumulative sums
    and searches are compiled (:func:`_systematic_positions`) and give the bits of
    :func:`systematic_within_labels_reference`, its NumPy form.
    """
    if labels.size == 0:
        return np.zeros(0, dtype=np.intp), {}
    order, ids, starts, counts = label_segments(labels)
    n = np.array([targets.get(int(sid), int(c)) for sid, c in zip(ids, counts, strict=True)])
    n = np.maximum(n, 0)
    u = np.zeros(ids.size)
    u[n > 0] = rng.random(int(np.count_nonzero(n > 0)))
    pos = _systematic_positions(
        np.ascontiguousarray(loglik[order], dtype=np.float64),
        starts.astype(np.intp),
        counts.astype(np.intp),
        n.astype(np.intp),
        u,
    )
    first = np.cumsum(n) - n
    members = {
        int(sid): np.arange(a, a + c, dtype=np.intp)
        for sid, a, c in zip(ids, first, n, strict=True)
        if c > 0
    }
    return order[pos].astype(np.intp), members


def systematic_within_labels_reference(
    labels: NDArray[np.int64],
    loglik: NDArray[np.float64],
    targets: dict[int, int],
    rng: np.random.Generator,
) -> tuple[NDArray[np.intp], dict[int, NDArray[np.intp]]]:
    """:func:`systematic_within_labels` in NumPy, the reference it equals bit for bit
    (``tests/filters/test_resampling.py``)."""
    if labels.size == 0:
        return np.zeros(0, dtype=np.intp), {}
    order, ids, starts, counts = label_segments(labels)
    seg = np.repeat(np.arange(ids.size), counts)
    w = segment_weights(loglik[order], starts, seg)
    # Cumulative weights inside each label, normalised by the label's total.
    cum = np.cumsum(w)
    local = cum - np.append(0.0, cum)[starts][seg]
    ends = starts + counts - 1
    cdf = local / local[ends][seg]
    n = np.array([targets.get(int(sid), int(c)) for sid, c in zip(ids, counts, strict=True)])
    n = np.maximum(n, 0)
    u = np.zeros(ids.size)
    u[n > 0] = rng.random(int(np.count_nonzero(n > 0)))
    ptr_seg = np.repeat(np.arange(ids.size), n)
    first = np.cumsum(n) - n
    k = np.arange(ptr_seg.size) - first[ptr_seg]
    pointers = (u[ptr_seg] + k) / n[ptr_seg]
    # One search for all labels: label k's cumulative weights lie in [2k, 2k + 1].
    pos = np.searchsorted(2.0 * seg + cdf, 2.0 * ptr_seg + pointers, side="right")
    pos = np.minimum(pos, ends[ptr_seg])
    members = {
        int(sid): np.arange(a, a + c, dtype=np.intp)
        for sid, a, c in zip(ids, first, n, strict=True)
        if c > 0
    }
    return order[pos].astype(np.intp), members


# ------------------------------------------------------------ compiled segment sums
@numba.njit(cache=True)
def _pairwise_sum(a: NDArray[np.float64], lo: int, n: int) -> float:  # pragma: no cover
    """NumPy's pairwise summation of ``a[lo : lo + n]`` (numpy/_core/src/umath/loops_utils.h:
    eight running sums in blocks of up to 128, halves above), operation for operation."""
    if n < 8:
        res = -0.0  # NumPy 2 keeps the sign of a sum of negative zeros
        for i in range(n):
            res += a[lo + i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        stop = n - n % 8
        while i < stop:
            j = lo + i
            r0 += a[j]
            r1 += a[j + 1]
            r2 += a[j + 2]
            r3 += a[j + 3]
            r4 += a[j + 4]
            r5 += a[j + 5]
            r6 += a[j + 6]
            r7 += a[j + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise_sum(a, lo, n2) + _pairwise_sum(a, lo + n2, n - n2)


@numba.njit(cache=True)
def segment_sum(a: NDArray[np.float64], s: int, e: int) -> float:  # pragma: no cover
    """``np.add.reduceat``'s sum of ``a[s:e]``: the first value plus the pairwise sum of the
    rest."""
    return a[s] + _pairwise_sum(a, s + 1, e - s - 1)


@numba.njit(cache=True)
def maximum(x: float, y: float) -> float:  # pragma: no cover
    """``np.maximum(x, y)`` of two numbers: NaN propagates, ties keep ``x``."""
    return x if (x >= y or np.isnan(x)) else y


@numba.njit(cache=True)
def segment_max(a: NDArray[np.float64], s: int, e: int) -> float:  # pragma: no cover
    """``np.maximum.reduceat``'s maximum of ``a[s:e]`` (NaN propagates)."""
    m = a[s]
    for i in range(s + 1, e):
        m = maximum(m, a[i])
    return m


@numba.njit(cache=True)
def segment_weights_into(ll, s, e, buf, out):  # type: ignore[no-untyped-def]  # pragma: no cover
    """:func:`segment_weights` of the one segment ``[s, e)`` of ``ll`` into ``out[s:e]``, the
    same operations and sums (``buf``: scratch of the same length)."""
    for i in range(s, e):
        v = ll[i]
        buf[i] = -np.inf if np.isnan(v) else v
    top = segment_max(buf, s, e)
    if np.isfinite(top):
        for i in range(s, e):
            buf[i] = np.exp(buf[i] - top)
    else:
        for i in range(s, e):
            buf[i] = 1.0
    total = segment_sum(buf, s, e)
    for i in range(s, e):
        out[i] = buf[i] / total


@numba.njit(cache=True)
def _systematic_positions(ll, starts, counts, n, u):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The reference's searches: each label's in-label weights (:func:`segment_weights`), their
    running sum over all labels (``np.cumsum``) less the labels before, normalised by the
    label's total, and for pointer ``j`` of the ``n[k]`` of label ``k`` the position of
    ``2 k + (u[k] + j) / n[k]`` among the keys ``2 k + cdf`` (``np.searchsorted``, side
    right), at most the label's last particle."""
    n_all = ll.size
    w = np.empty(n_all)
    buf = np.empty(n_all)
    for k in range(starts.size):
        segment_weights_into(ll, starts[k], starts[k] + counts[k], buf, w)
    cum = np.empty(n_all)
    cum[0] = w[0]
    for i in range(1, n_all):
        cum[i] = cum[i - 1] + w[i]
    keys = np.empty(n_all)
    for k in range(starts.size):
        s = starts[k]
        e = s + counts[k]
        before = 0.0 if s == 0 else cum[s - 1]
        last = cum[e - 1] - before
        for i in range(s, e):
            keys[i] = 2.0 * k + (cum[i] - before) / last
    total = 0
    for k in range(n.size):
        total += n[k]
    pos = np.empty(total, dtype=np.intp)
    j = 0
    for k in range(n.size):
        end = starts[k] + counts[k] - 1
        for m in range(n[k]):
            q = 2.0 * k + (u[k] + m) / n[k]
            lo, hi = 0, n_all  # the first key > q (side right)
            while lo < hi:
                mid = (lo + hi) >> 1
                if keys[mid] <= q:
                    lo = mid + 1
                else:
                    hi = mid
            pos[j] = min(lo, end)
            j += 1
    return pos
