"""Student-t noise of the composite fit: the weighted collapsed density, the default path."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.nls import nls
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.robust import StudentT, collapsed_weighted
from loadbayes.fit.composite.sampler import sample
from loadbayes.inference.condlinear import GroupSums, log_marginal
from loadbayes.inference.student_weights import draw_weights
from loadbayes.models.composite import design
from loadbayes.models.composite_prior import POSITIVE_BETA as _POS
from loadbayes.models.composite_prior import CompositePrior


def _problem():
    ev, _ = simulate_event("small_industrial", depth=0.3, noise=0.01, seed=3, t_end_s=1.5, fs=30.0)
    return CompositeProblem([ev], CompositePrior.default([ev]), window_s=0)


def test_weighted_collapsed_density_equals_a_direct_computation():
    pb = _problem()
    ev = pb.events[0]
    rng = np.random.default_rng(0)
    u = pb.prior.scale_free()[0] + 0.1 * rng.standard_normal(5)
    tau = np.array([900.0, 2500.0])
    lam = rng.gamma(2.0, 0.5, size=(2, ev.n))
    lp, sums = collapsed_weighted(pb, u, tau, lam)
    # Direct: the Gaussian evidence of the rows scaled by sqrt(lambda), plus the
    # log-determinant of the weights, with the design built by models.composite.design.
    pm, qm = pb.responses(u)[0]
    zp, zq = design(ev, pm, qm)
    s = np.sqrt(lam)
    direct = GroupSums.from_arrays(
        [s[0, :, None] * zp, s[1, :, None] * zq], [s[0] * ev.p, s[1] * ev.q]
    )
    want = pb.prior.log_u(u) + log_marginal(direct, tau, pb.m0, pb.p0, positive=_POS)
    want += 0.5 * np.log(lam).sum()
    # The two sum in different orders, and the log evidence is ill-conditioned in Z'Z
    # (x^2, x and 1 are nearly collinear over a sag): measured 4.5e-7 apart on ~173.
    # A wrong weight, a missing log-determinant or a wrong design is off by O(1).
    assert lp == pytest.approx(want, abs=1e-5)
    # Weight 1 is the Gaussian kernel (its compact sums, the same to rounding).
    ones = collapsed_weighted(pb, u, tau, np.ones((2, ev.n)))[0]
    assert ones == pytest.approx(pb.collapsed(u, tau)[0], abs=1e-5)


def test_the_gaussian_default_draws_no_weights_and_is_reproducible():
    # (When the option was added the default's draws were checked against numbers
    # recorded before it; the model has changed since: steps between samples.)
    pb = _problem()
    start = nls(pb)
    r = sample(pb, start=start, draws=40, burn=10, chains=1, seed=7)[0]
    r2 = sample(pb, start=start, draws=40, burn=10, chains=1, seed=7, student_t=None)[0]
    np.testing.assert_array_equal(r.theta, r2.theta)
    assert r.nu is None and r.weight is None


def test_student_t_chains_are_reproducible_and_record_nu_and_weights():
    pb = _problem()
    st = nls(pb)
    a = sample(pb, start=st, draws=30, burn=10, chains=1, seed=3, student_t=StudentT())[0]
    b = sample(pb, start=st, draws=30, burn=10, chains=1, seed=3, student_t=StudentT())[0]
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.nu, b.nu)
    assert a.nu.shape == (20, 2) and a.weight.shape == (2, pb.events[0].n)
    fixed = sample(pb, start=st, draws=30, burn=10, chains=1, seed=3, student_t=StudentT(nu=4))
    assert np.all(fixed[0].nu == 4.0) and fixed[0].nu_acceptance is None
    with pytest.raises(ValueError, match="nu"):
        StudentT(nu=-1.0)


def test_weights_have_the_gamma_conditional_mean():
    rng = np.random.default_rng(1)
    e2 = np.full(20000, 4.0)
    lam, mean = draw_weights(e2, 1.0, 3.0, rng)
    assert mean[0] == pytest.approx(4.0 / 7.0)
    # sd of the mean of 20000 Gamma(2, 2/7) draws is ~0.0029; 5 sd: false alarm ~6e-7.
    assert lam.mean() == pytest.approx(4.0 / 7.0, abs=5 * lam.std() / np.sqrt(e2.size))
