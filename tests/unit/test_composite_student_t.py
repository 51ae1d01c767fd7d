"""Student-t noise of the composite fit: the weighted collapsed density, the default path."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite_problem import _POS, CompositePrior, CompositeProblem, nls, sample
from loadbayes.fit.composite_robust import StudentT, collapsed_weighted
from loadbayes.inference.condlinear import GroupSums, log_marginal
from loadbayes.inference.student_weights import draw_weights
from loadbayes.models.composite import design


def _problem():
    ev, _ = simulate_event("small_industrial", depth=0.3, noise=0.01, seed=3, t_end_s=1.5, fs=30.0)
    return CompositeProblem([ev], CompositePrior.default([ev]))


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
    assert lp == pytest.approx(want, rel=1e-10, abs=1e-8)
    # Weight 1 is the Gaussian kernel exactly.
    ones = collapsed_weighted(pb, u, tau, np.ones((2, ev.n)))[0]
    assert ones == pytest.approx(pb.collapsed(u, tau)[0], rel=1e-12)


def test_the_gaussian_default_gives_the_same_draws_as_before_the_option():
    pb = _problem()
    r = sample(pb, start=nls(pb), draws=40, burn=10, chains=1, seed=7)[0]
    # Recorded on this machine's code before the Student-t option existed (same seed).
    theta = [-3.097196111958896, -1.4790041876865387, 1.4329214642330554,
             -0.33045710717020493, -0.4712006066901743, -0.16866416980871704]  # fmt: skip
    np.testing.assert_allclose(r.theta[-1], theta, rtol=1e-9)
    np.testing.assert_allclose(r.tau[-1], [6157.124207377139, 10656.557315057842], rtol=1e-9)
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
