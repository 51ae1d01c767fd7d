"""Sufficient statistics of linear-Gaussian regressions, accumulated in one chunked pass.

Every conjugate block in loadbayes (ZIP for P and for Q, the three motor blocks) sees the
data only through the Gram matrix ``A'A`` of an augmented matrix ``A = [Z | r | 1]``:
``Z'Z``, ``Z'r``, ``r'r`` and ``n`` are sub-blocks of it. :class:`GramAccumulator`
builds that matrix from chunks of any size, in memory that does not grow with ``n``.

Reproducibility and accuracy
----------------------------
Rows are grouped into fixed blocks of ``block_rows`` rows aligned to the global row
index (not to the chunks a reader happens to deliver). Each block's Gram is summed in a
fixed order by a compiled kernel, and the block Grams are combined with
:func:`math.fsum`, which returns the correctly rounded sum whatever the order of its
terms. Hence the result is the same to the last bit for any chunk size and for any split
of the blocks between workers, and the only rounding left is inside one block (at most
``block_rows`` terms), far below the statistical error of any fit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["Gram", "GramAccumulator", "RegressionStats", "gram_of"]

BLOCK_ROWS = 1 << 14


@njit(cache=True, nogil=True)
def _block_gram(a: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    m, k = a.shape
    g = np.zeros((k, k))
    for t in range(m):
        for i in range(k):
            ai = a[t, i]
            for j in range(i, k):
                g[i, j] += ai * a[t, j]
    for i in range(k):
        for j in range(i):
            g[i, j] = g[j, i]
    return g


@dataclass(frozen=True)
class RegressionStats:
    """Sufficient statistics of one regression ``r = Z b + e``.

    Attributes
    ----------
    ztz : ndarray, shape (k, k)
        ``Z'Z``.
    ztr : ndarray, shape (k,)
        ``Z'r``.
    rtr : float
        ``r'r``.
    n : int
        Number of rows (equations).
    """

    ztz: np.ndarray
    ztr: np.ndarray
    rtr: float
    n: int

    @property
    def k(self) -> int:
        """Number of coefficients."""
        return self.ztz.shape[0]

    def __add__(self, other: RegressionStats) -> RegressionStats:
        """Stack two sets of equations that share coefficients and noise precision."""
        return RegressionStats(
            self.ztz + other.ztz, self.ztr + other.ztr, self.rtr + other.rtr, self.n + other.n
        )

    def least_squares(self) -> tuple[np.ndarray, float]:
        """Return the least-squares coefficients and the residual sum of squares."""
        coef = np.linalg.lstsq(self.ztz, self.ztr, rcond=None)[0]
        ssr = max(self.rtr - float(coef @ self.ztr), 0.0)
        return coef, ssr


@dataclass(frozen=True)
class Gram:
    """The Gram matrix ``A'A`` of named columns, with the row count and column ranges.

    Attributes
    ----------
    names : tuple of str
        Column names of ``A``.
    matrix : ndarray, shape (k, k)
        ``A'A``.
    n : int
        Number of rows accumulated.
    col_min, col_max : ndarray, shape (k,)
        Smallest and largest value of each column (to detect data with no spread).
    """

    names: tuple[str, ...]
    matrix: np.ndarray
    n: int
    col_min: np.ndarray
    col_max: np.ndarray

    def index(self, name: str) -> int:
        """Position of column ``name``."""
        return self.names.index(name)

    def regression(self, design: Sequence[str], target: str) -> RegressionStats:
        """Statistics of the regression of column ``target`` on columns ``design``."""
        d = [self.index(c) for c in design]
        t = self.index(target)
        g = self.matrix
        return RegressionStats(
            ztz=g[np.ix_(d, d)].copy(), ztr=g[d, t].copy(), rtr=float(g[t, t]), n=self.n
        )

    def mean(self, name: str) -> float:
        """Sample mean of one column (needs a column of ones named ``"1"``)."""
        return float(self.matrix[self.index(name), self.index("1")] / self.n)

    def variance(self, name: str) -> float:
        """Population variance of one column (needs a column of ones named ``"1"``)."""
        i = self.index(name)
        m = self.mean(name)
        return max(float(self.matrix[i, i] / self.n - m * m), 0.0)


class GramAccumulator:
    """Accumulate ``A'A`` over chunks of rows, bit-for-bit independent of chunking.

    Parameters
    ----------
    names : sequence of str
        Column names of ``A``; :meth:`update` takes arrays with these columns in order.
    block_rows : int, optional
        Rows per summation block (the unit of exact combination). Results are
        reproducible between runs that use the same ``block_rows``.
    """

    def __init__(self, names: Sequence[str], *, block_rows: int = BLOCK_ROWS) -> None:
        self.names = tuple(names)
        self.block_rows = int(block_rows)
        k = len(self.names)
        self._buf = np.empty((self.block_rows, k))
        self._fill = 0
        self._partials: list[np.ndarray] = []
        self._n = 0
        self._min = np.full(k, np.inf)
        self._max = np.full(k, -np.inf)

    def update(self, a: np.ndarray) -> None:
        """Add rows ``a`` (shape ``(m, k)``)."""
        a = np.ascontiguousarray(a, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != len(self.names):
            raise ValueError(f"expected an (m, {len(self.names)}) array, got {a.shape}")
        m = a.shape[0]
        if m == 0:
            return
        self._n += m
        np.minimum(self._min, a.min(axis=0), out=self._min)
        np.maximum(self._max, a.max(axis=0), out=self._max)
        pos = 0
        if self._fill:
            take = min(self.block_rows - self._fill, m)
            self._buf[self._fill : self._fill + take] = a[:take]
            self._fill += take
            pos = take
            if self._fill == self.block_rows:
                self._partials.append(_block_gram(self._buf))
                self._fill = 0
        while m - pos >= self.block_rows:
            self._partials.append(_block_gram(a[pos : pos + self.block_rows]))
            pos += self.block_rows
        rest = m - pos
        if rest:
            self._buf[:rest] = a[pos:]
            self._fill = rest

    def merge(self, other: GramAccumulator) -> None:
        """Absorb another accumulator whose rows all come after this one's.

        Both must have consumed whole blocks only (except ``other``'s tail), which holds
        when each worker is given a block-aligned range of rows.
        """
        if self._fill:
            raise ValueError("merge needs this accumulator to end on a block boundary")
        self._partials.extend(other._partials)
        self._n += other._n
        np.minimum(self._min, other._min, out=self._min)
        np.maximum(self._max, other._max, out=self._max)
        if other._fill:
            self._buf[: other._fill] = other._buf[: other._fill]
            self._fill = other._fill

    @property
    def n(self) -> int:
        """Rows accumulated so far."""
        return self._n

    def result(self) -> Gram:
        """The Gram matrix of every row so far (the accumulator stays usable)."""
        parts = list(self._partials)
        if self._fill:
            parts.append(_block_gram(self._buf[: self._fill]))
        k = len(self.names)
        g = np.zeros((k, k))
        if parts:
            stack = np.stack(parts)
            for i in range(k):
                for j in range(i, k):
                    g[i, j] = g[j, i] = math.fsum(stack[:, i, j])
        return Gram(self.names, g, self._n, self._min.copy(), self._max.copy())


def gram_of(a: np.ndarray, names: Sequence[str], *, block_rows: int = BLOCK_ROWS) -> Gram:
    """Gram matrix of an in-memory array (one-shot :class:`GramAccumulator`)."""
    acc = GramAccumulator(names, block_rows=block_rows)
    acc.update(a)
    return acc.result()
