"""Printed digits follow the interval where a heavy tail inflates the sd (core/display.py)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from loadbayes.core.display import precision_sd, summary_rows


def _summary(x: np.ndarray) -> pd.DataFrame:
    lo, hi = np.quantile(x, [0.025, 0.975])
    row = {"mean": x.mean(), "sd": x.std(), "hdi_low": lo, "hdi_high": hi,
           "ess_bulk": 1000.0, "r_hat": 1.0}  # fmt: skip
    return pd.DataFrame([row], index=["a1"])


def test_a_ridge_tail_does_not_round_the_interval_away():
    # Draws of a share along a ridge: most within a few hundred, 0.1% far out (as the
    # real record's a1: sd 41,000 beside an interval of -593 to 560).
    rng = np.random.default_rng(0)
    x = rng.normal(-230.0, 300.0, 40_000)
    x[:40] = rng.choice([-1.0, 1.0], 40) * 1.2e6
    (row,) = summary_rows(None, summary=_summary(x))
    lo, hi = np.quantile(x, [0.025, 0.975])
    # Read back, the printed ends are within 5% of the interval's width of the true ends.
    for text, true in ((row["low"], lo), (row["high"], hi), (row["mean"], x.mean())):
        assert abs(float(text.replace(",", "")) - true) < 0.05 * (hi - lo), (row, true)


def test_a_normal_row_prints_as_before():
    # The sd sets the digits wherever it is near what the interval implies.
    assert precision_sd(0.037, 0.2, 0.345) == 0.037
    rng = np.random.default_rng(1)
    x = rng.normal(0.268, 0.037, 4_000)
    (row,) = summary_rows(None, summary=_summary(x))
    assert row["mean"] == f"{round(x.mean(), 3):.3f}"
