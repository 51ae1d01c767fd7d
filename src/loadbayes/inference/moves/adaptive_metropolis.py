"""Adaptive Metropolis for a block of Metropolis-within-Gibbs.

Knows no physics: a block is a vector ``x`` and a log-density callable.

:class:`AdaptiveMetropolis` is the random-walk proposal of Haario, Saksman and
Tamminen (2001), "An adaptive Metropolis algorithm", Bernoulli 7(2): a Gaussian step
whose covariance is the running covariance of the chain's own draws, scaled by
``2.38^2 / d`` (Roberts, Gelman and Gilks 1997), with the overall scale tuned towards an
acceptance rate of 0.234 by a Robbins-Monro recursion. Both are learned **only during
burn-in** and then frozen, so the kept draws come from a fixed, valid Metropolis kernel
(no diminishing-adaptation argument needed).

The contract (``step``, the burn-in window, the counters) is
:class:`~loadbayes.inference.moves.base.BlockMove`'s; chains run through
:func:`loadbayes.core.parallel.run_chains`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from loadbayes.inference.moves.base import BlockMove

__all__ = ["AdaptiveMetropolis"]


class AdaptiveMetropolis(BlockMove):
    """Random-walk Metropolis on a block, adapting its covariance during burn-in.

    Parameters
    ----------
    cov0 : ndarray, shape (d, d)
        Initial proposal covariance (before scaling), e.g. a Laplace approximation.
    adapt_until : int
        Iterations during which the covariance and scale adapt (the burn-in).
    adapt_start : int
        Iterations with ``cov0`` before the empirical covariance takes over.
    target : float
        Acceptance rate the scale is tuned towards.
    """

    def __init__(
        self,
        cov0: np.ndarray,
        *,
        adapt_until: int,
        adapt_start: int = 100,
        target: float = 0.234,
    ) -> None:
        super().__init__(cov0, adapt_until=adapt_until, adapt_start=adapt_start)
        self.log_scale = math.log(2.38**2 / self.d)
        self.target = float(target)

    def step(
        self,
        x: np.ndarray,
        logp_x: float,
        logp: Callable[[np.ndarray], tuple[float, Any]],
        rng: np.random.Generator,
        iteration: int,
        aux: Any = None,
    ) -> tuple[np.ndarray, float, Any, bool]:
        """One Metropolis step; adapts when ``iteration < adapt_until``.

        Parameters
        ----------
        x : ndarray
            Current block.
        logp_x : float
            ``logp(x)`` at the current state (recomputed by the caller when the other
            blocks changed).
        logp : callable
            ``logp(x) -> (log density, aux)``; ``aux`` is carried along with the state
            (e.g. a simulated trajectory) so it need not be recomputed.
        rng : numpy.random.Generator
            The chain's generator.
        iteration : int
            Zero-based iteration number.
        aux : any
            The current state's ``aux``.

        Returns
        -------
        (x, logp_x, aux, accepted)
        """
        w = self._walk(x)
        z = rng.standard_normal(self.d)
        w_prop = w + math.exp(0.5 * self.log_scale) * (self._root @ z)
        prop = self._block(w_prop)
        lp_prop, aux_prop = logp(prop)
        log_u = math.log(rng.uniform())
        alpha = min(1.0, math.exp(min(0.0, lp_prop - logp_x))) if math.isfinite(lp_prop) else 0.0
        accept = log_u < lp_prop - logp_x if math.isfinite(lp_prop) else False
        self.steps += 1
        self.evaluations += 1
        if accept:
            x, logp_x, aux, w = prop, lp_prop, aux_prop, w_prop
            self.accepted += 1
        if iteration < self.adapt_until:
            self._adapt(w, alpha, iteration)
        return x, logp_x, aux, bool(accept)

    # The coordinates the walk moves in, and back: the block itself here; a subclass may
    # walk in others whose map to the block has a unit Jacobian (so the Metropolis
    # ratio stays the density ratio), and the covariance is then learned in them.
    def _walk(self, x: np.ndarray) -> np.ndarray:
        return x

    def _block(self, w: np.ndarray) -> np.ndarray:
        return w

    def _adapt(self, w: np.ndarray, alpha: float, iteration: int) -> None:
        # Robbins-Monro on the log scale, step size decaying as 1/sqrt(t).
        self.log_scale += (alpha - self.target) / math.sqrt(iteration + 1.0)
        self._learn(w)
