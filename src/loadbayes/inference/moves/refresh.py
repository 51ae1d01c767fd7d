"""Refresh bounded coordinates of a block from their uniform support.

Knows no physics: a block is a vector, some of its coordinates are bounded, and a
log-density callable says the rest.

The composite's default move walks in the coordinates of the bulk and jumps from a
mixture of t's fitted to the pooled burn-in (:mod:`.adaptive_metropolis`,
:mod:`.mixture`). A minor mode the burn-in missed defeats both: the walk crosses the
trough to it rarely, and once a chain is there the jumps cannot take it back, because an
independence step out of ``x`` accepts by ``p(y) q(x) / (p(x) q(y))`` and the mixture's
``q(x)`` is tiny where its draws never were. The instant of a fault's edge inside a
recorder's sample interval has such modes: on the real record's reclose 3.5% of the mass
near 0.57 of the interval against a bulk at 0.26, where seed 4's chains sat up to 4,909
iterations and the run took 100,000 iterations per chain for a median of 24,000
(docs/composite.md, "A minor mode of an edge's instant").

:class:`UniformRefresh` is one Metropolis step on one bounded coordinate, picked at
random, the others held, proposed uniformly on its support (a symmetric proposal:
accepted by the density ratio alone), taken with probability ``share`` each iteration.
Where the coordinate is bimodal it crosses the trough in one step both ways, and it
leaves the density invariant with any ``share``: it runs during burn-in (so the pooled
burn-in the jumps are fitted to may see the minor mode) and during the kept draws alike.
Half its proposals from a normal fitted to the burn-in was tried: on the reclose it
lengthened the slowest seeds (docs/composite.md).
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.inference.moves.base import BlockState, LogDensity

__all__ = ["UniformRefresh"]


class UniformRefresh:
    """A Metropolis step on one bounded coordinate, proposed uniformly on its support.

    Parameters
    ----------
    index : sequence of int
        The bounded coordinates of the block.
    low, high : float
        Their support (the density is zero outside: the proposal never leaves it).
    share : float
        Probability that an iteration takes the step (0: never, no random numbers drawn).

    Attributes
    ----------
    steps, accepted : int
        Steps taken and accepted.
    """

    def __init__(self, index, *, low: float = 0.0, high: float = 1.0, share: float) -> None:
        self.index = np.asarray(index, dtype=int)
        if not 0.0 <= share <= 1.0:
            raise ValueError(f"share must be in [0, 1], got {share}")
        if not high > low:
            raise ValueError(f"the support needs high > low, got [{low}, {high}]")
        self.low, self.high, self.share = float(low), float(high), float(share)
        self.steps = self.accepted = 0

    def step(self, state: BlockState, logp: LogDensity, rng: np.random.Generator) -> BlockState:
        """Maybe one refresh (probability :attr:`share`); the state it leaves."""
        # rng.random(): rng.uniform()'s number (0 + 1 * d), its call cheaper.
        if not self.share or not self.index.size or rng.random() >= self.share:
            return state
        j = self.index[rng.integers(self.index.size)] if self.index.size > 1 else self.index[0]
        prop = np.array(state.x, dtype=float)
        prop[j] = rng.uniform(self.low, self.high)
        lp_prop, aux = logp(prop)
        self.steps += 1
        if math.isfinite(lp_prop) and math.log(rng.random()) < lp_prop - state.logp:
            self.accepted += 1
            return BlockState(prop, lp_prop, aux)
        return state

    @property
    def acceptance(self) -> float | None:
        """Share of the refreshes that moved (None before any)."""
        return self.accepted / self.steps if self.steps else None
