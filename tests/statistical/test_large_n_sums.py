"""The chunked sufficient statistics agree with exact sums at large n.

Ten million rows of the ZIP model's Gram columns (z1 = x^2 - 1, z2 = x - 1, 1, r = y - 1;
bus-18 band, noise sd 0.1) go through ``GramAccumulator`` in chunks of a million; three
entries are compared with their exact value (each product split without error by
Dekker's two-product, every piece summed by ``math.fsum``, rounded once):
``z1'z1`` (positive terms), ``z1'r`` (mixed signs) and ``1'r`` (heavy cancellation).

Tolerance: the accumulator's rigorous bound ``gamma(B + 1) sum|x y| + u |S|`` (B = rows
per block, u = 2^-53; about 1.8e-12 of ``sum|x y|``, independent of n), and a stated
typical tolerance of 1e-14 of ``sum|x y|`` (the measured error is 0: the result is the
correctly rounded sum). ``make validate`` runs all ten entries at 1e8 rows. These checks
are deterministic (fixed data); no false alarms.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from loadbayes.core.stats import GramAccumulator
from loadbayes.studies.calibration.sums import exact_entry, gram_bound, two_product, zip_chunks

pytestmark = pytest.mark.statistical

COLUMNS = ("z1", "z2", "1", "rp")
TYPICAL = 1e-14


def test_the_exact_reference_is_exact():
    rng = np.random.default_rng(7)
    x = rng.standard_normal(3000) * 10.0 ** rng.integers(-30, 30, 3000)
    y = rng.standard_normal(3000) * 10.0 ** rng.integers(-30, 30, 3000)
    p, e = two_product(x, y)
    for a, b, pp, ee in zip(x, y, p, e, strict=True):
        assert Fraction(a) * Fraction(b) == Fraction(pp) + Fraction(ee)
    a = np.column_stack([x, y])
    exact, _ = exact_entry(lambda: iter([a[:1000], a[1000:]]), 0, 1)
    truth = sum((Fraction(u) * Fraction(v) for u, v in zip(x, y, strict=True)), Fraction(0))
    assert exact == float(truth)


def test_chunked_gram_matches_exact_sums_at_ten_million_rows():
    n = 10_000_000
    chunks = zip_chunks(n, seed=2018)
    acc = GramAccumulator(COLUMNS)
    for a in chunks():
        acc.update(a)
    gram = acc.result()
    assert gram.n == n and gram.matrix[2, 2] == n
    for ci, cj in (("z1", "z1"), ("z1", "rp"), ("1", "rp")):
        i, j = COLUMNS.index(ci), COLUMNS.index(cj)
        exact, abs_sum = exact_entry(chunks, i, j)
        err = abs(gram.matrix[i, j] - exact)
        assert err <= gram_bound(abs_sum, exact, acc.block_rows), (ci, cj, err, abs_sum)
        assert err <= TYPICAL * abs_sum, (ci, cj, err / abs_sum)


def test_the_same_bits_for_any_chunking():
    rows = np.concatenate(list(zip_chunks(2_000_000, chunk_rows=500_000, seed=3)()))
    ref = None
    for size in (2_000_000, 999_983, 65_536, 12_345):
        acc = GramAccumulator(COLUMNS)
        for start in range(0, rows.shape[0], size):
            acc.update(rows[start : start + size])
        m = acc.result().matrix
        if ref is None:
            ref = m
        np.testing.assert_array_equal(m, ref)
    # and through an odd split of the same rows into two accumulators merged
    first, second = GramAccumulator(COLUMNS), GramAccumulator(COLUMNS)
    cut = 16_384 * 37
    for start in range(0, cut, 300_000):
        first.update(rows[start : min(start + 300_000, cut)])
    second.update(rows[cut:])
    first.merge(second)
    np.testing.assert_array_equal(first.result().matrix, ref)
