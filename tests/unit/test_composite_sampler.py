"""The sampler's parts on targets with known answers: linear block, chain seeds.

The moves (adaptive Metropolis and the others) are checked in ``test_moves.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from loadbayes.core.parallel import chain_generators, run_chains
from loadbayes.inference.condlinear import GroupSums, draw_beta, log_marginal


def _problem(seed=0, k=3):
    rng = np.random.default_rng(seed)
    zs = [rng.normal(size=(30, k)), rng.normal(size=(25, k))]
    beta = np.array([0.5, -1.0, 0.3])[:k]
    ys = [zs[0] @ beta + 0.5 * rng.normal(size=30), zs[1] @ beta + 0.2 * rng.normal(size=25)]
    return GroupSums.from_arrays(zs, ys), zs, ys


def test_log_marginal_is_the_gaussian_evidence():
    sums, zs, ys = _problem()
    tau, m0, p0 = np.array([4.0, 25.0]), np.array([0.1, 0.0, -0.2]), np.array([0.5, 2.0, 1.0])
    # y ~ N(Z m0, Z P0^-1 Z' + diag(1/tau)) stacked over groups.
    z = np.vstack(zs)
    y = np.concatenate(ys)
    noise = np.concatenate([np.full(30, 1 / tau[0]), np.full(25, 1 / tau[1])])
    cov = z @ np.diag(1 / p0) @ z.T + np.diag(noise)
    want = stats.multivariate_normal(z @ m0, cov).logpdf(y)
    assert log_marginal(sums, tau, m0, p0) == pytest.approx(want, rel=1e-10)


def test_truncated_log_marginal_and_draws_in_one_dimension():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(8, 1))
    y = z[:, 0] * 0.05 + rng.normal(size=8)  # the data put mass near zero
    sums = GroupSums.from_arrays([z], [y])
    tau, m0, p0 = np.array([1.0]), np.zeros(1), np.array([0.25])

    def joint(b):  # likelihood x the prior truncated to b > 0 (normalised)
        lik = stats.norm(z[:, 0] * b, 1.0).logpdf(y).sum()
        return math.exp(lik) * 2 * stats.norm(0, 2).pdf(b)

    evidence = integrate.quad(joint, 0, np.inf)[0]
    assert log_marginal(sums, tau, m0, p0, positive=0) == pytest.approx(
        math.log(evidence), rel=1e-8
    )
    draws = np.array([draw_beta(sums, tau, m0, p0, rng, positive=0)[0] for _ in range(4000)])
    assert draws.min() > 0
    mean = integrate.quad(lambda b: b * joint(b), 0, np.inf)[0] / evidence
    # 4000 draws: the sd of the mean is ~0.015; 5 sd, false alarm ~6e-7.
    assert draws.mean() == pytest.approx(mean, abs=5 * draws.std() / math.sqrt(4000))


def test_chains_are_reproducible_whatever_the_workers():
    def chain(i, rng):
        return rng.standard_normal(3)

    a = run_chains(chain, chain_generators(11, 4), workers=1)
    b = run_chains(chain, chain_generators(11, 4), workers=3)
    np.testing.assert_array_equal(np.array(a), np.array(b))
