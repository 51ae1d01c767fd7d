"""The fits' sampler settings: one SamplerSettings; the old keywords refused in one line."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_robust, fit_zip
from loadbayes.fit.sampler import MODEL_DEFAULTS
from loadbayes.io.errors import OptionError

P1 = DataSpec(p0=1.0, q0=1.0)


def _data(n=300, seed=1, outlier=None):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.9, 1.1, n)
    p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, n)
    if outlier is not None:
        p[outlier] += 1.0
    return {"v": v, "p": p}


def test_defaults_are_the_papers():
    assert (MODEL_DEFAULTS.draws, MODEL_DEFAULTS.burn, MODEL_DEFAULTS.chains) == (40_000, 5_000, 4)
    assert (MODEL_DEFAULTS.thin, MODEL_DEFAULTS.init, MODEL_DEFAULTS.seed) == (1, "prior", 0)


def test_with_changes_one_setting_and_seed_none_is_kept():
    s = MODEL_DEFAULTS.with_(draws=100, burn=10)
    assert (s.draws, s.burn, s.chains) == (100, 10, 4)
    assert s.with_(seed=None).seed is None
    with pytest.raises(TypeError, match="drawz"):
        SamplerSettings.of(None, drawz=3)


def test_the_same_settings_give_the_same_draws():
    data = _data()
    smp = SamplerSettings(draws=600, burn=100, chains=2, seed=3)
    a = fit_zip(data, with_q=False, sampler=smp, warn=False, spec=P1)
    b = fit_zip(
        data,
        with_q=False,
        sampler=SamplerSettings(draws=600, burn=100, chains=2).with_(seed=3),
        warn=False,
        spec=P1,
    )
    for name in ("a1", "a2", "tau_p"):
        np.testing.assert_array_equal(a.draws[name], b.draws[name])


def test_a_bad_burn_is_refused_when_the_settings_are_built():
    with pytest.raises(ValueError, match=r"burn-in \(10\) must be smaller than the draws \(10\)"):
        fit_zip(_data(), sampler=SamplerSettings(draws=10, burn=10), spec=P1)
    old = {"draws": 10, "burn": 10}
    with pytest.raises(TypeError, match=r"^fit_zip: draws=, burn= are now sampler="):
        fit_zip(_data(), spec=P1, **old)


def test_student_t_zip_flags_the_bad_row_as_a_data_row():
    data = _data(outlier=41)
    post = fit_zip(data, with_q=False, likelihood="student-t", nu=4.0, warn=False, spec=P1,
                   sampler=SamplerSettings(draws=800, burn=200, chains=2, seed=0))  # fmt: skip
    assert 42 in post.settings["flagged_rows"]
    assert post.extra_json["flagged"] == post.settings["flagged_rows"]
    # the same draws as fit_robust on the same columns
    from loadbayes.models.zip import ZIPModel

    model = ZIPModel(p0=1.0, with_q=False)
    ref = fit_robust(
        model, data, nu=4.0, sampler=SamplerSettings(draws=800, burn=200, chains=2, seed=0)
    )
    np.testing.assert_array_equal(post.draws["a1"], ref.draws["a1"])
    with pytest.raises(OptionError, match="Gaussian-likelihood scheme"):
        fit_zip(data, likelihood="student-t", scheme="exact", spec=P1)


def test_an_old_keyword_is_one_line_naming_the_new_spelling():
    from loadbayes.fit.core import fit
    from loadbayes.fit.sampler import new_spelling
    from loadbayes.models.zip import ZIPModel

    with pytest.raises(TypeError) as err:
        fit(ZIPModel(with_q=False), _data(), **{"draws": 4000})
    assert str(err.value) == "fit: draws= is now sampler=SamplerSettings(draws=4000)"
    with pytest.raises(TypeError, match=r"^fit_robust: draws=, seed= are now "
                       r"sampler=SamplerSettings\(draws=10, seed=None\)$"):  # fmt: skip
        fit_robust(ZIPModel(with_q=False), _data(), **{"draws": 10, "seed": None})

    @new_spelling(data=("v_col", "p0", "v0"))
    def fit_toy(data, *, v0=1.0, spec=None, sampler=None):
        return v0

    assert fit_toy(None, v0=2.0) == 2.0  # a keyword the function still takes passes
    with pytest.raises(TypeError) as err:
        fit_toy(None, **{"chains": 2, "v_col": "V", "p0": "auto"})
    msg = str(err.value)
    assert msg == (
        "fit_toy: chains= is now sampler=SamplerSettings(chains=2); "
        "v_col=, p0= are now spec=DataSpec(v_col='V', p0=None)"
    )
    assert "\n" not in msg
