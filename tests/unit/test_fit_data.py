"""A DataSpec handed to a fit: the same fit from a table or a file; old keywords refused."""

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.fit.zip import fit_zip_file

FAST = SamplerSettings(chains=2, draws=600, burn=100, seed=3)


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


def test_the_old_data_keywords_are_refused_with_the_new_spelling():
    old = {"v_col": "V", "p0": "auto"}  # a dict: a call spelled the old way on purpose
    with pytest.raises(TypeError) as err:
        fit_zip(_frame(), **old)
    assert str(err.value) == "fit_zip: v_col=, p0= are now spec=DataSpec(v_col='V', p0=None)"
    with pytest.raises(
        TypeError, match=r"^fit_exp: s_base= is now spec=DataSpec\(s_base=1000.0\)$"
    ):
        fit_exp(_frame(), **{"s_base": 1e3})


def test_fit_zip_with_a_spec_is_the_same_from_a_table_and_a_file(tmp_path):
    df = _frame()
    spec = DataSpec(v_col="V", p_col="P", q_col="Q", v_base=400.0, s_base=1e3, p0=1.0, q0=1.0)
    path = tmp_path / "bus.csv"
    df.to_csv(path, index=False)
    from_file, _ = fit_zip_file(str(path), spec=spec, sampler=FAST)
    _same(from_file, fit_zip(str(path), spec=spec, sampler=FAST))
    # a spec changed with with_(): P alone
    p_only = fit_zip(df, spec=spec.with_(q_col=None), sampler=FAST)
    assert "a4" not in p_only.draws and "a1" in p_only.draws


def test_fit_exp_with_a_spec():
    df = _frame()
    spec = DataSpec(v_col="V", p_col="P", q_col=None, v_base=400.0, s_base=1e3, p0=1.0)
    post = fit_exp(df, spec=spec, sampler=FAST)
    assert set(post.draws) == {"np", "tau_p"}


def test_a_bad_spec_is_refused_when_built():
    with pytest.raises(ValueError, match="v_base must be a positive number, got -1"):
        fit_zip(_frame(), spec=DataSpec(v_col="V", p_col="P", q_col="Q", v_base=-1.0))
