"""The uniform refresh of bounded coordinates (inference.moves.refresh) on known targets.

Seeds are fixed, so each test is deterministic; the tolerances are what a correct move
passes with the stated false-alarm rate were the seed drawn at random.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from loadbayes.inference.moves.base import BlockState
from loadbayes.inference.moves.refresh import UniformRefresh

MINOR, LOC_MAJOR, LOC_MINOR, SD = 0.05, 0.26, 0.66, 0.05


def _log_mix(x: float) -> float:
    """A bimodal density on [0, 1]: 0.95 N(0.26, 0.05) + 0.05 N(0.66, 0.05), truncated."""
    if not 0.0 <= x <= 1.0:
        return -math.inf
    a = math.log(1 - MINOR) - 0.5 * ((x - LOC_MAJOR) / SD) ** 2
    b = math.log(MINOR) - 0.5 * ((x - LOC_MINOR) / SD) ** 2
    return float(np.logaddexp(a, b))


def _cdf(x):
    def part(loc):
        d = stats.norm(loc, SD)
        return (d.cdf(np.clip(x, 0, 1)) - d.cdf(0)) / (d.cdf(1) - d.cdf(0))

    return (1 - MINOR) * part(LOC_MAJOR) + MINOR * part(LOC_MINOR)


def test_refresh_alone_draws_a_bimodal_coordinate_with_its_minor_mode_weighed_right():
    """A chain of refreshes only (share 1), on the second coordinate of a 2-vector, started
    in the minor mode: its draws follow the target (KS on the draws thinned to 1 in 20,
    about independent at an acceptance near 0.25: p > 0.001, a false alarm of 0.1%), the
    minor mode holds its 5% (binomial sd of 2,000 thinned draws: 0.5%; 4 sds allowed), and
    the other coordinate never moves."""
    rng = np.random.default_rng(3)
    move = UniformRefresh([1], share=1.0)

    def logp(x):
        return _log_mix(float(x[1])), "aux"

    state = BlockState(np.array([7.0, LOC_MINOR]), _log_mix(LOC_MINOR), None)
    out = []
    for _ in range(40_000):
        state = move.step(state, logp, rng)
        out.append(state.x.copy())
    x = np.array(out)
    assert np.all(x[:, 0] == 7.0)
    kept = x[::20, 1]
    assert stats.kstest(kept, _cdf).pvalue > 1e-3
    assert abs(np.mean(kept > 0.46) - MINOR) < 4 * math.sqrt(MINOR * (1 - MINOR) / kept.size)
    assert 0.15 < move.acceptance < 0.4
    assert state.aux == "aux"  # what travels with the state comes from logp


def test_refresh_with_share_zero_draws_no_random_numbers_and_never_evaluates():
    """share 0 leaves the generator's stream as it was (runs without steps keep their
    draws)."""
    rng, twin = np.random.default_rng(1), np.random.default_rng(1)
    move = UniformRefresh([0, 1], share=0.0)

    def logp(x):
        raise AssertionError("evaluated")

    state = BlockState(np.zeros(2), 0.0, None)
    assert move.step(state, logp, rng) is state
    assert rng.uniform() == twin.uniform()
    assert move.acceptance is None


def test_refresh_takes_about_its_share_of_iterations_and_proposes_inside_the_support():
    """share 0.1 over 20,000 iterations: 2,000 steps expected (binomial sd 42; 5 sds
    allowed), every proposal inside [low, high], each coordinate picked about evenly."""
    rng = np.random.default_rng(5)
    move = UniformRefresh([0, 2], low=-2.0, high=3.0, share=0.1)
    seen = []

    def logp(x):
        seen.append(x.copy())
        return 0.0, None

    state = BlockState(np.array([0.5, 9.0, 0.5]), 0.0, None)
    for _ in range(20_000):
        state = move.step(state, logp, rng)
    seen = np.array(seen)
    assert abs(move.steps - 2000) < 5 * 42
    assert np.all((seen[:, [0, 2]] >= -2.0) & (seen[:, [0, 2]] <= 3.0))
    assert np.all(seen[:, 1] == 9.0)
    changed0 = np.sum(np.diff(seen[:, 0]) != 0)
    changed2 = np.sum(np.diff(seen[:, 2]) != 0)
    assert abs(changed0 - changed2) < 0.2 * (changed0 + changed2)


@pytest.mark.parametrize(("share", "low", "high"), [(-0.1, 0, 1), (1.5, 0, 1), (0.5, 1, 1)])
def test_refresh_refuses_a_share_outside_0_1_and_an_empty_support(share, low, high):
    with pytest.raises(ValueError):
        UniformRefresh([0], low=low, high=high, share=share)
