"""Several block steps per iteration (fit.composite.sampler.block_steps) on a known target.

A model of parts may ask the composite sampler for several steps of its block move per
iteration (``PartsModel.block_steps``: ``cmld-lite`` 12), taken in runs whose burn-in is
``BLOCK_STEPS_MIN_BURN`` or more. Each step is the move's own, so
their composition leaves the density invariant; what can go wrong is the state carried
from one step to the next. Seeds are fixed; the tolerances are what a correct sampler
passes with the stated false-alarm rate were the seed drawn at random.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from scipy import stats

from loadbayes.fit.composite.sampler import (
    BLOCK_STEPS_MIN_BURN,
    JUMP_SHARE,
    block_steps,
    jump_share,
    steps_per_iteration,
)
from loadbayes.inference.moves import ShearedAM
from loadbayes.inference.moves.base import BlockState
from loadbayes.models.dynamic import dynamic_model

W, M, SD = 0.3, 1.2, 0.6  # x: W N(-M, SD^2) + (1 - W) N(M, SD^2); y | x ~ N(x^2 / 2, 0.3^2)


def _logp(v):
    x, y = float(v[0]), float(v[1])
    a = math.log(W) - 0.5 * ((x + M) / SD) ** 2
    b = math.log(1 - W) - 0.5 * ((x - M) / SD) ** 2
    return float(np.logaddexp(a, b)) - 0.5 * ((y - 0.5 * x * x) / 0.3) ** 2, None


def _cdf(x):
    return W * stats.norm.cdf(x, -M, SD) + (1 - W) * stats.norm.cdf(x, M, SD)


def _run(steps: int, iterations: int, burn: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    move = ShearedAM(np.eye(2) * 0.1, adapt_until=burn, adapt_start=100)
    x0 = np.array([-M, 0.5 * M * M])
    state = BlockState(x0, _logp(x0)[0], None)
    out = []
    for it in range(iterations):
        state = block_steps(move, state, _logp, rng, it, steps)
        if it >= burn:
            out.append(state.x[0])
    return np.array(out)


def test_six_block_steps_per_iteration_draw_a_bimodal_curved_target():
    """Six steps per iteration of the default move (a shear learned in burn-in, then
    frozen) on a two-mode target bent in y: x's 600 draws thinned to 1 in 50 (about
    independent: the chain's integrated autocorrelation was measured at 9 iterations)
    follow the mixture's CDF (KS p > 0.001: a false alarm of 0.1 % for independent
    draws), and the lighter mode holds its 30 % (4 binomial sds). Power, measured once:
    steps handed the new x with a stale log density (the first step's) give p 6e-4 at
    this seed, a failure."""
    x = _run(6, 32_000, 2_000, seed=2)[::50]
    assert stats.kstest(x, _cdf).pvalue > 1e-3
    assert abs(np.mean(x < 0) - W) < 4 * math.sqrt(W * (1 - W) / x.size)


def test_one_block_step_is_the_moves_own_draw_for_draw():
    """One step per iteration is one call of the move: the same draws as the move driven
    directly (zip+motor and every model of parts but cmld-lite keep their draws)."""
    rng = np.random.default_rng(4)
    move = ShearedAM(np.eye(2) * 0.1, adapt_until=300, adapt_start=50)
    twin_rng = np.random.default_rng(4)
    twin = ShearedAM(np.eye(2) * 0.1, adapt_until=300, adapt_start=50)
    a = b = BlockState(np.zeros(2), _logp(np.zeros(2))[0], None)
    for it in range(600):
        a = block_steps(move, a, _logp, rng, it, 1)
        b, _ = twin.step(b, _logp, twin_rng, it)
        assert np.array_equal(a.x, b.x)


def test_the_sampler_takes_the_models_block_steps_in_a_long_run_only():
    """cmld-lite asks for 12 block steps, slm for 1; the sampler takes them where the
    burn-in is BLOCK_STEPS_MIN_BURN or more (the defaults' 4,000), else one step (a short
    run keeps its cost and draws); a problem with no model (zip+motor) always 1."""
    cmld, slm = dynamic_model("cmld-lite"), dynamic_model("slm")
    assert cmld.block_steps == 12 and slm.block_steps == 1
    assert cmld.share_steps == slm.share_steps == 20
    assert BLOCK_STEPS_MIN_BURN == 4_000
    assert steps_per_iteration(SimpleNamespace(model=cmld), 4_000) == 12
    assert steps_per_iteration(SimpleNamespace(model=cmld), 3_999) == 1
    assert steps_per_iteration(SimpleNamespace(model=slm), 40_000) == 1
    assert steps_per_iteration(SimpleNamespace(), 40_000) == 1


def test_cmld_lite_jumps_once_per_iteration_and_the_others_keep_the_share():
    """With its 12 block steps cmld-lite jumps in one step per iteration on average (a
    share of 1/12, its jumps accepted about 1 in 400 times); one step per iteration (a
    short run), slm and a problem with no model (zip+motor) keep JUMP_SHARE of every
    step, so their draws are unchanged."""
    cmld, slm = dynamic_model("cmld-lite"), dynamic_model("slm")
    long_run = steps_per_iteration(SimpleNamespace(model=cmld), 4_000)
    assert jump_share(SimpleNamespace(model=cmld), long_run) == 1.0 / 12
    assert jump_share(SimpleNamespace(model=cmld), 1) == JUMP_SHARE
    assert jump_share(SimpleNamespace(model=slm), 1) == JUMP_SHARE
    assert jump_share(SimpleNamespace(model=slm), 12) == JUMP_SHARE  # slm asks for none
    assert jump_share(SimpleNamespace(), 12) == JUMP_SHARE
    few = SimpleNamespace(model=SimpleNamespace(jumps_per_iteration=10.0))
    assert jump_share(few, 12) == JUMP_SHARE  # never more than the sampler's share


def test_cmld_lite_runs_a_first_round_of_10000_and_slm_keeps_16000():
    """The defaults of a model of parts (driver.parts_defaults): cmld-lite's first round
    is 10,000 iterations (its 12 block steps mix more per iteration; the run goes on until
    converged), slm's the 16,000 of PARTS_DEFAULTS; both 4,000 burn-in, four chains."""
    from loadbayes.fit.composite.driver import PARTS_DEFAULTS, parts_defaults

    cmld, slm = parts_defaults(dynamic_model("cmld-lite")), parts_defaults(dynamic_model("slm"))
    assert (cmld.draws, cmld.burn, cmld.chains) == (10_000, 4_000, 4)
    assert slm == PARTS_DEFAULTS and slm.draws == 16_000
    assert cmld.burn >= BLOCK_STEPS_MIN_BURN  # the default run takes the block steps


def test_the_cost_estimates_probe_takes_the_runs_block_steps(monkeypatch):
    """The probe behind "about N s on this machine" runs a short burn-in, which alone
    would take one block step; a cmld-lite run at the defaults takes 12, and its
    estimate read 36 s for a first round of 4 min (real record, seed 3). The probe must
    ask for the run's steps."""
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite import chain_fast, driver, until

    asked = []
    monkeypatch.setattr(driver, "sample", lambda *a, **k: asked.append(k["block_steps"]))
    monkeypatch.setattr(chain_fast, "compiled_run", lambda *a, **k: False)
    monkeypatch.setattr(until, "estimate_seconds", lambda probe, draws, rounds: probe(64))
    problem = SimpleNamespace(model=dynamic_model("cmld-lite"), events=[])
    for burn, steps in ((BLOCK_STEPS_MIN_BURN, 12), (BLOCK_STEPS_MIN_BURN - 1, 1)):
        run = SamplerSettings(draws=2 * burn, burn=burn, chains=4, seed=0, threads=2)
        asked.clear()
        driver._estimate_seconds(problem, None, run, "shear", None)
        assert asked == [steps, steps]  # the compiling call, then the probe
