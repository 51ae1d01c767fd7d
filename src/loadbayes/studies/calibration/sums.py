"""Exact Gram entries at large n, to check the chunked sums of the sufficient statistics.

The reference for an entry ``sum_i x_i y_i`` of the Gram matrix is exact: each product is
split without error into ``p + e`` (Dekker's two-product: ``p = fl(x y)`` and ``e`` its
rounding error, both floats) and all the ``p`` and ``e`` are summed by :func:`math.fsum`,
which returns the correctly rounded value of the exact sum. Data are generated chunk by
chunk from seeded generators, so memory stays bounded at any ``n``.

Error bound of :class:`~loadbayes.core.stats.GramAccumulator`: each block of ``B``
rows is summed in floating point (every term is one rounded product and goes through at
most ``B`` roundings, whatever the order inside the block), and the block sums are
combined exactly (``math.fsum``) and rounded once. Hence::

    |G - S| <= gamma(B + 1) sum_i |x_i y_i| + u |S|,   gamma(m) = m u / (1 - m u)

with ``u = 2^-53``: a bound that does not grow with ``n``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator

import numpy as np

__all__ = [
    "UNIT_ROUNDOFF",
    "exact_entry",
    "gamma",
    "gram_bound",
    "two_product",
    "zip_chunks",
]

UNIT_ROUNDOFF = 2.0**-53
_SPLIT = 2.0**27 + 1.0  # Veltkamp's splitter for float64


def gamma(m: int) -> float:
    """Higham's ``gamma_m = m u / (1 - m u)``: the bound on ``m`` successive roundings."""
    return m * UNIT_ROUNDOFF / (1.0 - m * UNIT_ROUNDOFF)


def two_product(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x * y = p + e`` exactly, with ``p = fl(x * y)`` (Dekker 1971, Veltkamp split).

    Exact for products that neither overflow nor underflow (|values| within about
    ``1e-290 .. 1e290``).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    p = x * y
    cx = _SPLIT * x
    xh = cx - (cx - x)
    xl = x - xh
    cy = _SPLIT * y
    yh = cy - (cy - y)
    yl = y - yh
    e = ((xh * yh - p) + xh * yl + xl * yh) + xl * yl
    return p, e


def exact_entry(chunks: Callable[[], Iterator[np.ndarray]], i: int, j: int) -> tuple[float, float]:
    """Correctly rounded ``sum x_i y_j`` over all rows, and ``sum |x_i y_j|``.

    Parameters
    ----------
    chunks : callable
        Returns a fresh iterator over the row chunks (arrays of shape (m, k)).
    i, j : int
        Columns.

    Returns
    -------
    (float, float)
        The exact sum rounded once, and the sum of absolute products (for the bound).
    """
    abs_sum = 0.0

    def pieces() -> Iterator[list[float]]:
        nonlocal abs_sum
        for a in chunks():
            p, e = two_product(a[:, i], a[:, j])
            abs_sum += float(np.abs(p).sum())
            yield p.tolist()
            yield e.tolist()

    exact = math.fsum(itertools.chain.from_iterable(pieces()))
    # Summed in floating point: enlarge by the worst relative error of that sum.
    return exact, abs_sum * (1.0 + 1e-9)


def gram_bound(abs_sum: float, exact: float, block_rows: int) -> float:
    """Largest ``|G - S|`` the chunked accumulator may show (module docstring)."""
    return gamma(block_rows + 1) * abs_sum + UNIT_ROUNDOFF * abs(exact)


def zip_chunks(
    n: int, *, chunk_rows: int = 1_000_000, seed: int = 0, noise: float = 0.1
) -> Callable[[], Iterator[np.ndarray]]:
    """Rows of the ZIP model's Gram columns ``(z1, z2, 1, r_p)`` for ``n`` samples.

    Voltages uniform on the bus-18 band, P from ZIP (0.25, 0.25, 0.5) with noise sd
    ``noise``. Chunk ``c`` comes from its own child of ``SeedSequence(seed)``, so every
    call of the returned function yields the same rows.
    """
    from loadbayes.models.zip import ZIPModel

    model = ZIPModel(with_q=False)
    n_chunks = -(-n // chunk_rows)

    def gen() -> Iterator[np.ndarray]:
        for c, child in enumerate(np.random.SeedSequence(seed).spawn(n_chunks)):
            m = min(chunk_rows, n - c * chunk_rows)
            rng = np.random.default_rng(child)
            v = rng.uniform(0.66, 0.89, m)
            p = 0.25 * v**2 + 0.25 * v + 0.5 + noise * rng.standard_normal(m)
            yield model.rows({"v": v, "p": p})

    return gen
