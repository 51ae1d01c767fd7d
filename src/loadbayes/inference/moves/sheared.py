"""Adaptive Metropolis in coordinates that straighten a curved ridge (a polynomial shear).

Knows no physics: a block is a vector ``x`` and a log-density callable.

A random-walk proposal with one covariance moves well along a straight ridge and badly
along a bent one: the proposal's width across the ridge must be the ridge's, so its
steps along it are short, and a bend makes every long step leave it. This move learns
the bend in the first half of the burn-in and removes it for the rest of the run:

- the first half of the burn-in is :class:`~loadbayes.inference.moves.adaptive_metropolis.
  AdaptiveMetropolis` as is;
- at mid burn-in, with the block standardised by the draws' mean ``m`` and sds ``D``
  (``y = (x - m) / D``), the pivot ``s = e . y`` is the position along the draws' first
  principal direction ``e``; each coordinate across it, ``r = y - s e``, is regressed on
  ``s^2`` and ``s^3`` (the linear part is nil by construction), giving the ridge's bend
  ``H(s)``, orthogonal to ``e``, with ``s`` clipped to the range the draws covered;
- from then on the chain moves ``w = y - H(e . y)``: a shear (``e . w = s``, so
  ``y = w + H(e . w)``), whose Jacobian is one, so the Metropolis ratio is the density
  ratio as before; the second half of the burn-in learns the covariance and scale in
  ``w`` (started from the first half's draws, transformed) and then all freeze.

The kept draws therefore come from a fixed Metropolis kernel in fixed coordinates, as
with :class:`AdaptiveMetropolis`. When the bend explains little (no coordinate's
``R^2`` above :data:`MIN_R2`) the shear is left out and the move is AM in standardised
coordinates; with a burn-in too short to learn it from (fewer than
:data:`MIN_HISTORY` draws in its second quarter) the move is AM, draw for draw.
"""

from __future__ import annotations

import numba
import numpy as np

from loadbayes.inference.moves.adaptive_metropolis import AdaptiveMetropolis
from loadbayes.inference.moves.base import BlockState, LogDensity, RunningCovariance

__all__ = ["MIN_HISTORY", "MIN_R2", "Shear", "ShearedAM", "sheared", "unsheared"]

#: The bend is used when it explains at least this share of some coordinate's variance
#: across the principal direction.
MIN_R2 = 0.2
#: ... and is learned only from at least this many burn-in draws (the second quarter of
#: a burn-in of 2,000 or more): from the 100 draws of a 400-iteration burn-in it was a
#: wrong bend, and 200 short fits covered T' at 88% (test_composite_recovery).
MIN_HISTORY = 500


def _bend(y: np.ndarray, e: np.ndarray):
    """The bend of standardised draws ``y`` across pivot ``e``.

    Returns (coefficients (2, d) orthogonal to ``e``, R^2 per coordinate, the pivots
    ``s``).
    """
    s = y @ e
    r = y - np.outer(s, e)
    basis = np.stack([s**2 - np.mean(s**2), s**3], axis=1)
    coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
    coef -= np.outer(coef @ e, e)  # keep H orthogonal to e
    fitted = basis @ coef
    var = r.var(axis=0)
    r2 = np.where(var > 0, 1.0 - (r - fitted).var(axis=0) / np.where(var > 0, var, 1), 0.0)
    return coef, r2, s


