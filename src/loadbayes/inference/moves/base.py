"""What a block move of Metropolis-within-Gibbs is: the contract the moves share.

A move updates one block ``x`` (a vector) of a Metropolis-within-Gibbs sweep given a
log-density callable, leaving that density invariant; it knows no physics. The moves
here learn a covariance of the block from the chain's own draws **during burn-in only**
(the first ``adapt_until`` iterations, with ``cov0`` for the first ``adapt_start``) and
then freeze it, so the kept draws come from a fixed, valid kernel.

:class:`BlockMove` holds what every move has: that adaptation window, the shared
:class:`RunningCovariance` and its square root (:func:`scaled_eigenvectors`), and the
counters behind :attr:`~BlockMove.acceptance` and :attr:`~BlockMove.evaluations_per_step`.
A move supplies :meth:`~BlockMove.step`, which takes and returns a :class:`BlockState`
(as emcee's ``Move.propose(model, state) -> (state, accepted)``): the contract is written
once, here, and the moves refer to it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np

__all__ = ["BlockMove", "BlockState", "LogDensity", "RunningCovariance", "scaled_eigenvectors",
           "welford_step"]  # fmt: skip

#: ``logp(x) -> (log density, aux)``: ``-inf`` outside the support (such proposals are
#: never accepted); ``aux`` is carried along with the state (e.g. a simulated
#: trajectory) so it need not be recomputed.
LogDensity = Callable[[np.ndarray], tuple[float, Any]]


class BlockState(NamedTuple):
    """Where a block stands: its value, the log-density there, and what travels with it.

    Attributes
    ----------
    x : ndarray
        The block.
    logp : float
        ``logp(x)`` (recomputed by the caller when the other blocks changed).
    aux : any
        The ``aux`` of ``logp(x)`` (None when there is none).
    """

    x: np.ndarray
    logp: float
    aux: Any = None


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

    @property
    def mean(self) -> np.ndarray:
        """The mean of the draws fed so far."""
        return self._mean.copy()

    @property
    def count(self) -> int:
        """How many draws were fed."""
        return self._n

    def update(self, x: np.ndarray) -> bool:
        """Add a draw; True when the covariance was refreshed."""
        self._n += 1
        _welford(self._mean, self._m2, np.asarray(x, dtype=float), float(self._n))
        if self._n >= self.adapt_start and self._n % 20 == 0:
            self.refresh()
            return True
        return False

    def refresh(self) -> None:
        """Take the draws' covariance into use.

        :meth:`update` does every 20 draws; a compiled loop that ran the Welford steps
        itself asks for it.
        """
        emp = self._m2 / (self._n - 1)
        self.cov = emp + 1e-3 * np.diag(np.diag(self.cov)) + 1e-10 * np.eye(self.d)


@numba.njit(cache=True, nogil=True)
def _welford(mean, m2, x, n):  # pragma: no cover - compiled
    # Welford's step in place, NumPy's arithmetic one element at a time (the adaptive
    # moves feed one draw each burn-in iteration): delta = x - mean; mean += delta / n;
    # m2 += outer(delta, x - mean).
    d = x.size
    delta = np.empty(d)
    for i in range(d):
        delta[i] = x[i] - mean[i]
        mean[i] += delta[i] / n
    for i in range(d):
        for j in range(d):
            m2[i, j] += delta[i] * (x[j] - mean[j])


#: Welford's step in place ``(mean, m2, x, n)``, compiled: for a compiled chain loop that
#: runs the adaptive moves' burn-in itself (fit/composite/chain_loop.py).
welford_step = _welford


class BlockMove:
    """A move on one block, with a covariance learned during burn-in.

    Parameters
    ----------
    cov0 : ndarray, shape (d, d)
        Initial covariance (e.g. a Laplace approximation).
    adapt_until : int
        Iterations during which the move adapts (the burn-in).
    adapt_start : int
        Iterations with ``cov0`` before the empirical covariance takes over.

    Attributes
    ----------
    d : int
        Size of the block.
    cov : ndarray, shape (d, d)
        The covariance in use (``cov0``, then the learned one).
    steps, accepted, evaluations : int
        Calls of :meth:`step`, of them those that moved, and density evaluations.
    """

    def __init__(self, cov0: np.ndarray, *, adapt_until: int, adapt_start: int = 100) -> None:
        self._running = RunningCovariance(cov0, adapt_start)
        self.d = self._running.d
        self.cov = self._running.cov
        self.adapt_until = int(adapt_until)
        self.adapt_start = int(adapt_start)
        self._root = scaled_eigenvectors(self.cov)
        self.steps = 0
        self.accepted = 0
        self.evaluations = 0

    def step(
        self, state: BlockState, logp: LogDensity, rng: np.random.Generator, iteration: int
    ) -> tuple[BlockState, bool]:
        """One update of the block; adapts while ``iteration < adapt_until``.

        Every move has this contract.

        Parameters
        ----------
        state : BlockState
            The current block, its log-density and ``aux``.
        logp : callable
            ``logp(x) -> (log density, aux)`` (:data:`LogDensity`).
        rng : numpy.random.Generator
            The chain's generator.
        iteration : int
            Zero-based iteration number.

        Returns
        -------
        (state, moved)
            The new state (the current one when the block stayed) and whether it moved.
        """
        raise NotImplementedError

    def _learn(self, x: np.ndarray) -> None:
        """Feed a burn-in draw to the running covariance; refresh its root when it moved."""
        if self._running.update(x):
            self._refresh()

    def _refresh(self) -> None:
        """Take the running covariance and its scaled root into use."""
        self.cov = self._running.cov
        self._root = scaled_eigenvectors(self.cov)

    @property
    def acceptance(self) -> float:
        """Share of the steps that moved the block."""
        return self.accepted / max(self.steps, 1)

    @property
    def evaluations_per_step(self) -> float:
        """Density evaluations per :meth:`step` so far (the cost of one step)."""
        return self.evaluations / max(self.steps, 1)
