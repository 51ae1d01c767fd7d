"""The composite sampler's speed-ups keep its answers: sums, step rule, seeds.

The slice move on a correlated Gaussian is checked with every move in ``test_moves.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.nls import nls
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.sampler import MOVES, sample
from loadbayes.fit.composite.sums import design_sums
from loadbayes.fit.composite.sums import weighted_sums as _weighted_sums
from loadbayes.models.composite_prior import CompositePrior
from loadbayes.models.motor_kernel import H_MAX_S, TP_STEPS, step_size


def test_compact_design_sums_equal_the_direct_ones():
    rng = np.random.default_rng(3)
    n = 500
    x = 1.0 - 0.3 * rng.uniform(size=n)
    pm, qm = 0.6 + 0.1 * rng.normal(size=n), 0.4 + 0.1 * rng.normal(size=n)
    p, q = rng.normal(size=n), rng.normal(size=n)
    # The direct sums: every sample's 7 x 7 outer product (the Student-t kernel's, unit
    # weights).
    ones = np.ones_like(x)
    direct = _weighted_sums(x, pm, qm, p, q, ones, ones)
    pairs = zip(design_sums(x, pm, qm, p, q), direct, strict=True)
    for fast, direct in pairs:
        np.testing.assert_allclose(fast, direct, rtol=1e-12, atol=1e-12 * np.abs(direct).max())


def test_step_rule_caps_the_step_at_a_fraction_of_t_prime():
    assert step_size(1.0, H_MAX_S) == H_MAX_S
    assert step_size(0.087, H_MAX_S) == pytest.approx(0.087 / TP_STEPS)


@pytest.mark.parametrize("move", sorted(MOVES))
def test_same_seed_same_draws_whatever_the_workers(move):
    ev, _ = simulate_event("small_industrial", depth=0.4, noise=0.01, seed=2, t_end_s=1.5)
    prob = CompositeProblem([ev], CompositePrior.default([ev]), window_s=0)
    start = nls(prob)
    kw = {"start": start, "draws": 30, "burn": 10, "chains": 3, "seed": 9, "move": move}
    a = sample(prob, workers=1, **kw)
    b = sample(prob, workers=3, **kw)
    for ra, rb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ra.theta, rb.theta)
        np.testing.assert_array_equal(ra.beta, rb.beta)
        np.testing.assert_array_equal(ra.tau, rb.tau)
    # And the chains differ from one another (the seeds are really per chain).
    assert not np.array_equal(a[0].theta, a[1].theta)
    assert math.isfinite(a[0].acceptance)


def test_unknown_move_is_refused():
    ev, _ = simulate_event("small_industrial", depth=0.4, seed=2, t_end_s=1.5)
    prob = CompositeProblem([ev], CompositePrior.default([ev]), window_s=0)
    with pytest.raises(ValueError, match="move must be one of"):
        sample(prob, start=nls(prob), draws=10, burn=2, move="hmc")