class Shear:
    """``w = y - H(e . y)`` with ``y = (x - m) / D`` and ``H(s) = A [s^2, s^3]`` (clipped ``s``).

    Parameters
    ----------
    draws : ndarray, shape (n, d)
        Draws of the block the bend is learned from.
    """

    def __init__(self, draws: np.ndarray) -> None:
        draws = np.asarray(draws, dtype=float)
        self.m = draws.mean(axis=0)
        self.D = np.where(draws.std(axis=0) > 0, draws.std(axis=0), 1.0)
        y = (draws - self.m) / self.D
        _, v = np.linalg.eigh(np.cov(y, rowvar=False))
        # The pivot is the first principal direction. Choosing, of all principal
        # directions and coordinate axes, the one across which the draws bend most
        # found spurious bends in a chain's poorly mixed burn-in: min ESS 5-14 against
        # 214-291 on issue 21's events (docs/composite.md, "A bent ridge, straightened").
        # Contiguous, not eigh's strided column: BLAS sums e . y in another order over a
        # stride, so a copy (a pickled move, a restart's deepcopy, the compiled chain's)
        # stepped differently in the last bit from the original (docs/composite.md,
        # "Models of parts in processes").
        self.e = np.ascontiguousarray(v[:, -1])
        coef, self.r2, s = _bend(y, self.e)
        self.s_lo, self.s_hi = float(s.min()), float(s.max())
        self.active = bool(np.max(self.r2) >= MIN_R2)
        self.coef = coef if self.active else np.zeros_like(coef)
        self.c2 = float(np.mean(s**2))

    def _h(self, s: float) -> np.ndarray:
        a, b = self._powers(s)
        return a * self.coef[0] + b * self.coef[1]

    def _powers(self, s: float) -> tuple[float, float]:
        # H(s)'s factors of A's two rows: s^2 less its mean, s^3 (s clipped).
        s = min(max(s, self.s_lo), self.s_hi)
        return s * s - self.c2, s**3

    def forward(self, x: np.ndarray) -> np.ndarray:
        """``w`` of a block ``x``."""
        y = (x - self.m) / self.D
        c0, c1 = self._rows()
        return _sheared(y, *self._powers(float(y @ self.e)), c0, c1)

    def forward_rows(self, xs: np.ndarray) -> np.ndarray:
        """``w`` of each row of ``xs`` (n, d): :meth:`forward`'s arithmetic, vectorised.

        The same elementwise operations; the pivots ``e . y`` are one matrix-vector
        product, which may round differently from the rows' dot products in the last bit.
        """
        y = (np.asarray(xs, dtype=float) - self.m) / self.D
        s = np.clip(y @ self.e, self.s_lo, self.s_hi)
        c0, c1 = self._rows()
        return y - ((s * s - self.c2)[:, None] * c0 + (s**3)[:, None] * c1)

    def inverse(self, w: np.ndarray) -> np.ndarray:
        """The block ``x`` of ``w``."""
        c0, c1 = self._rows()
        return _unsheared(w, *self._powers(float(w @ self.e)), c0, c1, self.m, self.D)

    def _rows(self) -> tuple[np.ndarray, np.ndarray]:
        # A's rows as contiguous arrays for the compiled maps (made once: the step's).
        rows = self.__dict__.get("_coef_rows")
        if rows is None or rows[0] is not self.coef:
            c = np.asarray(self.coef, dtype=float)
            rows = self._coef_rows = (self.coef, np.ascontiguousarray(c[0]),
                                      np.ascontiguousarray(c[1]))  # fmt: skip
        return rows[1], rows[2]


# The shear's elementwise arithmetic compiled (every step maps a point each way): NumPy's
# own operations, one element at a time, in its order (no fused multiply-add), so the
# same numbers; the dot product e . y stays NumPy's.
@numba.njit(cache=True, nogil=True)
def _sheared(y, a, b, c0, c1):  # pragma: no cover - compiled
    # y - H: y - (a c0 + b c1)
    out = np.empty(y.size)
    for i in range(y.size):
        out[i] = y[i] - (a * c0[i] + b * c1[i])
    return out


@numba.njit(cache=True, nogil=True)
def _unsheared(w, a, b, c0, c1, m, d):  # pragma: no cover - compiled
    # m + D (w + H): m + D (w + (a c0 + b c1))
    out = np.empty(w.size)
    for i in range(w.size):
        out[i] = m[i] + d[i] * (w[i] + (a * c0[i] + b * c1[i]))
    return out


