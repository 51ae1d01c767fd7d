"""The bulk summary of many series in one compiled pass: mean, sd, HDI, R-hat, bulk ESS.

What a fleet asks for (twelve series per bus, tens of thousands of buses):
:func:`summarize` gives ``convergence.summarize(..., tail=False)``'s numbers, through a
compiled pass (:func:`summarize_bulk`) for finite draws of 2 or more chains and an even
number (4 or more) of draws per chain, through the general path otherwise. Same
formulas, same numbers to the last bit (``tests/unit/test_bulk_summary.py`` checks it
against the general path and against ArviZ); only the work is arranged differently:

- each series is sorted once by a bucket sort: two buckets per draw, a draw's bucket
  ``floor(n (1 + t / (1 + |t|)))`` with ``t = 0.8 (x - mean) / sd`` (about the normal
  CDF, so a posterior fills the buckets evenly: equally wide buckets put 3 draws in the
  middle ones), then one insertion pass over all draws, which sorts whatever the buckets
  (numpy's sort takes over after 64 moves a draw, a shape far from the buckets'). 8,000
  draws: 68 us, 107 us with one equally wide bucket per draw and insertion bucket by
  bucket, 200 us by numpy's argsort (measured on this loaded 2-core machine); a constant
  series (a given P0) is not sorted at all;
- the ranks' normal scores, the HDI, the median, the folded draws' order (a merge of the
  two sides of the median) and their scores are computed in the same loop, without
  numpy's temporaries (``take_along_axis``, ``concatenate``: a third of the old cost);
- the ESS that need more than :data:`~loadbayes.core.convergence.DIRECT_LAGS` lags get
  their autocovariances from one batched FFT
  (:func:`~loadbayes.core.convergence.ess_fft`, as the general path).

Average ranks do not depend on how ties are ordered, so any sort gives the same scores.
The compiled functions here call ``convergence``'s (``_ess_direct``) and
numba's cache keys a kernel on its own file only: after editing ``convergence.py``,
delete this module's cached ``*.nbi``/``*.nbc`` files.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from loadbayes.core.convergence import (
    _MIN_DRAWS_PER_THREAD,
    DIRECT_LAGS,
    _ess_direct,
    _rhat,
    _scores,
    _scores_sorted,
    ess_fft,
)

__all__ = ["applies", "summarize", "summarize_bulk"]

#: Series per compiled pass (their scores take 2 x 8 bytes x draws each).
_BLOCK = 256

#: Buckets per draw in the bucket sort (2: 30% faster than 1, measured).
_BUCKETS = 2

#: Moves per draw of the bucket sort's insertion pass beyond which numpy's sort takes over.
_MAX_MOVES = 64


def applies(x: np.ndarray) -> bool:
    """Whether :func:`summarize_bulk` gives the general path's numbers for ``x``.

    ``x`` (series, chain, draw), float64: 2 or more chains, an even number of draws (4 or
    more) and no NaN or infinity (those take the general path, which handles them).
    """
    return (
        x.ndim == 3
        and x.shape[1] >= 2
        and x.shape[2] >= 4
        and x.shape[2] % 2 == 0
        and bool(np.isfinite(x).all())
    )


@njit(cache=True, nogil=True, error_model="numpy")
def _bucket_sort(v, order, srt, keys, starts):  # pragma: no cover - compiled
    """``srt`` = ``v`` sorted and ``order`` with ``v[order] == srt`` (ties in any order).

    ``v`` finite; ``keys`` (n) and ``starts`` (:data:`_BUCKETS` n + 1) are work space.
    Values travel with their indices, so the moves read contiguous memory.
    """
    n = v.size
    lo = v[0]
    hi = v[0]
    s1 = 0.0
    for i in range(n):
        lo = min(lo, v[i])
        hi = max(hi, v[i])
        s1 += v[i]
    if hi == lo:
        # constant (a given P0): already sorted
        for i in range(n):
            order[i] = i
            srt[i] = v[i]
        return
    mean = s1 / n
    s2 = 0.0
    for i in range(n):
        s2 += (v[i] - mean) * (v[i] - mean)
    k = 0.8 / np.sqrt(s2 / n)
    if not (np.isfinite(k) and k > 0.0 and np.isfinite(mean)):
        # a spread too small or too large for the buckets
        _argsort_into(v, order, srt)
        return
    nb = _BUCKETS * n
    half = 0.5 * nb
    for b in range(nb + 1):
        starts[b] = 0
    for i in range(n):
        # t / (1 + |t|): about the normal CDF's shape, so buckets fill evenly
        t = (v[i] - mean) * k
        b = min(max(int(half + half * t / (1.0 + abs(t))), 0), nb - 1)
        keys[i] = b
        starts[b + 1] += 1
    for b in range(nb):
        starts[b + 1] += starts[b]
    for i in range(n):
        b = keys[i]
        f = starts[b]
        order[f] = i
        srt[f] = v[i]
        starts[b] = f + 1
    # One insertion pass sorts whatever the buckets (rounding may put a value one bucket
    # off): a draw moves only past the few of its own bucket. Too many moves (a posterior
    # far from the buckets' shape): numpy's sort instead.
    moves = 0
    for i in range(1, n):
        val = srt[i]
        if srt[i - 1] <= val:
            continue
        o = order[i]
        j = i - 1
        while j >= 0 and srt[j] > val:
            srt[j + 1] = srt[j]
            order[j + 1] = order[j]
            j -= 1
        srt[j + 1] = val
        order[j + 1] = o
        moves += i - 1 - j
        if moves > _MAX_MOVES * n:
            _argsort_into(v, order, srt)
            return


@njit(cache=True, nogil=True, error_model="numpy")
def _argsort_into(v, order, srt):  # pragma: no cover - compiled
    o = np.argsort(v)
    for i in range(v.size):
        order[i] = o[i]
        srt[i] = v[o[i]]


@njit(cache=True, nogil=True, error_model="numpy")
def _rank_pass(x, inc, table, half_table, z, zf, hdi_lo, hdi_hi):  # pragma: no cover
    """Per series of ``x`` (m, c, d), ``d`` even: the split chains' rank scores and HDI.

    ``z`` and ``zf`` (m, c d) receive the normal scores of the ranks of the draws and of
    the folded draws ``|x - median|``, in ``az.summary``'s split order (the first halves
    of every chain, then the second halves: reshape to (m, 2c, d / 2)); ``hdi_lo``,
    ``hdi_hi`` the HDI of ``inc + 1`` draws (``arviz.hdi``: the first narrowest).
    """
    m, c, d = x.shape
    half = d // 2
    n = c * d
    v = np.empty(n)
    order = np.empty(n, np.int64)
    keys = np.empty(n, np.int64)
    starts = np.empty(_BUCKETS * n + 1, np.int64)
    srt = np.empty(n)
    fsrt = np.empty(n)
    forder = np.empty(n, np.int64)
    for s in range(m):
        # the split chains, flattened as numpy's concatenate + reshape
        for k in range(2 * c):
            ch = k % c
            off = 0 if k < c else half
            for i in range(half):
                v[k * half + i] = x[s, ch, off + i]
        _bucket_sort(v, order, srt, keys, starts)
        # HDI: np.argmin of the widths (the first minimum)
        best = 0
        wbest = srt[inc] - srt[0]
        for i in range(1, n - inc):
            w = srt[i + inc] - srt[i]
            if w < wbest:
                wbest = w
                best = i
        hdi_lo[s] = srt[best]
        hdi_hi[s] = srt[best + inc]
        _scores_sorted(srt, order, table, half_table, z[s])
        # The median of all draws (n even); |x - med| in increasing order is the merge of
        # the two sides of the median (IEEE subtraction is monotone and med - x equals
        # -(x - med) exactly, so these are numpy's abs(x - med) values).
        k2 = n // 2
        med = (srt[k2 - 1] + srt[k2]) / 2
        hi = np.searchsorted(srt, med)
        lo = hi - 1
        for k in range(n):
            if lo < 0 or (hi < n and srt[hi] - med <= med - srt[lo]):
                fsrt[k] = srt[hi] - med
                forder[k] = order[hi]
                hi += 1
            else:
                fsrt[k] = med - srt[lo]
                forder[k] = order[lo]
                lo -= 1
        _scores_sorted(fsrt, forder, table, half_table, zf[s])


def _ess(y: np.ndarray) -> np.ndarray:
    """ESS of each series of ``y`` (m, chains, draws), as ``convergence``'s; FFT batched."""
    m, c, d = y.shape
    mean_var = np.zeros(m)
    var_plus = np.zeros(m)
    out = _ess_direct(y, y.mean(axis=2), DIRECT_LAGS, mean_var, var_plus)
    idx = np.flatnonzero(out == -1.0)
    for b0 in range(0, idx.size, 64):
        sel = idx[b0 : b0 + 64]
        out[sel] = ess_fft(y[sel], mean_var[sel], var_plus[sel])
    return out


