"""Chains of a model of parts in different modes (fit/composite/restart.py, sampler.py).

- a chain whose late burn-in's median log density is more than RESTART_GAP below the
  best chain's goes on from a copy of the best chain's state, and the words say how many
  and by how much; chains within the gap are left alone;
- on a two-mode target written here (two Gaussians, 40 log-units apart in height), the
  restart takes the chains out of the lower mode: every kept draw is the higher mode's;
- a model of parts asks the sampler to restart lagging chains and says how many regions
  its jumps take (one by default); zip+motor's path is untouched (its problem has no
  model to ask);
- a gap over NEAR_GAP but under RESTART_GAP is named, its chain not moved;
- only a model of parts whose events give a third channel gets a second least-squares
  start (the fit of P and Q alone) for half its chains.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from loadbayes.fit.composite.nls import _has_third_channel
from loadbayes.fit.composite.restart import (
    NEAR_GAP,
    RESTART_GAP,
    late_gaps,
    restart_lagging,
    words,
)
from loadbayes.inference.chain import Chain
from loadbayes.models.dynamic import dynamic_model


def test_a_chain_far_below_the_best_goes_on_from_its_state_and_is_said():
    chains = [SimpleNamespace(state={"u": np.full(3, float(k))}) for k in range(3)]
    lp = [np.full(50, 100.0), np.full(50, 100.0 - RESTART_GAP - 5), np.full(50, 97.0)]
    moved = restart_lagging(chains, lp)
    assert moved == [(1, 0, RESTART_GAP + 5)]
    assert np.array_equal(chains[1].state["u"], chains[0].state["u"])
    assert chains[1].state["u"] is not chains[0].state["u"]  # a copy: the chains go apart
    assert np.array_equal(chains[2].state["u"], np.full(3, 2.0))  # within the gap: left
    text = words(moved, 3)
    assert "1 of 3 chains" in text and "by 15" in text and "more than one mode" in text
    assert words([], 3) is None
    assert restart_lagging(chains, [np.full(5, 1.0), np.full(5, 0.0), []]) == []


def test_the_restart_takes_chains_out_of_a_lower_mode_of_a_two_mode_target():
    # Two unit Gaussians at -20 and +20 whose heights differ by 40 (log): a random walk of
    # scale 0.5 never crosses. Chains started in the lower mode are restarted from the one
    # in the higher; after it every chain's draws are the higher mode's.
    def logp(x):
        return max(-0.5 * (x + 20) ** 2, -0.5 * (x - 20) ** 2 + 40.0)

    def step(state, rng, it):
        x, lp = state
        c = x + 0.5 * rng.standard_normal()
        lc = logp(c)
        return (c, lc) if np.log(rng.uniform()) < lc - lp else (x, lp)

    starts = [-20.0, -20.0, 20.0, -20.0]
    rngs = [np.random.default_rng(s) for s in range(4)]
    chains = [
        Chain(
            step, (x, logp(x)), r, fields={"x": ()}, record=lambda s: {"x": s[0]}, burn=200
        )  # fmt: skip
        for x, r in zip(starts, rngs, strict=True)
    ]
    late = []
    for c in chains:
        c.run(200)
        late.append([c.state[1]])
    moved = restart_lagging(chains, late)
    assert sorted(k for k, _, _ in moved) == [0, 1, 3]
    for c in chains:
        c.run(400)
        assert np.all(c.draws()["x"] > 0)


def test_a_model_of_parts_restarts_lagging_chains_and_keeps_one_t_for_its_jumps():
    for name in ("slm", "cmld-lite"):
        model = dynamic_model(name)
        assert model.jump_regions == 1 and model.restart_modes


def test_a_smaller_gap_is_named_without_moving_a_chain():
    # Gaps 0, 7, 12, 3: the chain 12 below is moved and said; the one 7 below (over
    # NEAR_GAP, under RESTART_GAP) is said, not moved; 3 is within one mode: silent.
    lp = [np.full(9, 100.0), np.full(9, 93.0), np.full(9, 88.0), np.full(9, 97.0)]
    gaps = late_gaps(lp)
    assert gaps == [0.0, 7.0, 12.0, 3.0]
    chains = [SimpleNamespace(state={"u": np.full(2, float(k))}) for k in range(4)]
    moved = restart_lagging(chains, lp)
    assert [k for k, _, _ in moved] == [2]
    text = words(moved, 4, gaps)
    assert "1 of 4 chains ended their burn-in in a mode" in text and "by 12" in text
    assert "1 of 4 chains ended their burn-in with a log density" in text and "by 7" in text
    assert np.array_equal(chains[1].state["u"], np.full(2, 1.0))  # named, not moved
    assert words([], 4, [0.0, NEAR_GAP - 1, 2.0, 0.5]) is None
    assert "by 6" in words([], 2, [0.0, NEAR_GAP + 1])


def test_only_a_model_of_parts_with_a_third_channel_gets_a_second_least_squares_start():
    # nls: the fit of P and Q alone is a second start only for a model that restarts
    # chains and whose events give the negative-sequence channel rows; zip+motor's
    # problem (no model) and a model of parts on balanced events get none.
    def problem(rows, restart=True):
        model = SimpleNamespace(restart_modes=restart)
        return SimpleNamespace(model=model, channel_rows=lambda: np.array(rows, float))

    assert _has_third_channel(problem([60, 60, 8]))
    assert not _has_third_channel(problem([60, 60, 0]))
    assert not _has_third_channel(problem([60, 60]))
    assert not _has_third_channel(problem([60, 60, 8], restart=False))
    assert not _has_third_channel(SimpleNamespace())