#: The shear's maps on arrays, compiled: for a compiled chain loop to call
#: (fit/composite/chain_loop.py). ``sheared(y, a, b, c0, c1)``; ``unsheared(w, a, b, c0,
#: c1, m, d)``.
sheared, unsheared = _sheared, _unsheared


class ShearedAM(AdaptiveMetropolis):
    """Adaptive Metropolis that straightens the posterior's main bend at mid burn-in.

    Parameters
    ----------
    cov0 : ndarray, shape (d, d)
        Initial proposal covariance (before scaling), e.g. a Laplace approximation.
    adapt_until : int
        Iterations during which the move adapts (the burn-in); the shear is learned at
        half of it from the draws of its second quarter, when they are at least
        :data:`MIN_HISTORY` (else the move is :class:`AdaptiveMetropolis` throughout).
    adapt_start : int
        Iterations with ``cov0`` before the empirical covariance takes over.
    target : float
        Acceptance rate the scale is tuned towards.
    independence : float
        Share of the steps after burn-in that are jumps, from a t fitted in the sheared
        coordinates (:class:`AdaptiveMetropolis`).
    """

    def __init__(
        self,
        cov0: np.ndarray,
        *,
        adapt_until: int,
        adapt_start: int = 100,
        target: float = 0.234,
        independence: float = 0.0,
    ) -> None:
        super().__init__(cov0, adapt_until=adapt_until, adapt_start=adapt_start, target=target,
                         independence=independence)  # fmt: skip
        self.shear: Shear | None = None
        self._switch = adapt_until // 2
        self._min_history = max(MIN_HISTORY, 10 * self.d)
        self._history: list[np.ndarray] = []
        self._walk_last: tuple | None = None  # (shear, x's bytes, w): _walk's last

    def step(
        self, state: BlockState, logp: LogDensity, rng: np.random.Generator, iteration: int
    ) -> tuple[BlockState, bool]:
        """One Metropolis step (in the sheared coordinates after mid burn-in).

        The contract is :meth:`BlockMove.step`'s.
        """
        self.learn_shear(iteration)
        out = super().step(state, logp, rng, iteration)
        if self.shear is None and self._switch // 2 <= iteration < self._switch:
            self._history.append(np.array(out[0].x, dtype=float))
        return out

    def learn_shear(self, iteration: int) -> None:
        """At mid burn-in (``iteration`` the switch): the shear learned, or not (too few draws).

        :meth:`step` calls it first; a compiled chain loop that runs the steps itself calls
        it before each run of them (fit/composite/chain_fast.py).
        """
        if self.shear is None and iteration == self._switch:
            if len(self._history) >= self._min_history:
                self.use_shear(Shear(np.array(self._history)))
            self._history = []

    def _walk(self, x: np.ndarray) -> np.ndarray:
        # The walk's coordinates of the current block, asked each step: kept while the
        # block is the same to the bit (a rejected step leaves it), under the same shear.
        if self.shear is None:
            return x
        key, last = x.tobytes(), self._walk_last
        if last is not None and last[0] is self.shear and last[1] == key:
            return last[2]
        w = self.shear.forward(x)
        self._walk_last = (self.shear, key, w)
        return w

    def _block(self, w: np.ndarray) -> np.ndarray:
        return w if self.shear is None else self.shear.inverse(w)

    def _walk_rows(self, xs: np.ndarray) -> np.ndarray:
        if self.shear is None:
            return super()._walk_rows(xs)
        return self.shear.forward_rows(xs)

    def use_shear(self, shear: Shear, draws: np.ndarray | None = None) -> None:
        """Move in ``shear``'s coordinates from now on; the covariance restarts there.

        ``draws`` (default: this chain's second quarter) seed the covariance in ``w``.
        """
        hist = np.array(self._history) if draws is None else np.asarray(draws)
        self._history = []
        self.shear = shear
        w = np.array([shear.forward(h) for h in hist])
        self._running = RunningCovariance(np.cov(w, rowvar=False), self.adapt_start)
        for row in w:
            self._running.update(row)
        self._refresh()
