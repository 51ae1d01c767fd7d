"""Posterior summaries as ``arviz.summary`` computes them, compiled, for many series at once.

One idea at about 450 lines, ArviZ's summary: R-hat, ESS and MCSE need the ranks, the
folded draws and the autocovariances, each a compiled kernel of its own.

One implementation for every caller: :meth:`loadbayes.posterior.Posterior.summary` (the
parameters of one fit) and the fleets (a parameter of tens of thousands of buses). The
formulas are ArviZ's (0.23, ``arviz.summary(..., round_to="none")``, Vehtari et al. 2021):

- ``mean``, ``sd`` (``ddof=1``) and the HDI (``arviz.hdi``, one interval) over all draws;
- ``r_hat``: rank-normalised split R-hat, the larger of the bulk and the folded one; the
  folded draws are ``|x - median(x)|`` with the median of all draws (as ``az.summary``;
  ``az.rhat`` takes the median of the split chains, which differs only for an odd
  number of draws);
- ``ess_bulk`` (Geyer's initial monotone sequence on the z-scaled split chains),
  ``ess_tail`` (the smaller ESS of the indicators ``x <= q05`` and ``x <= q95``, type-7
  quantiles), ``mcse_mean`` and ``mcse_sd``.

Agreement with ArviZ. Ranks are average ranks (ties included: Metropolis draws repeat),
the normal scores are the same ``ndtri`` values, the sums are numpy's (the chain means
use numpy's pairwise summation, ported) and the variances ArviZ's numba formula
(``E[x^2] - E[x]^2``, summed in order), so R-hat, mean, sd, HDI and MCSE come out as
ArviZ's to the last bits. The autocovariances are summed lag by lag (a chain that
decorrelates in a few lags needs only those), with an FFT over every lag when the
Geyer sequence runs past :data:`DIRECT_LAGS` (:func:`fft_mean_acov`): the ESS and MCSE
differ from ArviZ's in the last digits only (relative 1e-12 or so;
``tests/unit/test_convergence.py`` checks 1e-8). As ArviZ: a series with a NaN has every
diagnostic NaN (mean, sd and the HDI propagate it as numpy does); fewer than 4 draws give
NaN diagnostics; one chain gives NaN R-hat; a constant series has ESS equal to its
number of split draws.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

__all__ = ["DIRECT_LAGS", "hdi", "summarize"]

#: Lags summed directly before the FFT over all lags takes over. A lag costs a pass over
#: the draws (about 4 us for 8,000), the FFT about 20 lags' worth; a chain that
#: decorrelates in a few lags stops early, a slow one pays the direct lags for nothing.
#: Measured on a fleet's 12 series per bus (8 chains x 1,000 split draws): 8 lags cost
#: 30% less than 48 (the share series' Geyer sequences often run 20 to 120 lags).
DIRECT_LAGS = 8

_RESOLUTION = float(np.finfo(float).resolution)

#: Draws (all series together) below which one thread summarises them all.
_MIN_DRAWS_PER_THREAD = 200_000


@functools.lru_cache(maxsize=8)
def _scores(size: int, half: bool) -> np.ndarray:
    """Normal scores of the ranks 1..size (or 1.5..size + 0.5), Blom's offset 3/8.

    The same float operations as ArviZ's ``_backtransform_ranks`` and ``norm.ppf``.
    """
    from scipy.special import ndtri

    ranks = np.arange(1, size + 1, dtype=float) + (0.5 if half else 0.0)
    out = ndtri((ranks - 0.375) / (size - 2 * 0.375 + 1))
    out.setflags(write=False)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _pairwise_sum(a, lo, n):  # pragma: no cover - compiled
    """``a[lo:lo + n].sum()`` in numpy's order for ``n <= 128`` (8 lanes); in order above.

    Used over chains (few); the sums over draws are numpy's own, passed in. (Not
    recursive: numba cannot load a recursive function from its cache.)
    """
    if n < 8 or n > 128:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True, error_model="numpy")
def _var_seq(a, ddof):  # pragma: no cover - compiled
    """ArviZ's ``stats_variance_1d``: ``E[x^2] - E[x]^2``, summed in order."""
    s = 0.0
    s2 = 0.0
    for v in a:
        s += v
        s2 += v * v
    n = a.size
    var = s2 / n - (s / n) ** 2
    return var * (n / (n - ddof))


