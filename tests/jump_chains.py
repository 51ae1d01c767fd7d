"""Two chains of one u-move with jumps, for the moves' tests (tests/unit/test_moves*.py).

Each chain adapts its walk until ``burn``, then fits the jumps to ``pooled`` (several
chains' burn-in, as the composite sampler does) and keeps its draws from there.
"""

from __future__ import annotations

import numpy as np

from loadbayes.core.parallel import chain_generators, run_chains
from loadbayes.inference.moves import MOVES, BlockState

__all__ = ["run_jumping"]


def run_jumping(name, logp, x0, pooled, *, burn, draws, seed, components=1, wide=0.0,
                anchors=None, anchor=0.0):  # fmt: skip
    """``(draws (2, kept, d), moves)``: chain ``i`` from ``x0[i]``; no jumps without ``pooled``."""

    def chain(i, rng):
        move = MOVES[name](0.25 * np.eye(2), adapt_until=burn, independence=0.35)
        x = np.array(x0[i], dtype=float)
        lp = logp(x)[0]
        out = []
        for it in range(draws):
            if it == burn and pooled is not None:
                move.fit_jumps(pooled, components=components, wide=wide, anchors=anchors,
                               anchor=anchor)  # fmt: skip
            (x, lp, _), _ = move.step(BlockState(x, lp), logp, rng, it)
            if it >= burn:
                out.append(x)
        return np.array(out), move

    res = run_chains(chain, chain_generators(seed, 2), workers=1)
    return np.stack([r[0] for r in res]), [r[1] for r in res]
