"""Chains of a model of parts in different modes (fit/composite/restart.py, sampler.py).

- a chain whose late burn-in's median log density is more than RESTART_GAP below the
  best chain's goes on from a copy of the best chain's state, and the words say how many
  and by how much; chains within the gap are left alone;
- on a two-mode target written here (two Gaussians, 40 log-units apart in height), the
  restart takes the chains out of the lower mode: every kept draw is the higher mode's;
- a model of parts asks the sampler to restart lagging chains and says how many regions
  its jumps take (one by default); zip+motor's path is untouched (its problem has no
  model to ask).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from loadbayes.fit.composite.restart import RESTART_GAP, restart_lagging, words
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
