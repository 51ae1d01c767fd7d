"""A plain zip+motor chain run compiled gives the Python iteration's draws, bit for bit.

fit/composite/chain_loop.py compiles the whole iteration of a plain chain (the u-move, the
steps' refresh, the coefficients, tau, log T0); chain_fast.py drives it and does in
Python what the Python path does once (the shear's switch, the covariance's refresh, the
jumps' fit). Each test runs the same sampler twice, compiled and not, and asks for the
same arrays and the same statistics: any difference in an arithmetic step or in the
order of the random draws shows as a different draw within a few iterations. A
deterministic comparison: no false alarms.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

import loadbayes.fit.composite.chain_fast as fast
import loadbayes.fit.composite.sampler as sampler_module
from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.bounded import share_start
from loadbayes.fit.composite.driver import _append_start
from loadbayes.fit.composite.nls import nls
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.ridge import cached_ridge_points
from loadbayes.fit.composite.sampler import sample
from loadbayes.models.composite_prior import CompositePrior


@pytest.fixture(scope="module")
def fitted():
    # Two events with a step at each edge: the refresh picks among four fractions.
    evs = [simulate_event("small_industrial", depth=d, t_end_s=1.2, fs=60.0, seed=s)[0]
           for d, s in ((0.3, 3), (0.2, 4))]  # fmt: skip
    prob = CompositeProblem(evs, CompositePrior.default(evs), window_s=0)
    assert prob.n_steps >= 2
    start = nls(prob)
    cached_ridge_points(prob, start)  # its profile's evaluations once, before the runs
    return prob, start


def _both(monkeypatch, prob, start, **kw):
    out = []
    for compiled in (False, True):
        monkeypatch.setattr(fast, "COMPILED", compiled)
        prob.evaluations = 0
        runs = sample(prob, start=start, **kw)
        out.append((runs, prob.evaluations))
    return out


def _same(a, b):
    (ra, ea), (rb, eb) = a, b
    assert ea == eb  # the kernel calls, one by one
    for x, y in zip(ra, rb, strict=True):
        for name in ("theta", "beta", "tau", "phi"):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name), err_msg=name)
        assert (x.acceptance, x.jump_acceptance, x.evaluations_per_iteration) == (
            y.acceptance,
            y.jump_acceptance,
            y.evaluations_per_iteration,
        )


def test_shear_with_its_switch_jumps_and_refresh_gives_the_same_draws(monkeypatch, fitted):
    # A burn-in of 2,000: the shear is learned at 1,000 from 500 draws, the jumps' mixture
    # is fitted to the chains' late burn-in; then kept draws with jumps and refreshes.
    prob, start = fitted
    a, b = _both(monkeypatch, prob, start, draws=2_400, burn=2_000, chains=2, seed=7,
                 move="shear", workers=1)  # fmt: skip
    assert a[0][0].jump_acceptance is not None  # the jumps ran
    _same(a, b)


def test_adaptive_metropolis_thinned_in_threads_gives_the_same_draws(monkeypatch, fitted):
    prob, start = fitted
    a, b = _both(monkeypatch, prob, start, draws=700, burn=400, thin=3, chains=2, seed=3,
                 move="am", workers=2)  # fmt: skip
    _same(a, b)


def test_ar1_noise_gives_the_same_draws(monkeypatch, fitted):
    # AR(1) noise: rho drawn each iteration after beta, the sums whitened for it.
    prob, start = fitted
    a, b = _both(monkeypatch, prob, start, draws=1_500, burn=1_100, chains=2, seed=5,
                 move="shear", ar=True, workers=1)  # fmt: skip
    _same(a, b)
    for x, y in zip(a[0], b[0], strict=True):
        np.testing.assert_array_equal(x.rho, y.rho)
    assert np.ptp(a[0][0].rho[:, 0]) > 0  # rho moved


def test_bounded_shares_give_the_same_draws(monkeypatch):
    # Bounded shares: the shares' own steps each iteration, the coefficients drawn in the
    # quadrant, the jumps refitted to the kept u before each round run on.
    evs = [simulate_event("small_industrial", depth=0.3, t_end_s=1.2, fs=60.0, seed=3)[0]]
    prior = CompositePrior.default(evs)
    free = CompositeProblem(evs, prior, window_s=0)
    prob = CompositeProblem(evs, prior, window_s=0, bounded=True)
    fit = nls(free)
    start = _append_start(fit, share_start(fit.betas), sd=0.5)  # as the driver starts it
    rounds = iter([400, 0, 400, 0])

    def extend(_):
        return next(rounds)

    a, b = _both(monkeypatch, prob, start, draws=1_300, burn=1_100, chains=2, seed=6,
                 move="shear", workers=1, extend=extend)  # fmt: skip
    _same(a, b)
    for x, y in zip(a[0], b[0], strict=True):
        np.testing.assert_array_equal(x.u_extra, y.u_extra)
    assert a[0][0].theta.shape[0] == 600  # the round ran


def test_a_jump_that_is_not_a_mixture_runs_the_python_iteration(monkeypatch, fitted):
    # One t instead of the mixture (JUMP_COMPONENTS = 1): the compiled loop hands the
    # rest of the batch to the Python iteration, with the same draws.
    prob, start = fitted
    monkeypatch.setattr(sampler_module, "JUMP_COMPONENTS", 1)
    a, b = _both(monkeypatch, prob, start, draws=1_300, burn=1_100, chains=2, seed=1,
                 move="am", workers=1)  # fmt: skip
    assert a[0][0].jump_acceptance is not None
    _same(a, b)


def test_a_passed_deadline_ends_the_burn_in_and_keeps_the_least_draws(monkeypatch, fitted):
    prob, start = fitted
    monkeypatch.setattr(fast, "COMPILED", True)
    runs = sample(prob, start=start, draws=5_000, burn=2_000, chains=2, seed=2,
                  deadline=time.perf_counter() - 1.0)  # fmt: skip
    for r in runs:
        assert r.cut > 0
        assert sampler_module.MIN_KEPT <= r.theta.shape[0] < 3_000
        assert np.all(np.isfinite(r.theta))
