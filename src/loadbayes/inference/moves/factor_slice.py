"""Factor slice sampling for a block of Metropolis-within-Gibbs.

Knows no physics: a block is a vector ``x`` and a log-density callable, as for
:class:`~loadbayes.inference.moves.adaptive_metropolis.AdaptiveMetropolis` (both are
:class:`~loadbayes.inference.moves.base.BlockMove`, so a sampler can take either).

Tibbits, Groendyke, Haran and Liechty (2014), "Automated factor slice sampling", JCGS
23(2): one univariate slice-sampling update (Neal 2003, stepping out then shrinkage)
along each eigenvector of the block's covariance, in random order, with an initial
interval of ``width`` times the sd along that eigenvector. Slice sampling adapts its
move to the local width of the density along each direction (a curved ridge that is
narrow here and wide there), where a random-walk proposal has one fixed scale; the
price is several density evaluations per direction.

The covariance is learned from the chain's own draws **during burn-in only** (as for the
adaptive Metropolis) and then frozen, and so is the width factor, tuned by the
Robbins-Monro recursion of Tibbits et al. towards equal numbers of expansions and
contractions (their "1/2 rule"); the kept draws come from a fixed slice-sampling kernel,
which leaves the target invariant for any fixed directions and widths.
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.inference.moves.base import BlockMove, BlockState, LogDensity

__all__ = ["FactorSlice"]


class FactorSlice(BlockMove):
    """Slice sampling along the eigenvectors of a covariance learned during burn-in.

    Parameters
    ----------
    cov0 : ndarray, shape (d, d)
        Initial covariance (e.g. a Laplace approximation).
    adapt_until : int
        Iterations during which the covariance and width adapt (the burn-in).
    adapt_start : int
        Iterations with ``cov0`` before the empirical covariance takes over.
    width : float
        Initial interval, in sds along each eigenvector.
    max_steps : int
        Largest number of stepping-out expansions on each side.
    """

    def __init__(
        self,
        cov0: np.ndarray,
        *,
        adapt_until: int,
        adapt_start: int = 100,
        width: float = 2.5,
        max_steps: int = 10,
    ) -> None:
        super().__init__(cov0, adapt_until=adapt_until, adapt_start=adapt_start)
        self.log_width = math.log(width)
        self.max_steps = int(max_steps)
        self._expansions = 0
        self._contractions = 0

    def step(
        self, state: BlockState, logp: LogDensity, rng: np.random.Generator, iteration: int
    ) -> tuple[BlockState, bool]:
        """One sweep: a slice update along every eigen-direction, in random order.

        The contract is :meth:`BlockMove.step`'s (``state.logp`` finite); ``moved`` is
        always True (a slice update always moves, if only a little).
        """
        x, logp_x, aux = state
        w0 = math.exp(self.log_width)
        exp0, con0 = self._expansions, self._contractions
        for j in rng.permutation(self.d):
            x, logp_x, aux = self._update(x, logp_x, aux, self._root[:, j], w0, logp, rng)
        self.steps += 1
        self.accepted += 1
        if iteration < self.adapt_until:
            self._adapt(x, exp0, con0, iteration)
        return BlockState(x, logp_x, aux), True

    def _update(self, x, logp_x, aux, direction, width, logp, rng):
        def at(t):
            self.evaluations += 1
            return logp(x + t * direction)

        level = logp_x - rng.exponential()
        left = -width * rng.uniform()
        right = left + width
        # Stepping out (Neal 2003, fig. 3): the step budget split at random between sides.
        j = int(rng.integers(self.max_steps))
        k = self.max_steps - 1 - j
        while j > 0 and at(left)[0] > level:
            left -= width
            j -= 1
            self._expansions += 1
        while k > 0 and at(right)[0] > level:
            right += width
            k -= 1
            self._expansions += 1
        while True:
            t = rng.uniform(left, right)
            lp, aux_t = at(t)
            if lp > level:
                return x + t * direction, lp, aux_t
            self._contractions += 1
            if t < 0.0:
                left = t
            else:
                right = t
            if right - left < 1e-12 * width:  # cannot happen for a finite logp_x > level
                return x, logp_x, aux

    def _adapt(self, x: np.ndarray, exp0: int, con0: int, iteration: int) -> None:
        # Tibbits et al.'s rule: expansions mean the interval was too narrow, contractions
        # that it was too wide; balance them.
        ne, nc = self._expansions - exp0, self._contractions - con0
        if ne + nc > 0:
            self.log_width += (ne / (ne + nc) - 0.5) / math.sqrt(iteration + 1.0)
        self._learn(x)
