"""The composite fit's phasor window: samples read as window means, or as points (0)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.problem import CompositeProblem, theta_of
from loadbayes.fit.composite.provenance import problem_settings
from loadbayes.fit.composite.sums import design_sums
from loadbayes.inference.condlinear import GroupSums, log_marginal
from loadbayes.models.composite import SCALE_FREE_MATRIX
from loadbayes.models.composite_prior import POSITIVE_BETA, CompositePrior
from loadbayes.models.motor_kernel import integrate, step_size
from loadbayes.models.motor_library import MOTORS

TAU = np.array([9000.0, 11000.0])


@pytest.fixture(scope="module")
def event():
    # A 40% sag whose fall lies inside a 60/s interval: one step, with its virtual knots.
    return simulate_event("krause_3hp", depth=0.4, seed=3, t_end_s=1.2, start_s=0.5071)[0]


def _u(name="krause_3hp"):
    m = MOTORS[name]
    u = (SCALE_FREE_MATRIX @ np.log([m.rs, m.xp, m.x - m.xp, m.tp_s, m.h_s, 0.6]))[:5]
    return u


def _by_hand(prob, u, window):
    # The collapsed density from the public kernel: integrate() on the augmented input,
    # the real samples' P, Q (points, or window means), the design's sums, the marginal.
    rs, xp, dx, tp, h, t0 = np.exp(theta_of(u[:5], 0.0))
    aug, real = prob.grid.motor_input(0, prob.grid.times(prob.phi(u)))
    kw = dict(rs=rs, xp=xp, dx=dx, tp_s=tp, h_s=h, t0=t0, h_max=step_size(tp, prob.h_max))
    if window > 0:
        pm, qm, _ = integrate(aug.t, aug.v, aug.delta, window_s=window, real=real, **kw)
    else:
        p, q, _ = integrate(aug.t, aug.v, aug.delta, **kw)
        pm, qm = p[real], q[real]
    ev = prob.events[0]
    ztz, zty, yty = design_sums(ev.x, pm, qm, ev.p, ev.q)
    g = GroupSums(ztz, zty, yty, np.array([ev.n, ev.n], dtype=float))
    return prob.prior.log_u(u[:5]) + log_marginal(g, TAU, prob.m0, prob.p0, positive=POSITIVE_BETA)


def test_window_zero_is_the_point_likelihood_to_the_bit(event):
    prob = CompositeProblem([event], CompositePrior.default([event]), window_s=0)
    u = np.r_[_u(), 0.3]
    lp, _ = prob.collapsed(u, TAU)
    assert lp == _by_hand(prob, u, 0.0)
    # The edges are found with the window as before: 0 s allows two intervals at most.
    assert prob.n_steps == 1


def test_the_default_reads_one_cycle_window_means(event):
    point = CompositeProblem([event], CompositePrior.default([event]), window_s=0)
    prob = CompositeProblem([event], CompositePrior.default([event]))
    assert prob.window == pytest.approx(1 / 60)
    u = np.r_[_u(), 0.3]
    lp, sums = prob.collapsed(u, TAU)
    assert lp == pytest.approx(_by_hand(prob, u, 1 / 60), rel=1e-12, abs=1e-9)
    assert lp == pytest.approx(prob.log_collapsed(prob.sums(u), u, TAU), rel=1e-10)
    # The check can fail: on point data the window means fit worse than the points.
    assert point.collapsed(u, TAU)[0] - lp > 1.0
    # The motor's response differs near the step, not on the flat stretches.
    (pw, _), (pp, _) = prob.responses(u)[0], point.responses(u)[0]
    assert np.max(np.abs(pw - pp)) > 1e-3
    assert np.max(np.abs(pw[:20] - pp[:20])) < 1e-9


def test_the_settings_say_how_samples_were_read(event):
    prior = CompositePrior.default([event])
    point = problem_settings(CompositeProblem([event], prior, window_s=0), (1.0, 0.0, 0.0))
    assert point["samples"] == {
        "window_s": 0.0,
        "read_as": "point samples (the motor's P and Q at the sample instants)",
    }
    wide = problem_settings(CompositeProblem([event], prior, window_s=0.02), (1.0, 0.0, 0.0))
    assert wide["samples"]["window_s"] == 0.02
    assert "0.02-s window means centred on the stamp" in wide["samples"]["read_as"]
    assert math.isclose(wide["steps"]["window_s"], 0.02)
