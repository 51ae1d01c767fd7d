"""Geweke's joint-distribution ("getting it right") test of the Gibbs kernels.

The marginal-conditional simulator (100,000 independent prior draws and data sets) and the
successive-conditional one (4 chains alternating one kernel sweep with a fresh data set)
must agree on the mean of every test function: first and second moments of a1, a2, tau,
``log tau``, and the cross moments ``a_j (Z'r)_j / n`` and ``tau SSR / n`` that tie the
draw to the data it was drawn from. Design: 20 voltages on 0.4-1.6 p.u., noise sd near
0.5, so the data weigh about as much as the prior and the chain crosses the prior fast.

False-alarm rate: each kernel fails when some |z| exceeds the two-sided Bonferroni
threshold for 1e-3 over its 11 functions (|z| > 3.91); 1e-3 per kernel. The z-scores use
the successive-conditional standard error from its effective sample size (ArviZ, over
the 4 chains). The sweep-from-a-state check allows 5 standard errors on a mean (6e-7) and
3.5 sd on a variance ratio (3e-4). About 3e-3 for the file.

A kernel handed a wrong sign in one term of the coefficient conditional (the data term
``(Z'r)_2`` or the prior term ``(m0)_2``) must fail the same check.

Hook: ``sample_block`` cannot start from a given state yet; until it takes
``init=(coef, tau)``, ``loadbayes.testing.geweke`` supplies the state by standing in
for ``loadbayes.inference.gibbs._initial`` (see ``sweep_from``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from loadbayes.core.stats import RegressionStats
from loadbayes.testing.geweke import (
    GEWEKE_PRIOR,
    _state_init,
    gibbs_kernel,
    run_geweke,
    sweep_from,
    zip_design,
)

pytestmark = pytest.mark.statistical

ALPHA = 1e-3
DESIGN = zip_design()


@pytest.mark.parametrize(("scheme", "steps"), [("blocked", 3000), ("single-site", 5000)])
def test_the_gibbs_kernel_gets_it_right(scheme, steps):
    res = run_geweke(
        gibbs_kernel(scheme), GEWEKE_PRIOR, DESIGN, steps=steps, seed=2004, alpha=ALPHA
    )
    zs = {k: round(v["z"], 2) for k, v in res.table.items()}
    assert res.passes(), (res.threshold, zs)


def _flip(x, j=1):
    out = np.array(x, dtype=float, copy=True)
    out[j] = -out[j]
    return out


def _broken(scheme, bug):
    kernel = gibbs_kernel(scheme)

    def broken(stats, prior, coef, tau, seed):
        if bug == "data":
            stats = RegressionStats(stats.ztz, _flip(stats.ztr), stats.rtr, stats.n)
        else:
            prior = dataclasses.replace(prior, mean=_flip(prior.mean))
        return kernel(stats, prior, coef, tau, seed)

    return broken


@pytest.mark.parametrize("scheme", ["blocked", "single-site"])
@pytest.mark.parametrize("bug", ["data", "prior"])
def test_a_wrong_sign_in_one_term_is_detected(scheme, bug):
    res = run_geweke(_broken(scheme, bug), GEWEKE_PRIOR, DESIGN, steps=300, seed=2004, alpha=ALPHA)
    assert not res.passes()
    assert res.max_abs_z > 2 * res.threshold  # not a near miss


@pytest.mark.parametrize("scheme", ["blocked", "single-site"])
def test_a_sweep_starts_from_the_given_state(scheme):
    # One sweep from (coef, tau): a1' ~ N(mean, var) of its conditional given tau (and,
    # single-site, given a2). A sweep that ignored the state would centre elsewhere.
    rng = np.random.default_rng(1)
    z = DESIGN
    r = z @ np.array([0.5, -0.2]) + 0.3 * rng.standard_normal(z.shape[0])
    stats = RegressionStats(z.T @ z, z.T @ r, float(r @ r), z.shape[0])
    coef, tau = np.array([3.0, -4.0]), 50.0
    p = GEWEKE_PRIOR
    if scheme == "blocked":
        lam = p.precision + tau * stats.ztz
        cov = np.linalg.inv(lam)
        mean = cov @ (p.precision @ p.mean + tau * stats.ztr)
        m1, v1 = mean[0], cov[0, 0]
    else:
        lam = p.precision + tau * stats.ztz
        m1 = (p.precision[0] @ p.mean + tau * stats.ztr[0] - lam[0, 1] * coef[1]) / lam[0, 0]
        v1 = 1.0 / lam[0, 0]
    with _state_init():
        a1 = np.array(
            [sweep_from(stats, p, coef, tau, scheme=scheme, seed=s)[0][0] for s in range(400)]
        )
    assert abs(a1.mean() - m1) < 5 * np.sqrt(v1 / a1.size)
    assert 0.75 < a1.var(ddof=1) / v1 < 1.3  # 3.5 and 4.2 sd of the ratio
