"""Exact, order-independent sums of float64 products, in integer digits.

The fleet's statistics pass adds per-row products ``a_i a_j`` of many buses, over
partitions cut anywhere, on any number of workers. For the result to be the same to the
last bit whatever the cut, the sum must not depend on the order of its terms. Rounding
each product to float64 is deterministic (it depends on the row alone); the *sum* is
made exact: every product ``m 2^e`` (``m`` its 53-bit integer significand) is added into
an array of signed 64-bit digits of 32 bits each, a fixed-point number wide enough for
any finite float64 (a Kulisch-style long accumulator). Integer addition is associative,
so partial sums from partitions and workers combine exactly in any order, and the final
value is rounded once, correctly (:func:`to_float`).

Each added product changes at most three digits by less than ``2^33``; a digit can take
``2^30`` additions before it could overflow, so accumulators are carry-normalised
(:func:`normalize`) at least every :data:`ROWS_BEFORE_NORMALIZE` rows and after merging.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["DIGITS", "ROWS_BEFORE_NORMALIZE", "accumulate_rows", "normalize", "to_float"]

#: Digits of 32 bits: binary exponents 1..2046 (biased) put a significand's lowest bit
#: in digit ``e >> 5``, and 85 bits above it reach digit 65; two more absorb carries.
DIGITS = 68
#: Rows added between carry normalisations (well under the 2^30 a digit can take).
ROWS_BEFORE_NORMALIZE = 1 << 28
_MASK = 0xFFFFFFFF
_BIAS = 1075  # value = digits * 2^-1075 (the exponent of the smallest subnormal bit)


@njit(cache=True, nogil=True)
def _add(acc, b, p, bits):  # pragma: no cover - compiled
    """Add the float64 whose bit pattern is ``bits`` to digits ``acc[b, p]``.

    Returns False if the value is inf or NaN (nothing is added).
    """
    ex = (bits >> 52) & 0x7FF
    if ex == 0x7FF:
        return False
    mant = bits & 0xFFFFFFFFFFFFF
    if ex == 0:
        if mant == 0:
            return True
        ex = 1  # subnormal: mant * 2^(1 - 1075)
    else:
        mant |= 1 << 52
    s = ex & 31
    d = ex >> 5
    lo = (mant & _MASK) << s  # < 2^63
    hi = (mant >> 32) << s  # < 2^52
    d0 = lo & _MASK
    d1 = (lo >> 32) + (hi & _MASK)
    d2 = hi >> 32
    if bits < 0:
        acc[b, p, d] -= d0
        acc[b, p, d + 1] -= d1
        acc[b, p, d + 2] -= d2
    else:
        acc[b, p, d] += d0
        acc[b, p, d + 1] += d1
        acc[b, p, d + 2] += d2
    return True


@njit(cache=True, nogil=True)
def accumulate_rows(a, codes, acc, count, mins, maxs, bad):  # pragma: no cover - compiled
    """Add the Gram products of each row of ``a`` to the digits of its bus.

    Parameters
    ----------
    a : ndarray, shape (m, k)
        Rows of the augmented matrix.
    codes : ndarray of int64, shape (m,)
        Bus (local index) of each row.
    acc : ndarray of int64, shape (buses, k (k + 1) / 2, DIGITS)
        Digits of the upper-triangle entries ``(0,0), (0,1), ..., (k-1,k-1)``.
    count : ndarray of int64, shape (buses,)
        Rows per bus (incremented).
    mins, maxs : ndarray, shape (buses, k)
        Column ranges per bus (updated).
    bad : ndarray of bool, shape (buses,)
        Set where a product overflowed to inf (the bus's Gram is then not finite).
    """
    m, k = a.shape
    buf = np.empty(1)
    ibuf = buf.view(np.int64)
    for t in range(m):
        b = codes[t]
        count[b] += 1
        p = 0
        for i in range(k):
            x = a[t, i]
            if x < mins[b, i]:
                mins[b, i] = x
            if x > maxs[b, i]:
                maxs[b, i] = x
            for j in range(i, k):
                buf[0] = x * a[t, j]
                if not _add(acc, b, p, ibuf[0]):
                    bad[b] = True
                p += 1


@njit(cache=True, nogil=True)
def normalize(acc):  # pragma: no cover - compiled
    """Propagate carries so that every digit but the last is in ``[0, 2^32)``.

    The value is unchanged; the last digit carries the sign. Works on any leading shape.
    """
    flat = acc.reshape(-1, acc.shape[-1])
    nd = flat.shape[1]
    for r in range(flat.shape[0]):
        carry = 0
        for i in range(nd - 1):
            v = flat[r, i] + carry
            carry = v >> 32  # arithmetic shift: floor division by 2^32
            flat[r, i] = v - (carry << 32)
        flat[r, nd - 1] += carry


def to_float(digits: np.ndarray) -> np.ndarray:
    """Correctly rounded float64 value of normalised digit arrays (last axis: digits).

    Python integers hold the exact value and ``int / int`` rounds it once, to nearest.
    """
    flat = np.ascontiguousarray(digits).reshape(-1, digits.shape[-1])
    out = np.empty(flat.shape[0])
    scale = 1 << _BIAS
    top_shift = 32 * (flat.shape[1] - 1)
    low = flat[:, :-1].astype("<u4")
    for r in range(flat.shape[0]):
        n = int.from_bytes(low[r].tobytes(), "little") + (int(flat[r, -1]) << top_shift)
        try:
            out[r] = n / scale
        except OverflowError:
            out[r] = np.inf if n > 0 else -np.inf
    return out.reshape(digits.shape[:-1])
