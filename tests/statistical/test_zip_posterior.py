"""Statistical checks of the ZIP samplers against known answers.

False-alarm rates (each check, fixed seeds, so a run is deterministic; the rates say how
often a *correct* sampler would fail such a check over random seeds):
- mean / sd within 4 Monte Carlo standard errors: 6e-5 per comparison;
- Kolmogorov-Smirnov at alpha = 1e-3 on draws thinned to near independence: 1e-3 per test;
- 99.9% interval covering the truth: 1e-3 per parameter.
About 40 comparisons in this file: overall false-alarm rate below 1%.
"""

import numpy as np
import pytest
from scipy import stats

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.core.stats import RegressionStats
from loadbayes.fit import fit_zip
from loadbayes.inference.gibbs import exact_posterior, sample_block
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.statistical


def _data(n, a=(0.25, 0.25, 0.5), noise=0.1, lo=0.66, hi=0.89, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.uniform(lo, hi, n)
    p = a[0] * v**2 + a[1] * v + a[2] + rng.normal(0, noise, n)
    return v, p


def _stats(v, p):
    z = np.column_stack([v**2 - 1, v - 1])
    r = p - 1
    return RegressionStats(z.T @ z, z.T @ r, float(r @ r), v.size)


def _thin_to_independent(x):
    post = Posterior({"x": x}, model="t", method="t")
    ess = post.summary().loc["x", "ess_bulk"]
    step = max(int(np.ceil(x.size / ess)), 1)
    return x[:, ::step].reshape(-1)


@pytest.mark.parametrize(
    ("scheme", "lo", "hi", "draws"),
    [
        ("blocked", 0.66, 0.89, 20_000),
        ("single-site", 0.3, 1.7, 40_000),
        ("exact", 0.66, 0.89, 20_000),
    ],
)
def test_gibbs_matches_the_exact_normal_gamma_posterior(scheme, lo, hi, draws):
    v, p = _data(300, lo=lo, hi=hi, seed=11)
    st = _stats(v, p)
    prior = BlockPrior(mean=[0.2, 0.1], precision=[4.0, 1.0], shape=2.0, rate=0.02, conjugate=True)
    ex = exact_posterior(st, prior)
    res = sample_block(
        st,
        prior,
        scheme=scheme,
        settings=SamplerSettings(chains=4, draws=draws, burn=1000, seed=2024),
    )
    cov = np.linalg.inv(ex["precision"]) * ex["rate"] / ex["shape"]
    dof = 2 * ex["shape"]
    for j in range(2):
        x = res.coef[..., j]
        post = Posterior({"x": x}, model="t", method="t")
        s = post.summary().loc["x"]
        exact_mean = ex["mean"][j]
        exact_sd = np.sqrt(cov[j, j] * dof / (dof - 2))
        assert abs(s["mean"] - exact_mean) < 4 * s["mcse_mean"]
        assert abs(s["sd"] - exact_sd) < 4 * s["mcse_sd"]
        marginal = stats.t(df=dof, loc=exact_mean, scale=np.sqrt(cov[j, j]))
        assert stats.kstest(_thin_to_independent(x), marginal.cdf).pvalue > 1e-3
    tau = _thin_to_independent(res.tau)
    assert stats.kstest(tau, stats.gamma(ex["shape"], scale=1 / ex["rate"]).cdf).pvalue > 1e-3


def test_weak_prior_mean_agrees_with_least_squares():
    v, p = _data(1000, seed=3)
    post = fit_zip(
        {"v": v, "p": p},
        sampler=SamplerSettings(draws=20_000, burn=2000, seed=7),
        spec=DataSpec(p0=1.0, q0=1.0),
    )
    s = post.summary()
    z = np.column_stack([v**2 - 1, v - 1])
    ls = np.linalg.lstsq(z, p - 1, rcond=None)[0]
    for name, val in zip(("a1", "a2"), ls, strict=True):
        # prior shrinkage (sd 10 against a posterior sd ~0.3) is far below MC error
        assert abs(s.loc[name, "mean"] - val) < 4 * s.loc[name, "mcse_mean"]


@pytest.mark.parametrize(
    "truth",
    [(0.25, 0.25, 0.5), (1.6, -1.2, 0.6), (-0.4, 1.1, 0.3)],
)
def test_known_coefficients_are_recovered(truth):
    # Negative shares occur in measured appliances (e.g. constant-power electronics).
    v, p = _data(4000, a=truth, noise=0.02, lo=0.85, hi=1.1, seed=5)
    rng = np.random.default_rng(8)
    q = truth[2] * v**2 + truth[0] * v + truth[1] + rng.normal(0, 0.02, v.size)
    post = fit_zip(
        {"v": v, "p": p, "q": q},
        sampler=SamplerSettings(draws=6000, burn=1000, seed=1),
        spec=DataSpec(p0=1.0, q0=1.0),
    )
    s = post.summary(hdi_prob=0.999)
    names = ("a1", "a2", "a3", "a4", "a5", "a6")
    expected = dict(zip(names, truth + (truth[2], truth[0], truth[1]), strict=True))
    for name, val in expected.items():
        assert s.loc[name, "hdi_low"] <= val <= s.loc[name, "hdi_high"], name
    assert (s["r_hat"] < 1.01).all()


def test_blocked_mixes_on_the_ridge_single_site_does_not():
    v, p = _data(1000, seed=1)
    kw = dict(sampler=SamplerSettings(draws=40_000, burn=5000, chains=4, seed=0))
    blocked = fit_zip(
        {"v": v, "p": p}, scheme="blocked", **kw, spec=DataSpec(p0=1.0, q0=1.0)
    ).summary()
    single = fit_zip(
        {"v": v, "p": p}, scheme="single-site", **kw, spec=DataSpec(p0=1.0, q0=1.0)
    ).summary()
    kept = 4 * 35_000
    assert blocked.loc["a1", "ess_bulk"] > 0.5 * kept
    assert single.loc["a1", "ess_bulk"] < 0.05 * kept
