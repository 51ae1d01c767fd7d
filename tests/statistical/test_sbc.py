"""Simulation-based calibration (Talts et al. 2018) of every sampler in the registry.

Each sampler under test (``loadbayes.studies.calibration.registry.REGISTRY``: ZIP blocked,
single-site, exact, blocked with the conjugate prior, unknown nominal power; the motor's
three blocks in both forms and every scheme; the Student-t sampler with nu fixed and
sampled; the online tracker, exact, windowed and with drift) is run on 200 data sets
simulated from its prior, with fixed seeds (the composite sampler, whose fit costs 20
times more, on 50). The rank of each true parameter among the kept posterior draws is
binned in 20 bins (10 for the composite at 50, so that 5 ranks fall in a bin) and tested
for uniformity (chi-square). ``make validate`` (LOADBAYES_VALIDATE=1) runs this file at
500 (the composite at 100), the counts of ``make test`` until 30 Nov 2026, and
``studies/calibration/run.py`` runs every sampler at 1000 with other seeds.

False-alarm rate (how often a *correct* sampler would fail over random seeds; the seeds
are fixed, so a run is deterministic): each sampler fails when any of its parameters has
a p-value below 1e-3 / (number of parameters) (Bonferroni), i.e. at most 1e-3 per
sampler and 1.5% for the 15 samplers. The thinning guard (median lag-1 autocorrelation of
the kept draws below 0.1, measured 0.00-0.04) has no false alarms at these settings.
The chi-square tail is the multinomial's only approximately: simulated with uniform
ranks, a parameter fails 1.2e-4 of the time at 100 ranks in 20 bins and 1.7e-4 at 50 in 10
(nominal 7e-5 for 14 parameters), so the composite's rate is at most 2.3e-3.

Power (the fixed seeds make each run one draw; simulated, normal posteriors, a parameter
failing alone): a sampler whose draws sit 0.5 posterior sd off the truth fails with
probability 0.88 at 200 replications (1.00 at 500; at 0.3 sd 0.10, against 0.79 at 500);
draws 30% too narrow, 0.85 (1.00 at 500). The composite at 50 replications and 10 bins
sees a 1 sd bias with probability 0.94 and draws half as wide as they should be with 0.60
(at 100: 1.00 and 0.99), a 0.5 sd bias hardly (0.08; 0.23 at 100): in ``make test`` it
guards against gross errors and a chain that does not mix; its calibration is
``make validate``'s. The wrong-sign bugs below are seen with p below 1e-8 (asserted) at
100 replications (200 under ``make validate``; the motor's coupled sampler at 50). Measured
at 100 (30 Nov 2026): the data-term bugs' smallest p underflows to 0, the prior-term bugs'
is 2.7e-27 (ZIP blocked), 3.3e-17 (exact), 5.1e-25 (Student-t) and 2.6e-16 (online): eight
orders of magnitude inside the bound (at 200: 1.9e-42, 2.2e-35, 3.6e-46, 4.1e-33).

A sampler given a wrong sign in one term of its coefficient conditional (injected here
only, by monkeypatching the kernel's entry point) must fail the same check: the data
term ``(Z'r)_2`` or the prior term ``(m0)_2`` of ``h = P0 m0 + tau Z'r``. (On the
single-site design the data dominate the prior, so SBC cannot see the prior-term bug
there; the Geweke test catches it.)
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

import loadbayes.inference.bilinear as bilinear
import loadbayes.inference.linear as linear
import loadbayes.inference.online as online
import loadbayes.inference.robust as robust
from loadbayes.core.stats import RegressionStats
from loadbayes.studies.calibration.registry import REGISTRY
from loadbayes.testing.sbc import run_sbc

pytestmark = pytest.mark.statistical

ALPHA = 1e-3  # per sampler
#: ``make validate`` (LOADBAYES_VALIDATE=1): the counts of ``make test`` until 30 Nov 2026.
FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"
REPLICATIONS = 500 if FULL else 200
SEED = 20_180_406  # Talts et al., arXiv v1
#: Replications of the wrong-sign tests (module docstring: the p-values at each count).
BUG_REPLICATIONS = 200 if FULL else 100


def _count_and_bins(name: str) -> tuple[int, int]:
    """Replications, and the most bins of at most 20 that divide the ranks' range and
    keep 5 ranks a bin expected (the chi-square's usual rule)."""
    ci = REGISTRY[name].ci_replications  # an expensive fit's count in CI (composite: 50)
    count = (2 * ci if FULL else ci) if ci else REPLICATIONS
    ranks = REGISTRY[name].kept + 1
    bins = max(b for b in range(1, 21) if ranks % b == 0 and count >= 5 * b)
    return count, bins


def test_counts_and_bins():
    assert _count_and_bins("zip-blocked") == (REPLICATIONS, 20)
    assert _count_and_bins("composite-mwg") == (100, 20) if FULL else (50, 10)


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_ranks_of_the_truth_are_uniform(name):
    count, bins = _count_and_bins(name)
    res = run_sbc(REGISTRY[name], count, seed=SEED, bins=bins)
    pvalues = res.pvalues()
    assert res.passes(ALPHA), (name, pvalues)
    lag1 = np.median(res.lag1, axis=0)
    assert np.all(lag1 < 0.1), dict(zip(res.parameters, lag1.round(3), strict=True))


# ---------------------------------------------------------------- broken conditionals
def _flip(x: np.ndarray, j: int) -> np.ndarray:
    out = np.array(x, dtype=float, copy=True)
    out[j] = -out[j]
    return out


def _wrong_data_term(stats: RegressionStats) -> RegressionStats:
    """The data term of the second coefficient's conditional mean with its sign flipped:
    ``h = P0 m0 + tau Z'r`` computed with ``-(Z'r)_2``."""
    j = min(1, stats.k - 1)
    return RegressionStats(stats.ztz, _flip(stats.ztr, j), stats.rtr, stats.n)


def _wrong_prior_term(prior):
    """The prior term of the second coefficient's conditional mean with its sign flipped:
    ``h = P0 m0 + tau Z'r`` computed with ``-(m0)_2``."""
    return dataclasses.replace(prior, mean=_flip(prior.mean, min(1, prior.k - 1)))


def _broken_sample_block(bug):
    real = linear.sample_block

    def sample_block(stats, prior, **kw):
        if bug == "data":
            stats = _wrong_data_term(stats)
        else:
            prior = _wrong_prior_term(prior)
        return real(stats, prior, **kw)

    return sample_block


def _broken_sample_bilinear():
    """The motor's coupled sampler with the sign of ``sum yed ed`` (the data term of b1's
    conditional mean, and of the flux residual sum of squares) flipped."""
    real = bilinear.sample_bilinear

    def sample_bilinear(stats, *args, **kw):
        h = stats.h.copy()
        i = 3  # monomial b1 * 1 in phi = kron([1, b1, b2, b3], [1, ab, ac])
        h[0, 0, i], h[0, i, 0] = -h[0, 0, i], -h[0, i, 0]
        return real(dataclasses.replace(stats, h=h), *args, **kw)

    return sample_bilinear


@pytest.mark.parametrize(
    ("name", "bug"),
    [
        ("zip-blocked", "data"),
        ("zip-single-site", "data"),
        ("zip-exact", "data"),
        ("zip-blocked", "prior"),
        ("zip-exact", "prior"),
        ("im-measured-blocked", "data"),
        ("im-measured-single-site", "data"),
    ],
)
def test_a_wrong_sign_in_one_term_is_detected(name, bug, monkeypatch):
    monkeypatch.setattr(linear, "sample_block", _broken_sample_block(bug))
    res = run_sbc(REGISTRY[name], BUG_REPLICATIONS, seed=SEED)
    assert not res.passes(ALPHA), res.pvalues()
    assert min(res.pvalues().values()) < 1e-8  # not a near miss


@pytest.mark.parametrize("name", ["im-modelled-blocked", "im-modelled-single-site"])
def test_a_wrong_sign_in_the_coupled_motor_sampler_is_detected(name, monkeypatch):
    monkeypatch.setattr(bilinear, "sample_bilinear", _broken_sample_bilinear())
    res = run_sbc(REGISTRY[name], 50, seed=SEED)
    assert not res.passes(ALPHA), res.pvalues()
    assert min(res.pvalues().values()) < 1e-8


def _wrong_online_prior(prior):
    return dataclasses.replace(prior, mean=_flip(prior.mean, 1))


@pytest.mark.parametrize("name", ["robust-nu4", "online-exact"])
def test_a_wrong_sign_in_the_robust_and_online_priors_is_detected(name, monkeypatch):
    if name.startswith("robust"):
        real = robust.sample_student_t

        def sample_student_t(z, r, prior, **kw):
            return real(z, r, _wrong_prior_term(prior), **kw)

        monkeypatch.setattr(robust, "sample_student_t", sample_student_t)
    else:
        real = online.track

        def track(z, r, *, prior, **kw):
            return real(z, r, prior=_wrong_online_prior(prior), **kw)

        monkeypatch.setattr(online, "track", track)
    res = run_sbc(REGISTRY[name], BUG_REPLICATIONS, seed=SEED)
    assert not res.passes(ALPHA), res.pvalues()
    assert min(res.pvalues().values()) < 1e-8