@njit(cache=True, nogil=True, error_model="numpy")
def _scores_sorted(srt, order, table, half_table, out):  # pragma: no cover - compiled
    """Normal scores of average ranks: ``srt`` sorted, ``out[order[k]]`` gets rank ``k``'s.

    A tie group at sorted positions ``i..j`` gets rank ``(i + j) / 2 + 1``: an integer
    rank's score is ``table``, a half-integer one's ``half_table``.
    """
    n = srt.size
    i = 0
    while i < n:
        j = i
        vi = srt[i]
        while j + 1 < n and srt[j + 1] == vi:
            j += 1
        if (i + j) % 2 == 0:
            z = table[(i + j) // 2]
        else:
            z = half_table[(i + j - 1) // 2]
        for k in range(i, j + 1):
            out[order[k]] = z
        i = j + 1


@njit(cache=True, nogil=True, error_model="numpy")
def _z_scores(values, order, table, half_table):  # pragma: no cover - compiled
    """:func:`_scores_sorted` of each row of ``values`` (rows sorted by ``order``)."""
    m, n = values.shape
    out = np.empty((m, n))
    for r in range(m):
        _scores_sorted(values[r][order[r]], order[r], table, half_table, out[r])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _fold_order(s, order, med):  # pragma: no cover - compiled
    """Order of ``|x - med|`` from the sorted ``x`` (``s``, ``order``): a merge, not a sort.

    Below the median ``|x - med|`` grows as ``x`` falls, above it as ``x`` rises (IEEE
    subtraction is monotone and ``med - x == -(x - med)`` exactly), so the folded values
    in increasing order are the merge of the two runs; equal values end up adjacent.
    """
    m, n = s.shape
    out = np.empty((m, n), dtype=np.int64)
    for r in range(m):
        row = s[r]
        md = med[r]
        hi = np.searchsorted(row, md)  # first value >= med
        lo = hi - 1
        for k in range(n):
            if lo < 0 or (hi < n and row[hi] - md <= md - row[lo]):
                out[r, k] = order[r, hi]
                hi += 1
            else:
                out[r, k] = order[r, lo]
                lo -= 1
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _rhat(z, chain_means):  # pragma: no cover - compiled
    """Split R-hat of each series of ``z`` (m, chains, draws) (ArviZ's ``_rhat``).

    ``chain_means`` is ``z.mean(axis=2)`` (numpy's sums, as ArviZ's).
    """
    m, c, d = z.shape
    out = np.empty(m)
    cvar = np.empty(c)
    for s in range(m):
        for ch in range(c):
            cvar[ch] = _var_seq(z[s, ch], 1)
        between = d * _var_seq(chain_means[s], 1)
        within = _pairwise_sum(cvar, 0, c) / c
        out[s] = np.sqrt((between / within + d - 1) / d)
    return out


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract", "nsz", "arcp"})
def _lag(xc, t):  # pragma: no cover - compiled
    """Mean over chains of the lag-``t`` autocovariance (sum of products / length)."""
    c, d = xc.shape
    acc = np.empty(c)
    for ch in range(c):
        a = 0.0
        x = xc[ch]
        for i in range(d - t):
            a += x[i] * x[i + t]
        acc[ch] = a / d
    return _pairwise_sum(acc, 0, c) / c


@njit(cache=True, nogil=True, error_model="numpy")
def _geyer(xc, acov, mean_var, var_plus, max_lag):  # pragma: no cover - compiled
    """ESS of one series from its centred chains (ArviZ's ``_ess`` loop).

    Autocovariances come from ``acov`` (the mean over chains, every lag) when it is not
    empty, else from ``xc`` lag by lag; then -1.0 when the sequence runs past
    ``max_lag`` (the caller computes ``acov`` by FFT and calls again).
    """
    c, n_draw = xc.shape
    full = acov.size > 0
    rho = np.zeros(n_draw)
    rho_even = 1.0
    rho[0] = rho_even
    a1 = acov[1] if full else _lag(xc, 1)
    rho_odd = 1.0 - (mean_var - a1) / var_plus
    rho[1] = rho_odd
    t = 1
    while t < (n_draw - 3) and (rho_even + rho_odd) > 0.0:
        if t + 2 >= (acov.size if full else max_lag):
            return -1.0
        ae = acov[t + 1] if full else _lag(xc, t + 1)
        ao = acov[t + 2] if full else _lag(xc, t + 2)
        rho_even = 1.0 - (mean_var - ae) / var_plus
        rho_odd = 1.0 - (mean_var - ao) / var_plus
        if (rho_even + rho_odd) >= 0:
            rho[t + 1] = rho_even
            rho[t + 2] = rho_odd
        t += 2
    max_t = t - 2
    if rho_even > 0:
        rho[max_t + 1] = rho_even
    t = 1
    while t <= max_t - 2:
        if (rho[t + 1] + rho[t + 2]) > (rho[t - 1] + rho[t]):
            rho[t + 1] = (rho[t - 1] + rho[t]) / 2.0
            rho[t + 2] = rho[t + 1]
        t += 2
    ess = c * n_draw
    tau = -1.0 + 2.0 * np.sum(rho[: max_t + 1]) + np.sum(rho[max_t + 1 : max_t + 2])
    tau = max(tau, 1.0 / np.log10(ess))
    if np.isnan(rho).any():
        return np.nan
    return ess / tau


@njit(cache=True, nogil=True, error_model="numpy")
def _ess_direct(y, chain_means, max_lag, mean_var_out, var_plus_out):  # pragma: no cover
    """ESS of each series of ``y`` (m, chains, draws); -1.0 where the FFT is needed.

    ``chain_means`` is ``y.mean(axis=2)``; ``mean_var_out`` and ``var_plus_out`` receive
    each series' variances for the FFT pass.
    """
    m, c, d = y.shape
    out = np.empty(m)
    xc = np.empty((c, d))
    acc0 = np.empty(c)
    empty = np.empty(0)
    for s in range(m):
        lo = y[s, 0, 0]
        hi = lo
        bad = False
        for ch in range(c):
            for i in range(d):
                v = y[s, ch, i]
                if np.isnan(v):
                    bad = True
                lo = min(lo, v)
                hi = max(hi, v)
        if bad:
            out[s] = np.nan
            continue
        if hi - lo < _RESOLUTION:
            out[s] = c * d
            continue
        means = chain_means[s]
        for ch in range(c):
            a = 0.0
            for i in range(d):
                xc[ch, i] = y[s, ch, i] - means[ch]
                a += xc[ch, i] * xc[ch, i]
            acc0[ch] = a / d
        mean_var = _pairwise_sum(acc0, 0, c) / c * d / (d - 1.0)
        var_plus = mean_var * (d - 1.0) / d
        if c > 1:
            var_plus += _var_seq(means, 1)
        mean_var_out[s] = mean_var
        var_plus_out[s] = var_plus
        out[s] = _geyer(xc, empty, mean_var, var_plus, max_lag)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _ess_from_acov(mean_acov, chains, draws, mean_var, var_plus, out):  # pragma: no cover
    """ESS of each series from its chain-mean autocovariances (k, lags).

    -1.0 where the Geyer sequence runs past the lags given.
    """
    k = mean_acov.shape[0]
    xc = np.empty((chains, draws))
    for s in range(k):
        out[s] = _geyer(xc, mean_acov[s], mean_var[s], var_plus[s], draws)


def _ess(y: np.ndarray) -> np.ndarray:
    """ESS of each series of ``y`` shaped (m, chains, draws), as ArviZ's ``_ess``."""
    y = np.ascontiguousarray(y, dtype=float)
    m, c, d = y.shape
    mean_var = np.zeros(m)
    var_plus = np.zeros(m)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = _ess_direct(y, y.mean(axis=2), DIRECT_LAGS, mean_var, var_plus)
        for s in np.flatnonzero(out == -1.0):
            out[s] = ess_fft(y[s : s + 1], mean_var[s : s + 1], var_plus[s : s + 1])[0]
    return out


def ess_fft(y: np.ndarray, mean_var: np.ndarray, var_plus: np.ndarray) -> np.ndarray:
    """ESS of series ``y`` (k, chains, draws) from FFT autocovariances (no lag limit).

    ``mean_var``, ``var_plus`` as :func:`_ess_direct` gives them. First the lags up to a
    quarter of the draws (a shorter transform: a third of the cost), then, for the series
    whose Geyer sequence runs further, every lag. Rows are independent: a batch gives
    each series the same bits as alone.
    """
    k, c, d = y.shape
    xc = y - y.mean(axis=2, keepdims=True)
    out = np.full(k, -1.0)
    short = d // 4
    if short >= 2 * DIRECT_LAGS:
        _ess_from_acov(fft_mean_acov(xc, short), c, d, mean_var, var_plus, out)
    redo = np.flatnonzero(out == -1.0)
    if redo.size:
        res = np.empty(redo.size)
        _ess_from_acov(fft_mean_acov(xc[redo], d), c, d, mean_var[redo], var_plus[redo], res)
        out[redo] = res
    return out


def fft_mean_acov(xc: np.ndarray, lags: int) -> np.ndarray:
    """Autocovariances of lags ``0 .. lags - 1``, averaged over chains, of centred ``xc``.

    ``xc`` (k, c, d). ArviZ's ``_autocov`` per chain is ``irfft(|rfft(x)|^2)[:d] / d`` of
    the draws padded to ``next_fast_len(2 d)``; padding to ``d + lags`` is enough for
    the first ``lags`` lags (no wrap-around), and the mean over chains is taken of the
    power spectra before the one inverse transform (linear). The same numbers to
    rounding (1e-16 of the lag-0 autocovariance).
    """
    from scipy.fft import next_fast_len

    d = xc.shape[2]
    n_fft = next_fast_len(2 * d if lags >= d else d + lags)
    f = np.fft.rfft(xc, n=n_fft, axis=2)
    power = f.real**2 + f.imag**2
    return np.ascontiguousarray(np.fft.irfft(power.mean(axis=1), n=n_fft, axis=1)[:, :lags] / d)


def _hdi_sorted(s: np.ndarray, prob: float) -> tuple[np.ndarray, np.ndarray]:
    """``arviz.hdi(..., multimodal=False)`` of each sorted row of ``s``."""
    n = s.shape[1]
    inc = int(np.floor(prob * n))
    width = np.subtract(s[:, inc:], s[:, : n - inc], dtype=np.float64)
    i = np.argmin(width, axis=1)
    rows = np.arange(s.shape[0])
    return s[rows, i], s[rows, i + inc]


def hdi(x: np.ndarray, prob: float = 0.95) -> tuple[float, float]:
    """``arviz.hdi(x, hdi_prob=prob)`` of all of ``x`` (one interval), without ArviZ."""
    lo, hi = _hdi_sorted(np.sort(np.asarray(x, dtype=float).reshape(1, -1), axis=1), prob)
    return float(lo[0]), float(hi[0])


def _quantile7(s: np.ndarray, p: float) -> np.ndarray:
    """ArviZ's type-7 quantile (``mquantiles(alphap=1, betap=1)``) of sorted rows."""
    n = s.shape[1]
    m = 1.0 + p * (1.0 - 1.0 - 1.0)
    aleph = n * p + m
    k = int(np.floor(np.clip(aleph, 1, n - 1)))
    gamma = float(np.clip(aleph - k, 0, 1))
    return (1.0 - gamma) * s[:, k - 1] + gamma * s[:, k]


def _z_ranked(values: np.ndarray, order: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Rank-normalised z-scores of each row (m, n), given its order and sorted values."""
    n = values.shape[1]
    ties = bool((s[:, 1:] == s[:, :-1]).any())
    half = _scores(n, True) if ties else np.empty(0)
    return _z_scores(values, order, _scores(n, False), half)


def summarize(
    draws: np.ndarray, *, hdi_prob: float = 0.95, tail: bool = True
) -> dict[str, np.ndarray]:
    """Mean, sd, HDI, MCSE, bulk and tail ESS and R-hat of many series, as ``az.summary``.

    Parameters
    ----------
    draws : ndarray, shape (m, chain, draw)
        ``m`` independent series (the parameters of a fit, a parameter of ``m`` buses).
    hdi_prob : float
        Probability of the highest-density interval.
    tail : bool
        Also ``ess_tail``, ``mcse_mean`` and ``mcse_sd`` (three more ESS per series);
        ``False`` gives only ``mean, sd, hdi_low, hdi_high, r_hat, ess_bulk``.

    Returns
    -------
    dict of str to ndarray, shape (m,)
        ``mean, sd, hdi_low, hdi_high, mcse_mean, mcse_sd, ess_bulk, ess_tail, r_hat``
        (the last five NaN for a series with a NaN or fewer than 4 draws; R-hat NaN with
        one chain).
    """
    x = np.ascontiguousarray(draws, dtype=float)
    if x.ndim != 3:
        raise ValueError(f"draws must be shaped (series, chain, draw); got {x.shape}")
    from loadbayes.core.parallel import num_threads, run_threads

    m = x.shape[0]
    groups = min(num_threads(), m, max(1, x.size // _MIN_DRAWS_PER_THREAD))
    if groups <= 1:
        return _summarize(x, hdi_prob, tail)
    # The series are independent: a share of them per thread (the sorts and the
    # compiled kernels release the GIL); the result is the same as in one thread.
    bounds = np.linspace(0, m, groups + 1).astype(int)
    parts: list[dict[str, np.ndarray]] = [{} for _ in range(groups)]

    def task(i: int):
        def run() -> None:
            parts[i] = _summarize(x[bounds[i] : bounds[i + 1]], hdi_prob, tail)

        return run

    run_threads([task(i) for i in range(groups)])
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _summarize(x: np.ndarray, hdi_prob: float, tail: bool) -> dict[str, np.ndarray]:
    m, c, d = x.shape
    flat = x.reshape(m, c * d)
    out: dict[str, np.ndarray] = {
        "mean": x.mean(axis=(1, 2)),
        "sd": x.std(axis=(1, 2), ddof=1),
    }
    half = d // 2
    split = np.concatenate([x[:, :, :half], x[:, :, d - half :]], axis=1)
    sflat = split.reshape(m, -1)
    keys = ("mcse_mean", "mcse_sd", "ess_bulk", "ess_tail", "r_hat") if tail else ()
    keys = keys or ("ess_bulk", "r_hat")
    diag = {k: np.full(m, np.nan) for k in keys}
    if d < 4:
        out["hdi_low"], out["hdi_high"] = _hdi_sorted(np.sort(flat, axis=1), hdi_prob)
        return {**out, **diag}
    order = np.argsort(sflat, axis=1)
    s_split = np.take_along_axis(sflat, order, axis=1)
    z = _z_ranked(sflat, order, s_split)
    s_all = s_split if 2 * half == d else np.sort(flat, axis=1)
    out["hdi_low"], out["hdi_high"] = _hdi_sorted(s_all, hdi_prob)
    ok = ~np.isnan(flat).any(axis=1)
    if not ok.all():
        # ArviZ: a series with a NaN has no diagnostics; the others are computed alone.
        if ok.any():
            part = _summarize(np.ascontiguousarray(x[ok]), hdi_prob, tail)
            for k in keys:
                diag[k][ok] = part[k]
        return {**out, **diag}
    with np.errstate(divide="ignore", invalid="ignore"):
        diag["ess_bulk"] = _ess(z.reshape(split.shape))
        if c >= 2:
            if 2 * half == d:  # the median from the sorted draws, as np.median
                k = sflat.shape[1] // 2
                med = (s_split[:, k - 1] + s_split[:, k]) / 2
            else:
                med = np.median(flat, axis=1)
            folded = np.abs(split - med[:, None, None]).reshape(m, -1)
            forder = _fold_order(s_split, order, med)
            fsorted = np.take_along_axis(folded, forder, axis=1)
            zf = _z_ranked(folded, forder, fsorted)
            z3, zf3 = z.reshape(split.shape), zf.reshape(split.shape)
            bulk = _rhat(z3, z3.mean(axis=2))
            fold = _rhat(zf3, zf3.mean(axis=2))
            # Python's max(bulk, fold), as ArviZ (NaN first wins, NaN second loses)
            diag["r_hat"] = np.where(fold > bulk, fold, bulk)
        if tail:
            q05, q95 = _quantile7(s_all, 0.05), _quantile7(s_all, 0.95)
            e05 = _ess((split <= q05[:, None, None]).astype(float))
            e95 = _ess((split <= q95[:, None, None]).astype(float))
            diag["ess_tail"] = np.where(e95 < e05, e95, e05)  # Python's min, as ArviZ
            centred = (x - x.mean(axis=(1, 2), keepdims=True)) ** 2
            sq = centred.reshape(m, -1)
            total = sq.sum(axis=1)
            ess_mean = _ess(split)
            diag["mcse_mean"] = np.sqrt(total / (sq.shape[1] - 1) / ess_mean)
            evar = total / sq.shape[1]
            half_sq = np.concatenate([centred[:, :, :half], centred[:, :, d - half :]], axis=1)
            varvar = ((sq**2).mean(axis=1) - evar**2) / _ess(half_sq)
            diag["mcse_sd"] = np.sqrt(varvar / evar / 4)
    return {**out, **diag}
