"""A DataSpec handed to a fit is the same as its keywords; keywords override it."""

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import DataSpec
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.fit.data import data_of
from loadbayes.fit.zip import fit_zip_file

FAST = {"chains": 2, "draws": 600, "burn": 100, "seed": 3}


def _frame(n=200, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.9, 1.1, n) * 400.0
    x = v / 400.0
    p = (0.3 * x**2 + 0.2 * x + 0.5 + rng.normal(0, 0.01, n)) * 1e3
    q = (0.5 * x**2 + 0.3 * x + 0.2 + rng.normal(0, 0.01, n)) * 1e3
    return pd.DataFrame({"V": v, "P": p, "Q": q})


def _same(a, b):
    assert a.draws.keys() == b.draws.keys()
    for k in a.draws:
        np.testing.assert_array_equal(a.draws[k], b.draws[k])


def test_data_of_without_a_spec_returns_the_keywords():
    assert data_of(None, fit_zip, v_col="x", p0="auto") == ("x", "auto")


def test_data_of_takes_the_spec_unless_a_keyword_changed():
    spec = DataSpec(v_col="V", p_col="P", q_col=None, v_base=400.0, p0=None, q0=-0.5)
    got = data_of(spec, fit_zip, v_col="v", p_col="W", q_col="q", v_base=None, p0="auto", q0="auto")
    assert got == ("V", "W", None, 400.0, "auto", -0.5)


def test_fit_zip_with_a_spec_is_the_fit_with_its_keywords(tmp_path):
    df = _frame()
    spec = DataSpec(v_col="V", p_col="P", q_col="Q", v_base=400.0, s_base=1e3, p0=1.0, q0=1.0)
    loose = fit_zip(
        df, v_col="V", p_col="P", q_col="Q", v_base=400.0, s_base=1e3, **FAST, p0=1.0, q0=1.0
    )
    _same(fit_zip(df, spec=spec, **FAST), loose)
    path = tmp_path / "bus.csv"
    df.to_csv(path, index=False)
    from_file, _ = fit_zip_file(str(path), spec=spec, **FAST)
    _same(from_file, fit_zip(str(path), spec=spec, **FAST))
    # a keyword changed from its default wins over the spec
    p_only = fit_zip(df, spec=spec, q_col=None, **FAST)
    assert "a4" not in p_only.draws and "a1" in p_only.draws


def test_fit_exp_with_a_spec_is_the_fit_with_its_keywords():
    df = _frame()
    spec = DataSpec(v_col="V", p_col="P", q_col=None, v_base=400.0, s_base=1e3, p0=1.0)
    loose = fit_exp(
        df, v_col="V", p_col="P", q_col=None, v_base=400.0, s_base=1e3, **FAST, p0=1.0, q0=1.0
    )
    _same(fit_exp(df, spec=spec, **FAST), loose)


def test_the_fits_keep_their_messages_for_bad_keywords():
    with pytest.raises(ValueError, match="v_base must be positive, got -1"):
        fit_zip(_frame(), spec=DataSpec(v_col="V", p_col="P", q_col="Q"), v_base=-1.0, **FAST)
