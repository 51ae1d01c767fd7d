"""Estimated torque shares: the prior in log-ratio coordinates, the base symmetry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.torque import TorqueProblem, log_prior_z, shares
from loadbayes.models.composite import SCALE_FREE_MATRIX, design, motor_response
from loadbayes.models.composite_prior import CompositePrior
from loadbayes.models.motor_library import MOTORS


def _theta(name, t0=0.6):
    m = MOTORS[name]
    return np.log([m.rs, m.xp, m.x - m.xp, m.tp_s, m.h_s, t0])


def test_log_ratio_prior_is_the_dirichlet_with_its_jacobian():
    rng = np.random.default_rng(0)
    for z in rng.normal(scale=2.0, size=(5, 2)):
        s = np.array(shares(z))
        assert s.sum() == pytest.approx(1.0) and np.all(s > 0)
        assert math.log(s[0] / s[2]) == pytest.approx(z[0])
        # density of z = Dirichlet(s) |ds/dz|, and |ds/dz| = s_A s_B s_C for the ALR map.
        want = stats.dirichlet([1.0, 1.0, 1.0]).logpdf(s) + np.log(s).sum()
        assert log_prior_z(z) + math.log(2.0) == pytest.approx(want, rel=1e-10)


def test_base_symmetry_holds_for_a_general_torque():
    ev, _ = simulate_event("small_industrial", depth=0.35, noise=0.0)
    th = _theta("small_industrial")
    k = np.log(2.7)
    th2 = th + np.array([k, k, k, 0.0, -k, -k])
    tq = (0.2, 0.3, 0.5)
    p1, q1 = motor_response(ev, th, torque=tq)
    p2, q2 = motor_response(ev, th2, torque=tq)
    np.testing.assert_allclose(p1, 2.7 * p2, rtol=1e-9)
    np.testing.assert_allclose(q1, 2.7 * q2, rtol=1e-9)
    z1, z2 = design(ev, p1, q1), design(ev, p2, q2)
    np.testing.assert_allclose(z1[0], z2[0], rtol=1e-9, atol=1e-12)
    # and the shares matter: a constant-torque load answers the sag differently.
    p3, _ = motor_response(ev, th, torque=(0.0, 0.0, 1.0))
    assert np.max(np.abs(p3 / p3[0] - p1 / p1[0])) > 1e-3


def test_torque_problem_is_the_fixed_problem_at_its_shares_plus_the_prior():
    ev, _ = simulate_event("small_industrial", depth=0.35, noise=0.01, t_end_s=1.5, fs=30.0)
    prior = CompositePrior.default([ev])
    u5 = (SCALE_FREE_MATRIX @ _theta("small_industrial"))[:5]
    z = np.array([-0.7, 0.4])
    tau = np.array([1e3, 2e3])
    lp, sums = TorqueProblem([ev], prior, window_s=0).collapsed(np.concatenate([u5, z]), tau)
    fixed = CompositeProblem([ev], prior, torque=shares(z), window_s=0)
    assert lp == pytest.approx(fixed.collapsed(u5, tau)[0] + log_prior_z(z), rel=1e-12)
    np.testing.assert_allclose(sums[0].ztz, fixed.sums(u5)[0].ztz, rtol=1e-12)


def test_student_t_weights_and_estimated_shares_combine():
    from loadbayes.fit.composite.robust import collapsed_weighted

    ev, _ = simulate_event("small_industrial", depth=0.35, noise=0.01, t_end_s=1.5, fs=30.0)
    pb = TorqueProblem([ev], CompositePrior.default([ev]))
    motor = (SCALE_FREE_MATRIX @ _theta("small_industrial"))[:5]
    u = np.concatenate([motor, np.full(pb.n_steps, 0.5), [0.3, -1.0]])
    tau = np.array([1e3, 2e3])
    lp = collapsed_weighted(pb, u, tau, np.ones((2, ev.n)))[0]
    assert lp == pytest.approx(pb.collapsed(u, tau)[0], rel=1e-12)
