"""Adaptive Metropolis for a block of Metropolis-within-Gibbs.

Knows no physics: a block is a vector ``x`` and a log-density callable.

:class:`AdaptiveMetropolis` is the random-walk proposal of Haario, Saksman and
Tamminen (2001), "An adaptive Metropolis algorithm", Bernoulli 7(2): a Gaussian step
whose covariance is the running covariance of the chain's own draws, scaled by
``2.38^2 / d`` (Roberts, Gelman and Gilks 1997), with the overall scale tuned towards an
acceptance rate of 0.234 by a Robbins-Monro recursion. Both are learned **only during
burn-in** and then frozen, so the kept draws come from a fixed, valid Metropolis kernel
(no diminishing-adaptation argument needed).

Chains run through :func:`loadbayes.core.parallel.run_chains`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["AdaptiveMetropolis", "RunningCovariance", "scaled_eigenvectors"]


def scaled_eigenvectors(cov: np.ndarray) -> np.ndarray:
    """Columns: the eigenvectors of ``cov`` scaled by their sds (a square root of it)."""
    w, v = np.linalg.eigh(cov)
    return v * np.sqrt(np.clip(w, 1e-14 * max(w.max(), 1e-300), None))


class RunningCovariance:
    """A chain's running covariance (Welford), refreshed every 20 draws after a start.

    The covariance the adaptive moves learn in burn-in: until ``adapt_start`` draws it is
    ``cov0``; then the empirical one plus a little of the previous diagonal, which keeps
    it non-singular.
    """

    def __init__(self, cov0: np.ndarray, adapt_start: int) -> None:
        cov0 = np.atleast_2d(np.asarray(cov0, dtype=float))
        self.d = cov0.shape[0]
        self.cov = (cov0 + cov0.T) / 2
        self.adapt_start = int(adapt_start)
        self._n = 0
        self._mean = np.zeros(self.d)
        self._m2 = np.zeros((self.d, self.d))

    def update(self, x: np.ndarray) -> bool:
        """Add a draw; True when the covariance was refreshed."""
        self._n += 1
        delta = x - self._mean
        self._mean += delta / self._n
        self._m2 += np.outer(delta, x - self._mean)
        if self._n >= self.adapt_start and self._n % 20 == 0:
            emp = self._m2 / (self._n - 1)
            self.cov = emp + 1e-3 * np.diag(np.diag(self.cov)) + 1e-10 * np.eye(self.d)
            return True
        return False


class AdaptiveMetropolis:
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
        self._running = RunningCovariance(cov0, adapt_start)
        self.d = self._running.d
        self.cov = self._running.cov
        self.log_scale = math.log(2.38**2 / self.d)
        self.adapt_until = int(adapt_until)
        self.adapt_start = int(adapt_start)
        self.target = float(target)
        self._chol = scaled_eigenvectors(self.cov)
        self.accepted = 0
        self.proposed = 0

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
        z = rng.standard_normal(self.d)
        prop = x + math.exp(0.5 * self.log_scale) * (self._chol @ z)
        lp_prop, aux_prop = logp(prop)
        log_u = math.log(rng.uniform())
        alpha = min(1.0, math.exp(min(0.0, lp_prop - logp_x))) if math.isfinite(lp_prop) else 0.0
        accept = log_u < lp_prop - logp_x if math.isfinite(lp_prop) else False
        self.proposed += 1
        if accept:
            x, logp_x, aux = prop, lp_prop, aux_prop
            self.accepted += 1
        if iteration < self.adapt_until:
            self._adapt(x, alpha, iteration)
        return x, logp_x, aux, bool(accept)

    def _adapt(self, x: np.ndarray, alpha: float, iteration: int) -> None:
        # Robbins-Monro on the log scale, step size decaying as 1/sqrt(t).
        self.log_scale += (alpha - self.target) / math.sqrt(iteration + 1.0)
        if self._running.update(x):
            self.cov = self._running.cov
            self._chol = scaled_eigenvectors(self.cov)

    @property
    def acceptance(self) -> float:
        """Acceptance rate so far."""
        return self.accepted / max(self.proposed, 1)

    @property
    def evaluations_per_step(self) -> float:
        """Density evaluations per :meth:`step`: one."""
        return 1.0
