"""Sufficient statistics of linear-Gaussian regressions, accumulated in one chunked pass.

Every conjugate block in loadbayes (ZIP for P and for Q, the three motor blocks) sees the
data only through the Gram matrix ``A'A`` of an augmented matrix ``A = [Z | r | 1]``:
``Z'Z``, ``Z'r``, ``r'r`` and ``n`` are sub-blocks of it. :class:`GramAccumulator`
builds that matrix from chunks of any size, in memory that does not grow with ``n``.

Reproducibility and accuracy
----------------------------
Rows are grouped into fixed blocks of ``block_rows`` rows aligned to the global row
index (not to the chunks a reader happens to deliver). Each block's Gram is summed in a
fixed order by a compiled kernel (four interleaved partial sums, rows ``t = 0, 1, 2, 3
mod 4``, added pairwise at the end), and the block Grams are combined with
:func:`math.fsum`, which returns the correctly rounded sum whatever the order of its
terms. Hence the result is the same to the last bit for any chunk size, for any number
of threads and for any split of the blocks between workers, and the only rounding left
is inside one block (four sums of at most ``block_rows / 4`` terms), far below the
statistical error of any fit.

Speed
-----
One pass over the rows computes the Gram and the column ranges together. The blocks of
a chunk are shared between threads (the kernel releases the GIL), each block written to
its own slot, so threads change nothing in the result. Threads are plain Python threads
started per call, not numba's ``parallel=True`` pool: that keeps the accumulator safe to
call from several threads at once (a Dask worker) and after ``fork``.
``LOADBAYES_NUM_THREADS`` caps the threads (default: the CPUs this process may use).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from loadbayes.core.parallel import num_threads, run_threads

__all__ = ["Gram", "GramAccumulator", "RegressionStats", "gram_of"]

BLOCK_ROWS = 1 << 14


#: Rows per thread below which a chunk is not worth splitting between threads.
_MIN_ROWS_PER_THREAD = 1 << 16


@njit(cache=True, nogil=True)
def _block_by_rows(a, lo, hi, acc, mins, maxs):  # pragma: no cover - compiled
    """Partial sums of rows ``lo:hi`` into ``acc`` (pairs by lanes), and column ranges."""
    k = a.shape[1]
    hi4 = lo + ((hi - lo) // 4) * 4
    for t in range(lo, hi4, 4):
        p = 0
        for i in range(k):
            x0 = a[t, i]
            x1 = a[t + 1, i]
            x2 = a[t + 2, i]
            x3 = a[t + 3, i]
            mins[i] = min(mins[i], min(min(x0, x1), min(x2, x3)))
            maxs[i] = max(maxs[i], max(max(x0, x1), max(x2, x3)))
            for j in range(i, k):
                acc[p, 0] += x0 * a[t, j]
                acc[p, 1] += x1 * a[t + 1, j]
                acc[p, 2] += x2 * a[t + 2, j]
                acc[p, 3] += x3 * a[t + 3, j]
                p += 1
    for t in range(hi4, hi):
        p = 0
        for i in range(k):
            x = a[t, i]
            mins[i] = min(mins[i], x)
            maxs[i] = max(maxs[i], x)
            for j in range(i, k):
                acc[p, t - hi4] += x * a[t, j]
                p += 1


@njit(cache=True, nogil=True)
def _gram_blocks(a, block_rows, grams, mins, maxs):  # pragma: no cover - compiled
    """Gram matrix, column minima and maxima of each block of ``block_rows`` rows of ``a``.

    Block ``b`` covers rows ``b * block_rows`` up to the next block or the end of ``a``.
    Within a block, row ``t`` (counted from the block's first row) adds to partial sum
    ``t mod 4``, in increasing ``t``; the four partial sums are added as
    ``(s0 + s1) + (s2 + s3)``. The order depends on the row index alone.
    """
    m, k = a.shape
    acc = np.empty((k * (k + 1) // 2, 4))
    for b in range(grams.shape[0]):
        lo = b * block_rows
        hi = min(lo + block_rows, m)
        acc[:] = 0.0
        mins[b, :] = np.inf
        maxs[b, :] = -np.inf
        _block_by_rows(a, lo, hi, acc, mins[b], maxs[b])
        p = 0
        for i in range(k):
            for j in range(i, k):
                s = (acc[p, 0] + acc[p, 1]) + (acc[p, 2] + acc[p, 3])
                grams[b, i, j] = s
                grams[b, j, i] = s
                p += 1
            if grams[b, i, i] != grams[b, i, i]:  # a NaN in the column: its range is NaN
                mins[b, i] = np.nan
                maxs[b, i] = np.nan


def _grams(a: np.ndarray, block_rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-block Grams, minima and maxima of ``a`` (the last block may be short)."""
    m, k = a.shape
    nb = -(-m // block_rows)
    grams = np.empty((nb, k, k))
    mins = np.empty((nb, k))
    maxs = np.empty((nb, k))
    workers = min(num_threads(), nb, max(m // _MIN_ROWS_PER_THREAD, 1))
    bounds = [nb * w // workers for w in range(workers + 1)]

    def task(b0: int, b1: int) -> Callable[[], None]:
        rows = a[b0 * block_rows : b1 * block_rows]
        return lambda: _gram_blocks(rows, block_rows, grams[b0:b1], mins[b0:b1], maxs[b0:b1])

    run_threads([task(b0, b1) for b0, b1 in zip(bounds, bounds[1:], strict=False)])
    return grams, mins, maxs


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
        if self.block_rows < 1:
            raise ValueError(f"block_rows must be >= 1, got {block_rows}")
        k = len(self.names)
        self._buf = np.empty((self.block_rows, k))
        self._fill = 0
        self._partials: list[np.ndarray] = []  # arrays of block Grams, (blocks, k, k)
        self._n = 0
        self._min = np.full(k, np.inf)
        self._max = np.full(k, -np.inf)

    def _add_blocks(self, a: np.ndarray) -> None:
        grams, mins, maxs = _grams(a, self.block_rows)
        self._partials.append(grams)
        self._min = _min_of(self._min, mins)
        self._max = _max_of(self._max, maxs)

    def update(self, a: np.ndarray) -> None:
        """Add rows ``a`` (shape ``(m, k)``; C order avoids a copy)."""
        a = np.ascontiguousarray(a, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != len(self.names):
            raise ValueError(f"expected an (m, {len(self.names)}) array, got {a.shape}")
        m = a.shape[0]
        if m == 0:
            return
        self._n += m
        pos = 0
        if self._fill:
            take = min(self.block_rows - self._fill, m)
            self._buf[self._fill : self._fill + take] = a[:take]
            self._fill += take
            pos = take
            if self._fill == self.block_rows:
                self._add_blocks(self._buf)
                self._fill = 0
        whole = (m - pos) // self.block_rows * self.block_rows
        if whole:
            self._add_blocks(a[pos : pos + whole])
            pos += whole
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
        if other.block_rows != self.block_rows or other.names != self.names:
            raise ValueError("merge needs the same columns and block_rows")
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
        lo, hi = self._min.copy(), self._max.copy()
        if self._fill:
            grams, mins, maxs = _grams(self._buf[: self._fill], self.block_rows)
            parts.append(grams)
            lo, hi = _min_of(lo, mins), _max_of(hi, maxs)
        k = len(self.names)
        g = np.zeros((k, k))
        if parts:
            stack = np.concatenate(parts)
            for i in range(k):
                for j in range(i, k):
                    g[i, j] = g[j, i] = math.fsum(stack[:, i, j].tolist())
        return Gram(self.names, g, self._n, lo, hi)


def _min_of(current: np.ndarray, mins: np.ndarray) -> np.ndarray:
    """Column minima so far and of new blocks; a NaN anywhere stays NaN (as np.minimum)."""
    return np.minimum(current, mins.min(axis=0))


def _max_of(current: np.ndarray, maxs: np.ndarray) -> np.ndarray:
    return np.maximum(current, maxs.max(axis=0))


def gram_of(a: np.ndarray, names: Sequence[str], *, block_rows: int = BLOCK_ROWS) -> Gram:
    """Gram matrix of an in-memory array (one-shot :class:`GramAccumulator`)."""
    acc = GramAccumulator(names, block_rows=block_rows)
    acc.update(a)
    return acc.result()
