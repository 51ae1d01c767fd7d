"""Refresh bounded coordinates of a block, one at a time, across their whole support.

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

:class:`CoordinateRefresh` is one Metropolis-Hastings step on one bounded coordinate,
picked at random, the others held, taken with probability ``share`` each iteration. It
proposes from ``q = weight U(low, high) + (1 - weight) N(m, s^2)``, where ``N`` is fitted
to draws (:meth:`~CoordinateRefresh.fit`: the pooled burn-in, its sd times
``inflation``; uniform alone before). The uniform part reaches a mode the draws never
saw; the normal part brings a chain back to the bulk in a step, since ``q`` at a minor
mode is at least ``weight / (high - low)``: not tiny. It is an independence proposal in
one coordinate, accepted by the Hastings ratio with ``q`` (a normal draw outside the
support has density 0 and is rejected), so it leaves the density invariant with any
``share``; fitted once and then frozen, as the jumps are.
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.inference.moves.base import BlockState, LogDensity

__all__ = ["CoordinateRefresh"]


class CoordinateRefresh:
    """A Metropolis-Hastings step on one bounded coordinate across its support.

    Parameters
    ----------
    index : sequence of int
        The bounded coordinates of the block.
    low, high : float
        Their support (the density is zero outside).
    share : float
        Probability that an iteration takes the step (0: never, no random numbers drawn).
    weight : float
        The uniform's weight in the proposal once :meth:`fit` has run.

    Attributes
    ----------
    steps, accepted : int
        Steps taken and accepted.
    """

    def __init__(self, index, *, low: float = 0.0, high: float = 1.0, share: float,
                 weight: float = 0.5) -> None:  # fmt: skip
        self.index = np.asarray(index, dtype=int)
        if not 0.0 <= share <= 1.0:
            raise ValueError(f"share must be in [0, 1], got {share}")
        if not 0.0 < weight <= 1.0:
            raise ValueError(f"weight must be in (0, 1], got {weight}")
        if not high > low:
            raise ValueError(f"the support needs high > low, got [{low}, {high}]")
        self.low, self.high, self.share, self.weight = (
            float(low),
            float(high),
            float(share),
            float(weight),
        )
        self.steps = self.accepted = 0
        self.centre: np.ndarray | None = None  # the fitted normals, per coordinate
        self.scale: np.ndarray | None = None

    def fit(self, draws: np.ndarray, *, inflation: float = 2.0) -> None:
        """Fit each coordinate's normal to ``draws`` (rows of the block).

        Its sd is the draws' times ``inflation``; fewer than two draws, or a coordinate
        that never moved in them, leave the proposal uniform.
        """
        x = np.asarray(draws, dtype=float)
        if x.ndim != 2 or x.shape[0] < 2:
            return
        cols = x[:, self.index]
        sd = cols.std(axis=0)
        if not np.all(sd > 0):
            return
        self.centre, self.scale = cols.mean(axis=0), inflation * sd

    def _log_q(self, k: int, value: float) -> float:
        inside = self.low <= value <= self.high
        uni = self.weight / (self.high - self.low) if inside else 0.0
        if self.centre is None:
            return math.log(uni) if uni > 0 else -math.inf
        z = (value - self.centre[k]) / self.scale[k]
        normal = (
            (1 - self.weight) * math.exp(-0.5 * z * z) / (self.scale[k] * math.sqrt(2 * math.pi))
        )
        total = uni + normal
        return math.log(total) if total > 0 else -math.inf

    def step(self, state: BlockState, logp: LogDensity, rng: np.random.Generator) -> BlockState:
        """Maybe one refresh (probability :attr:`share`); the state it leaves."""
        if not self.share or not self.index.size or rng.uniform() >= self.share:
            return state
        k = int(rng.integers(self.index.size)) if self.index.size > 1 else 0
        j = self.index[k]
        if self.centre is None or rng.uniform() < self.weight:
            value = rng.uniform(self.low, self.high)
        else:
            value = self.centre[k] + self.scale[k] * rng.standard_normal()
        self.steps += 1
        if not self.low <= value <= self.high:
            return state  # outside the support: density 0, rejected without a solve
        prop = np.array(state.x, dtype=float)
        prop[j] = value
        lp_prop, aux = logp(prop)
        log_ratio = lp_prop - state.logp
        if self.centre is not None:
            log_ratio += self._log_q(k, float(state.x[j])) - self._log_q(k, value)
        if math.isfinite(lp_prop) and math.log(rng.uniform()) < log_ratio:
            self.accepted += 1
            return BlockState(prop, lp_prop, aux)
        return state

    @property
    def acceptance(self) -> float | None:
        """Share of the refreshes that moved (None before any)."""
        return self.accepted / self.steps if self.steps else None
