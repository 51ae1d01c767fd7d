"""The fleet's bulk summary (loadbayes.core.bulk_summary) against the general path and ArviZ.

Draws are made here: autocorrelated chains from weak to a random walk (the FFT path),
chains that disagree, rounded draws with ties, Metropolis-like repeats, a constant
series, tau-like large values and float32-stored draws. The compiled pass must give the
general path's numbers to the last bit, and ArviZ's (``az.rhat``, ``az.ess``,
``az.hdi``) to 1e-10 relative.
"""

import warnings

import numpy as np
import pytest

from loadbayes.core import bulk_summary, convergence
from loadbayes.core.bulk_summary import applies, summarize_bulk
from loadbayes.posterior import import_arviz

KEYS = ("mean", "sd", "hdi_low", "hdi_high", "ess_bulk", "r_hat")


def _series(seed=0, chains=4, draws=600):
    rng = np.random.default_rng(seed)
    m = 12
    phi = np.linspace(0.0, 0.98, m)
    e = rng.standard_normal((m, chains, draws))
    x = np.empty_like(e)
    x[..., 0] = e[..., 0]
    for i in range(1, draws):
        x[..., i] = phi[:, None] * x[..., i - 1] + e[..., i]
    x[1] = np.cumsum(e[1], axis=1)  # a random walk: the Geyer sequence needs the FFT
    x[2] += np.arange(chains)[:, None] * 0.5  # chains that disagree
    x[3] = np.round(x[3], 1)  # ties
    x[4] = np.repeat(e[4][:, : draws // 6], 6, axis=1)  # Metropolis-like repeats
    x[5] = 2.5  # constant
    x[6] = 39_500 + 1_500 * e[6]  # tau-like: large values keep their digits
    x[7] = x[7].astype(np.float32)  # the fleet stores draws as float32
    return np.ascontiguousarray(x)


def _general(x, hdi_prob):
    # the general path (the one the single fits use), bypassing the compiled pass
    out = convergence._summarize(x, hdi_prob, True)
    return {k: out[k] for k in KEYS}


@pytest.mark.parametrize(("chains", "draws", "hdi_prob"), [(4, 600, 0.95), (2, 96, 0.9)])
def test_same_bits_as_the_general_path(chains, draws, hdi_prob, monkeypatch):
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "2")
    x = _series(chains=chains, draws=draws)
    assert applies(x)
    got = summarize_bulk(x, hdi_prob)
    want = _general(x, hdi_prob)
    for k in KEYS:
        assert np.array_equal(got[k], want[k], equal_nan=True), k
    # and the fleet's entry point, in two threads
    pub = bulk_summary.summarize(np.repeat(x, 30, axis=0), hdi_prob=hdi_prob)
    want = {k: np.repeat(v, 30) for k, v in want.items()}
    for k in KEYS:
        assert np.array_equal(pub[k], want[k], equal_nan=True), k


def test_agrees_with_arviz_rhat_ess_and_hdi():
    az = import_arviz()
    x = _series(seed=1)
    got = summarize_bulk(x, 0.95)
    for j, s in enumerate(x):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = float(az.rhat(s))  # split chains' median = all draws' median (even draws)
            e = float(az.ess(s, method="bulk"))
            lo, hi = az.hdi(s.ravel(), hdi_prob=0.95)
        if np.isnan(r):
            assert np.isnan(got["r_hat"][j]), j
        else:
            assert abs(got["r_hat"][j] - r) <= 1e-10 * abs(r), (j, got["r_hat"][j], r)
        assert abs(got["ess_bulk"][j] - e) <= 1e-10 * abs(e), (j, got["ess_bulk"][j], e)
        assert (got["hdi_low"][j], got["hdi_high"][j]) == (lo, hi), j


def test_a_wrong_answer_would_be_caught():
    # Other draws (one chain's halves swapped) give another R-hat: the check can fail.
    x = _series(seed=2)
    y = x.copy()
    y[2, 0] = np.concatenate([x[2, 0, 300:], x[2, 0, :300]]) + 1.0
    assert not np.array_equal(summarize_bulk(y, 0.95)["r_hat"], _general(x, 0.95)["r_hat"])


@pytest.mark.parametrize(
    "x",
    [np.ones((1, 4, 7)), np.ones((1, 1, 8)), np.ones((1, 4, 2)), np.array([[[np.nan] * 4] * 2])],
)
def test_odd_short_single_chain_or_nan_draws_take_the_general_path(x):
    assert not applies(x)
    got = bulk_summary.summarize(x)
    want = convergence.summarize(x, tail=False)
    for k in KEYS:
        assert np.array_equal(got[k], want[k], equal_nan=True), k


def test_shapes_far_from_the_buckets_are_still_sorted():
    # The bucket sort assumes a roughly normal posterior; far from it (two tight modes
    # far apart, a heavy tail, a spike with outliers) it must still sort exactly (by its
    # insertion pass, or numpy's sort after too many moves).
    rng = np.random.default_rng(9)
    e = rng.standard_normal((4, 4, 500))
    x = np.empty_like(e)
    x[0] = np.where(e[0] > 0, 1e6, 0.0) + 1e-3 * rng.standard_normal((4, 500))
    x[1] = rng.standard_cauchy((4, 500))
    x[2] = np.where(np.abs(e[2]) > 2.5, 1e9 * e[2], 1e-9 * e[2])
    x[3] = np.exp(8 * e[3])
    got = summarize_bulk(x, 0.95)
    want = _general(x, 0.95)
    for k in KEYS:
        assert np.array_equal(got[k], want[k], equal_nan=True), k
    order = np.empty(2000, np.int64)
    srt = np.empty(2000)
    keys = np.empty(2000, np.int64)
    starts = np.empty(bulk_summary._BUCKETS * 2000 + 1, np.int64)
    for s in x:
        v = s.reshape(-1).copy()
        bulk_summary._bucket_sort(v, order, srt, keys, starts)
        assert np.array_equal(srt, np.sort(v)) and np.array_equal(v[order], srt)
