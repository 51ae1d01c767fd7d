"""The compiled summary (loadbayes.core.convergence) against ``arviz.summary`` itself.

Draws are made here (random normals, random walks, Metropolis-like repeats, rounded
draws with ties, constant, NaN, short and odd-length chains), not by the package. Every
column must agree to 1e-8 relative (the module's claim; it is 1e-12 or better in
practice); a NaN must be a NaN where ArviZ has one.
"""

import warnings

import numpy as np
import pytest

from loadbayes.core.convergence import DIRECT_LAGS, summarize
from loadbayes.posterior import Posterior, import_arviz

COLUMNS = ("mean", "sd", "hdi_low", "hdi_high", "mcse_mean", "mcse_sd")
COLUMNS += ("ess_bulk", "ess_tail", "r_hat")


def _arviz_rows(x, hdi_prob):
    az = import_arviz()
    rows = []
    for series in x:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            df = az.summary({"v": series}, hdi_prob=hdi_prob, round_to="none")
        rows.append(df.iloc[0].to_numpy(dtype=float))
    return np.array(rows)


def _agree(x, hdi_prob=0.95):
    got = summarize(x, hdi_prob=hdi_prob)
    want = _arviz_rows(x, hdi_prob)
    for j, col in enumerate(COLUMNS):
        a, b = got[col], want[:, j]
        assert np.array_equal(np.isnan(a), np.isnan(b)), (col, a, b)
        ok = ~np.isnan(b)
        np.testing.assert_allclose(a[ok], b[ok], rtol=1e-8, atol=0, err_msg=col)


def _rng(seed):
    return np.random.default_rng(seed)


def test_random_autocorrelated_and_disagreeing_chains():
    x = _rng(1).standard_normal((3, 4, 400))
    x[1] = np.cumsum(x[1], axis=1) * 0.1 + x[1]
    x[2] += np.arange(4)[:, None] * 0.3
    _agree(x, hdi_prob=0.9)


@pytest.mark.parametrize(
    "shape", [(2, 4, 401), (2, 1, 50), (2, 3, 3), (2, 3, 4), (1, 2, 5), (2, 8, 64)]
)
def test_shapes_short_odd_and_single_chains(shape):
    _agree(_rng(sum(shape)).standard_normal(shape) * 3 + 7)


def test_random_walk_needs_every_lag():
    # The Geyer sequence runs past the directly summed lags: the FFT path is taken.
    x = np.cumsum(_rng(2).standard_normal((2, 4, 3000)), axis=2)
    _agree(x)
    assert DIRECT_LAGS < 3000 // 2


def test_ties_and_repeated_metropolis_draws():
    rounded = np.round(_rng(3).standard_normal((2, 4, 300)), 1)  # many ties
    _agree(rounded)
    repeats = np.repeat(_rng(4).standard_normal((2, 4, 50)), 7, axis=2)  # rejections
    _agree(repeats)


def test_constant_and_nan_series():
    x = _rng(5).standard_normal((3, 4, 100))
    x[0] = 2.5  # constant: ESS is the number of draws, R-hat NaN as ArviZ
    x[1, 2, 7] = np.nan  # a NaN: every diagnostic NaN, the other series unaffected
    _agree(x)
    s = summarize(x)
    assert np.isnan(s["r_hat"][1]) and np.isfinite(s["r_hat"][2])


def test_large_offset_values_keep_their_digits():
    # tau-like draws (mean 4e4, sd 1.5e3): ArviZ's E[x^2] - E[x]^2 variance is reproduced.
    x = _rng(6).standard_normal((2, 4, 2000)) * 1500 + 39500
    _agree(x)


def test_posterior_summary_is_arviz_summary():
    rng = _rng(7)
    post = Posterior(
        {"a": rng.standard_normal((4, 500)), "tau": rng.gamma(3.0, 2.0, (4, 500))},
        model="zip",
        method="test",
    )
    got = post.summary(hdi_prob=0.9)
    az = import_arviz()
    want = az.summary(post.draws, hdi_prob=0.9, round_to="none")
    assert list(got.index) == ["a", "tau"]
    np.testing.assert_allclose(got.to_numpy(), want.to_numpy(), rtol=1e-8, atol=0)
    # mean, sd, HDI and R-hat are ArviZ's to the last bit
    for j in (0, 1, 2, 3, 8):
        assert np.array_equal(got.to_numpy()[:, j], want.to_numpy()[:, j])


def test_a_wrong_formula_would_be_caught():
    # The comparison can fail: a summary of other draws does not pass it.
    x = _rng(8).standard_normal((1, 4, 200))
    got = summarize(x * 1.001)
    want = _arviz_rows(x, 0.95)
    assert not np.allclose(got["sd"], want[:, 1], rtol=1e-8, atol=0)


def test_threads_change_nothing(monkeypatch):
    x = _rng(9).standard_normal((5, 4, 20_000))
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "1")
    one = summarize(x)
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "2")
    two = summarize(x)
    for key in COLUMNS:
        assert np.array_equal(one[key], two[key]), key
