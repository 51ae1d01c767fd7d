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

from jump_chains import run_jumping
from loadbayes.core.parallel import chain_generators, run_chains
from loadbayes.inference.moves import MOVES, BlockMove, BlockState


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
            (x, lp, _), _ = move.step(BlockState(x, lp), logp, rng, it)
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
    # The same as adaptive Metropolis: on a Gaussian the bend explains nothing (R^2 under
    # MIN_R2), so after mid burn-in it is AM in standardised coordinates.
    "shear": {
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


# ------------------------------------------------------------------ a bent ridge
B, SD = 0.5, 0.3


def _banana(v):
    """y1 ~ N(0, 1), y2 | y1 ~ N(y1 + B (y1^2 - 1), SD^2), y3 ~ N(0, 1): a bent ridge."""
    r = v[1] - v[0] - B * (v[0] ** 2 - 1.0)
    return -0.5 * (v[0] ** 2 + (r / SD) ** 2 + v[2] ** 2), None


def test_the_sheared_move_learns_a_bent_ridge_and_keeps_its_marginals():
    """The shear learned at mid burn-in is a bijection of unit Jacobian, so the draws keep
    the target: y1 N(0, 1), E y2 = 0, sd y2 = sqrt(1 + 2 B^2 + SD^2) = 1.261, y3 N(0, 1).
    Bulk ESS of y1 from 2 x 20,000 draws is 616-1,185 on seeds 1-3 (measured), so the
    tolerances are 5 Monte Carlo sds at ESS 600: 0.2 in the means, 15% in the sds (the
    sd estimate's relative sd is about sqrt((kurtosis - 1) / (4 ESS)), under 3%). That
    the shear mixes faster is measured on the composite posterior it was made for
    (docs/composite.md, "A bent ridge, straightened"), not asserted on this toy."""
    from loadbayes.inference.moves.sheared import Shear

    x, moves = run_move(MOVES["shear"], _banana, np.zeros(3), cov0=np.eye(3), burn=4000,
                        draws=24000, seed=2)  # fmt: skip
    flat = x.reshape(-1, 3)
    np.testing.assert_allclose(flat.mean(0), [0.0, 0.0, 0.0], atol=0.2)
    np.testing.assert_allclose(flat.std(0), [1.0, math.sqrt(1 + 2 * B**2 + SD**2), 1.0],
                               rtol=0.15)  # fmt: skip
    assert all(isinstance(m.shear, Shear) and m.shear.active for m in moves)
    assert all(0.15 < m.acceptance < 0.4 for m in moves)


def _bent_shear(rng):
    # A shear learned on draws bent along their first coordinate, and the draws.
    from loadbayes.inference.moves.sheared import Shear

    y1 = rng.standard_normal(2000)
    draws = np.stack([y1, y1 + B * (y1**2 - 1) + SD * rng.standard_normal(2000),
                      rng.standard_normal(2000)], axis=1)  # fmt: skip
    draws = draws * [2.0, 0.5, 3.0] + [1.0, -1.0, 0.0]
    shear = Shear(draws)
    assert shear.active
    return shear, draws


def test_the_shear_is_a_bijection_with_unit_jacobian():
    rng = np.random.default_rng(0)
    shear, _ = _bent_shear(rng)
    for x in rng.standard_normal((20, 3)) * 3:
        np.testing.assert_allclose(shear.inverse(shear.forward(x)), x, atol=1e-12)
        # Jacobian of x -> w by central differences: det = 1 / prod(D) (the standardising).
        jac = np.empty((3, 3))
        for j in range(3):
            h = np.zeros(3)
            h[j] = 1e-6
            jac[:, j] = (shear.forward(x + h) - shear.forward(x - h)) / 2e-6
        assert np.linalg.det(jac) == pytest.approx(1.0 / np.prod(shear.D), rel=1e-6)


def test_the_shears_rows_at_once_are_its_points_one_at_a_time():
    # forward_rows (the jumps' fit maps every kept draw with it) against forward, inside
    # and far outside the range the bend was learned on (its pivot clipped there).
    rng = np.random.default_rng(1)
    shear, draws = _bent_shear(rng)
    for xs in (draws, rng.standard_normal((300, 3)) * 30):
        one = np.array([shear.forward(x) for x in xs])
        np.testing.assert_allclose(shear.forward_rows(xs), one, rtol=1e-13,
                                   atol=1e-13 * np.abs(one).max())  # fmt: skip


def test_with_a_short_burn_in_the_sheared_move_is_adaptive_metropolis_draw_for_draw():
    """A bend learned from the 100 draws of a 400-iteration burn-in was wrong (200 short
    composite fits covered T' at 88%): below MIN_HISTORY draws it is not learned."""
    runs = [run_move(MOVES[n], _banana, np.zeros(3), cov0=np.eye(3), burn=400, draws=1000,
                     seed=4)[0] for n in ("am", "shear")]  # fmt: skip
    np.testing.assert_array_equal(runs[0], runs[1])


# ------------------------------------------------------------------ jumps
W_LEFT = 0.3


def _two_modes(v):
    """0.3 N((-3, 0), 0.5^2 I) + 0.7 N((3, 0), 0.5^2 I): a random walk scaled to one mode
    does not cross between them."""
    a = math.log(W_LEFT) - 2.0 * ((v[0] + 3.0) ** 2 + v[1] ** 2)
    b = math.log(1 - W_LEFT) - 2.0 * ((v[0] - 3.0) ** 2 + v[1] ** 2)
    return float(np.logaddexp(a, b)), None


@pytest.mark.parametrize("name", ["am", "shear"])
def test_jumps_weigh_two_separated_modes_right(name):
    """The jumps' Hastings ratio is what weighs the modes: a wrong one (a random walk's
    symmetric ratio, or the t's density in the wrong coordinates) gives the wrong share.
    Each chain starts in one mode and its burn-in stays there, so the t is fitted to the
    two chains' burn-in pooled, as the composite sampler does. 2 x 20,000 draws with jumps
    accepted ~15% (measured): the share of the left mode has a Monte Carlo sd under 0.01
    (the chains switch modes hundreds of times), so 0.05 is over 5 sds (false alarm
    < 1e-6); the modes' own means and sds are checked at 5 sds too."""
    rng = np.random.default_rng(0)
    pooled = np.vstack([rng.normal([-3.0, 0.0], 0.5, (1000, 2)),
                        rng.normal([3.0, 0.0], 0.5, (1000, 2))])  # fmt: skip
    x, moves = run_jumping(name, _two_modes, [[-3.0, 0.0], [3.0, 0.0]], pooled,
                            burn=2000, draws=22000, seed=11)  # fmt: skip
    flat = x.reshape(-1, 2)
    left = flat[:, 0] < 0
    assert left.mean() == pytest.approx(W_LEFT, abs=0.05)
    for side, centre in ((left, -3.0), (~left, 3.0)):
        assert flat[side, 0].mean() == pytest.approx(centre, abs=0.05)
        assert flat[side, 0].std() == pytest.approx(0.5, rel=0.1)
    for m in moves:
        assert m.jumps > 1000 and 0.05 < m.jump_acceptance < 0.6
        # Each chain crossed: its draws hold both modes.
    assert all((c[:, 0] < 0).any() and (c[:, 0] > 0).any() for c in x)


def test_without_jumps_fitted_the_move_is_the_random_walk_draw_for_draw():
    """With fewer burn-in draws than JUMP_MIN_DRAWS there are no jumps, and the chain is
    the plain random walk's, draw for draw (no extra random numbers are drawn)."""
    from loadbayes.inference.moves.adaptive_metropolis import JUMP_MIN_DRAWS

    def run(independence):
        rng = np.random.default_rng(5)
        move = MOVES["am"](np.eye(3), adapt_until=JUMP_MIN_DRAWS - 1, independence=independence)
        x, lp, out = np.zeros(3), _gaussian(np.zeros(3))[0], []
        for it in range(2000):
            (x, lp, _), _ = move.step(BlockState(x, lp), _gaussian, rng, it)
            out.append(x)
        return np.array(out), move

    (plain, _), (jumpy, move) = run(0.0), run(0.35)
    np.testing.assert_array_equal(plain, jumpy)
    assert move.jumps == 0 and move.jump_acceptance is None


def test_jumps_after_a_long_burn_in_keep_the_bent_ridge_marginals():
    """The sheared move with jumps fitted to its own burn-in (in the sheared coordinates):
    the banana's marginals as in the test without jumps, at the same tolerances."""
    rng_seeds = chain_generators(2, 2)

    def chain(i, rng):
        move = MOVES["shear"](np.eye(3), adapt_until=4000, independence=0.35)
        x, lp, out = np.zeros(3), _banana(np.zeros(3))[0], []
        for it in range(24000):
            (x, lp, _), _ = move.step(BlockState(x, lp), _banana, rng, it)
            if it >= 4000:
                out.append(x)
        return np.array(out), move

    res = run_chains(chain, rng_seeds, workers=1)
    flat = np.vstack([r[0] for r in res])
    np.testing.assert_allclose(flat.mean(0), [0.0, 0.0, 0.0], atol=0.2)
    np.testing.assert_allclose(flat.std(0), [1.0, math.sqrt(1 + 2 * B**2 + SD**2), 1.0],
                               rtol=0.15)  # fmt: skip
    assert all(r[1].jumps > 1000 and r[1].jump_acceptance > 0.05 for r in res)
