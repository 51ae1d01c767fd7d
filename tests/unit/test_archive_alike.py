"""Which stations are alike (``archive pool``'s verdict, :mod:`loadbayes.archive.pool_words`).

Two units' curves as the pool's draws give them: a centre off the truth by the
posterior's own spread, draws around it (a calibrated posterior), on the pool's grid of
the year. Three cases:

- the same curve, wide bands (logit sd 0.2 a coefficient: 95% bands about 0.28 wide):
  the data cannot tell. Measured (seed 0, 100 pairs): the verdict before this rule
  ("different" when P(alike) <= 0.2) said "different" in 100 of 100, the three-way rule
  in 0 (in 2 of 200 at other seeds, and 2 of 200 with bands 0.52 wide). The test asserts
  at most 5: with a true rate of 1% that fails with probability 0.06% (Binomial(100,
  0.01)), its false-alarm rate;
- the same curve, narrow bands (logit sd 0.03): "alike" in at least 95 of 100;
- curves 0.2 apart in share, bands about 0.07 wide: "different" in every pair.
"""

import numpy as np

from loadbayes.archive.pool import design
from loadbayes.archive.pool_words import alike_pairs

X, _ = design(np.arange(7.0, 365, 14.0))  # the pool's grid: every other week
TRUTH = np.array([np.log(0.3 / 0.7), 0.4, 0.0, 0.0, 0.0])


def _verdicts(sd: float, shift: float = 0.0, pairs: int = 100, seed: int = 0):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(pairs):
        beta = np.empty((2, 500, 2, 5))
        for u, truth in enumerate((TRUTH, TRUTH + np.r_[shift, 0, 0, 0, 0])):
            centre = truth + sd * rng.standard_normal(5)
            beta[:, :, u] = centre + sd * rng.standard_normal((2, 500, 5))
        out.append(alike_pairs(["a", "b"], beta, X, 0.1).iloc[0])
    return out


def test_wide_bands_of_one_curve_cannot_tell():
    rows = _verdicts(0.2)
    said = [r["verdict"] for r in rows]
    assert said.count("different") <= 5, said.count("different")
    # the old rule's evidence is still there: P(alike) low, as the spread makes it
    assert np.mean([r["prob_alike"] <= 0.2 for r in rows]) > 0.5


def test_narrow_bands_of_one_curve_are_alike():
    said = [r["verdict"] for r in _verdicts(0.03)]
    assert said.count("alike") >= 95


def test_curves_apart_are_different():
    # a logit shift of 0.95 moves a share of 0.3 to about 0.5: 0.2 apart everywhere
    rows = _verdicts(0.05, shift=0.95, pairs=20)
    assert all(r["verdict"] == "different" for r in rows)
    assert min(r["prob_apart"] for r in rows) >= 0.95


def test_the_table_has_its_columns_when_there_is_one_unit():
    one = alike_pairs(["a"], np.zeros((1, 10, 1, 5)), X, 0.1)
    assert list(one.columns) == ["a", "b", "prob_alike", "prob_apart", "max_diff_median",
                                 "verdict"]  # fmt: skip
