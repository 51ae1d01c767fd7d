"""Every block move of :data:`loadbayes.inference.moves.MOVES` on targets with known answers.

As emcee tests its moves (``tests/integration/test_proposal.py``): one helper runs a move
alone on a log-density, and each test is parametrised over the registry, so a new move
is checked by adding it to ``MOVES`` (and its run length to ``GAUSSIAN``).

Seeds are fixed, so each test is deterministic; the tolerances are what a correct move
passes with the stated false-alarm rate were the seed drawn at random.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from loadbayes.core.parallel import chain_generators, run_chains
from loadbayes.inference.moves import MOVES, BlockMove


def run_move(move_cls, logp, x0, *, cov0, burn, draws, seed, chains=2):
    """Run ``chains`` chains of one move alone on ``logp``, adapting for ``burn`` iterations.

    Returns the kept draws, shaped (chains, draws - burn, d), and each chain's move.
    """

    def chain(i, rng):
        move = move_cls(cov0, adapt_until=burn)
        x = np.array(x0, dtype=float)
        lp = logp(x)[0]
        out = []
        for it in range(draws):
            x, lp, _, _ = move.step(x, lp, logp, rng, it)
            if it >= burn:
                out.append(x)
        return np.array(out), move

    res = run_chains(chain, chain_generators(seed, chains), workers=1)
    return np.stack([r[0] for r in res]), [r[1] for r in res]


# ------------------------------------------------------------- correlated Gaussian
COV = np.array([[1.0, 0.95, 0.0], [0.95, 1.0, 0.3], [0.0, 0.3, 2.0]])
MEAN = np.array([1.0, -2.0, 0.5])
PREC = np.linalg.inv(COV)

#: Per move: run length and seed, the tolerances its effective sample size allows, the
#: acceptance range (open) and the density evaluations per step (closed).
GAUSSIAN = {
    # 40,000 correlated draws (ESS ~ 4000): 0.15 in the mean is > 5 Monte Carlo sds.
    "am": {
        "burn": 3000,
        "draws": 23000,
        "seed": 7,
        "mean_atol": 0.15,
        "cov_atol": 0.2,
        "acceptance": (0.15, 0.4),
        "evaluations": (1, 1),
    },
    # 8,000 draws, ESS ~ 5,000 (measured; slice sweeps are nearly independent here): 0.1
    # in the mean is > 5 Monte Carlo sds (false alarm < 1e-6), 0.15 in the covariance
    # too. Stepping out and shrinkage cost a few evaluations per direction, not dozens.
    "slice": {
        "burn": 500,
        "draws": 4500,
        "seed": 5,
        "mean_atol": 0.1,
        "cov_atol": 0.15,
        "acceptance": (0.99, 1.01),  # a slice update always moves
        "evaluations": (3, 8 * 3),
    },
}


def test_every_move_is_a_block_move_with_a_gaussian_run_length():
    assert set(GAUSSIAN) == set(MOVES)
    for cls in MOVES.values():
        assert issubclass(cls, BlockMove)


def _gaussian(v):
    d = v - MEAN
    return -0.5 * float(d @ PREC @ d), None


@pytest.mark.parametrize("name", sorted(MOVES))
def test_move_finds_a_correlated_gaussian(name):
    s = GAUSSIAN[name]
    x, moves = run_move(
        MOVES[name], _gaussian, np.zeros(3), cov0=np.eye(3), burn=s["burn"],
        draws=s["draws"], seed=s["seed"],
    )  # fmt: skip
    x = x.reshape(-1, 3)
    np.testing.assert_allclose(x.mean(0), MEAN, atol=s["mean_atol"])
    np.testing.assert_allclose(np.cov(x.T), COV, atol=s["cov_atol"])
    lo, hi = s["acceptance"]
    assert all(lo < m.acceptance < hi for m in moves)
    lo, hi = s["evaluations"]
    assert all(lo <= m.evaluations_per_step <= hi for m in moves)


# ------------------------------------------------------------------ bounded target
BETA = stats.beta(2, 5)


def _box(v):
    """Beta(2, 5) x Uniform(0, 1): a density on [0, 1]^2, as the step fractions live on."""
    if not (0.0 < v[0] < 1.0 and 0.0 <= v[1] <= 1.0):
        return -math.inf, None
    return math.log(v[0]) + 4.0 * math.log1p(-v[0]), None


@pytest.mark.parametrize("name", sorted(MOVES))
def test_move_stays_in_a_bounded_support_and_finds_its_marginals(name):
    x, moves = run_move(
        MOVES[name], _box, [0.5, 0.5], cov0=0.05 * np.eye(2), burn=1000, draws=11000, seed=3
    )
    # A proposal outside the support is never accepted.
    assert np.all((x > 0.0) & (x < 1.0))
    # 20,000 draws; every move must reach an ESS of 1,000 here (measured on seeds 0-3:
    # adaptive Metropolis ~1,900, slice ~15,000). At ESS 1,000 the tolerances are 5
    # Monte Carlo sds (false alarm ~6e-7 each): the mean's sd is sd / sqrt(1000), 0.005
    # (beta) and 0.009 (uniform); the sample sd's about 0.0035 and 0.0041.
    flat = x.reshape(-1, 2)
    assert flat[:, 0].mean() == pytest.approx(BETA.mean(), abs=0.025)
    assert flat[:, 1].mean() == pytest.approx(0.5, abs=0.046)
    assert flat[:, 0].std() == pytest.approx(BETA.std(), abs=0.02)
    assert flat[:, 1].std() == pytest.approx(math.sqrt(1 / 12), abs=0.02)
    assert all(0.1 < m.acceptance <= 1.0 and m.evaluations_per_step >= 1 for m in moves)
    # One-dimensional KS tests on the draws thinned by 20: 1,000 nearly independent
    # draws (lag-20 autocorrelation below 0.05 for both moves, measured on seeds 0-3).
    # For independent draws the p-value is uniform: p > 1e-3 is a false alarm rate of
    # 1e-3 per test.
    thinned = x[:, ::20]
    assert stats.kstest(thinned[..., 0].ravel(), BETA.cdf).pvalue > 1e-3
    assert stats.kstest(thinned[..., 1].ravel(), "uniform").pvalue > 1e-3