def summarize_bulk(x: np.ndarray, hdi_prob: float) -> dict[str, np.ndarray]:
    """``mean, sd, hdi_low, hdi_high, ess_bulk, r_hat`` of each series of ``x``.

    ``x`` (m, chain, draw) float64, C-contiguous, with :func:`applies` true. The numbers
    are those of ``convergence.summarize(x, tail=False)``.
    """
    m, c, d = x.shape
    half = d // 2
    n = c * d
    inc = int(np.floor(hdi_prob * n))
    table, half_table = _scores(n, False), _scores(n, True)
    out = {
        "mean": x.mean(axis=(1, 2)),
        "sd": x.std(axis=(1, 2), ddof=1),
        "hdi_low": np.empty(m),
        "hdi_high": np.empty(m),
        "ess_bulk": np.empty(m),
        "r_hat": np.empty(m),
    }
    with np.errstate(divide="ignore", invalid="ignore"):
        for b0 in range(0, m, _BLOCK):
            b1 = min(b0 + _BLOCK, m)
            z2 = np.empty((b1 - b0, n))
            zf2 = np.empty_like(z2)
            _rank_pass(x[b0:b1], inc, table, half_table, z2, zf2,
                       out["hdi_low"][b0:b1], out["hdi_high"][b0:b1])  # fmt: skip
            z = z2.reshape(b1 - b0, 2 * c, half)
            zf = zf2.reshape(b1 - b0, 2 * c, half)
            out["ess_bulk"][b0:b1] = _ess(z)
            bulk = _rhat(z, z.mean(axis=2))
            fold = _rhat(zf, zf.mean(axis=2))
            # Python's max(bulk, fold), as ArviZ (NaN first wins, NaN second loses)
            out["r_hat"][b0:b1] = np.where(fold > bulk, fold, bulk)
    return out


def summarize(
    draws: np.ndarray, *, hdi_prob: float = 0.95, threads: int | None = None
) -> dict[str, np.ndarray]:
    """``convergence.summarize(draws, hdi_prob=hdi_prob, tail=False)``, faster.

    The series are split between ``threads`` (default
    :func:`~loadbayes.core.parallel.num_threads`) threads (the compiled passes release
    the GIL); the numbers do not depend on the threads.
    """
    from loadbayes.core.convergence import summarize as general
    from loadbayes.core.parallel import num_threads, run_threads

    x = np.ascontiguousarray(draws, dtype=float)
    if not applies(x):
        return general(x, hdi_prob=hdi_prob, tail=False)
    m = x.shape[0]
    groups = min(threads or num_threads(), m, max(1, x.size // _MIN_DRAWS_PER_THREAD))
    bounds = np.linspace(0, m, groups + 1).astype(int)
    parts: list[dict[str, np.ndarray]] = [{} for _ in range(groups)]

    def task(i: int):
        def run() -> None:
            parts[i] = summarize_bulk(x[bounds[i] : bounds[i + 1]], hdi_prob)

        return run

    run_threads([task(i) for i in range(groups)])
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
