"""One contract for Python and the CLI (issue 22): units checked, P0 estimated, own words."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.io.errors import DataError
from loadbayes.posterior import FitWarning

FAST = {"draws": 600, "burn": 100, "chains": 2, "seed": 1}


def _feeder(n=300, seed=0):
    """A 6.5 MW, 13.8 kV feeder in kV / MW / Mvar: ZIP (0.3, 0.3, 0.4), Q0 2 Mvar."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.94, 1.06, n)
    return pd.DataFrame(
        {
            "V_kV": 13.8 * x,
            "P_MW": 6.5 * (0.3 * x**2 + 0.3 * x + 0.4) + rng.normal(0, 0.005, n),
            "Q_Mvar": 2.0 * (0.8 * x**2 + 0.1 * x + 0.1) + rng.normal(0, 0.005, n),
        }
    )


NAMES = {"v_col": "V_kV", "p_col": "P_MW", "q_col": "Q_Mvar"}


@pytest.mark.parametrize("fit", [fit_zip, fit_exp])
def test_a_dataframe_in_kv_and_mw_is_refused_in_python_words(fit):
    with pytest.raises(DataError) as err:
        fit(_feeder(), sampler=SamplerSettings(**FAST), spec=DataSpec(**NAMES))
    msg = str(err.value)
    assert "\n" not in msg and "column 'V_kV'" in msg
    assert "v_base=13.8" in msg and "accept_units=True" in msg
    assert "--" not in msg  # no CLI option from Python


def test_a_wrong_p0_from_python_names_the_keyword(tmp_path):
    with pytest.raises(DataError) as err:
        fit_zip(
            _feeder(), sampler=SamplerSettings(**FAST), spec=DataSpec(**NAMES, v_base=13.8, p0=1.0)
        )
    msg = str(err.value)
    assert "column 'P_MW'" in msg and "p0='auto'" in msg and "--" not in msg
    # a file from Python: the same check and the same words
    path = tmp_path / "feeder.csv"
    _feeder().to_csv(path, index=False)
    with pytest.raises(DataError) as err:
        fit_zip(str(path), sampler=SamplerSettings(**FAST), spec=DataSpec(**NAMES))
    assert "v_base=13.8" in str(err.value) and "--" not in str(err.value)


def test_accept_units_fits_anyway_with_a_warning():
    with pytest.warns(FitWarning, match="units: V / V0"):
        post = fit_zip(
            _feeder(), sampler=SamplerSettings(**FAST), spec=DataSpec(**NAMES, accept_units=True)
        )
    assert any(w.startswith("units:") for w in post.warnings)


def test_p0_is_estimated_by_default_as_in_the_cli():
    # 6.5 MW in per unit of a 10 MVA base: 0.65 p.u., which p0 = 1 would misread.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        post = fit_zip(
            _feeder(),
            sampler=SamplerSettings(**FAST),
            spec=DataSpec(**NAMES, v_base=13.8, s_base=10.0),
        )
    m = post.mean()
    assert m["p0"] == pytest.approx(0.65, abs=0.002) and m["q0"] == pytest.approx(0.2, abs=0.002)
    assert abs(m["a1"] - 0.3) < 0.1 and abs(m["a3"] - 0.4) < 0.1
    # the prediction at 13.2 kV in MW: the truth, not the -0.5 MW of p0 = 1
    x = 13.2 / 13.8
    truth = 6.5 * (0.3 * x**2 + 0.3 * x + 0.4)
    assert post.predict([13.2])["p_mean"].iloc[0] == pytest.approx(truth, abs=0.02)


def test_the_motor_fit_checks_a_dataframe_too():
    from loadbayes.fit import fit_im
    from loadbayes.models.motor_fit import DATA_COLUMNS

    n = 200
    cols = {c: np.full(n, 0.5) for c in DATA_COLUMNS}
    cols["w"] = np.full(n, 376.99)  # rad/s, not per unit
    with pytest.raises(DataError) as err:
        fit_im(pd.DataFrame(cols), sampler=SamplerSettings(**FAST))
    msg = str(err.value)
    assert "rotor speed" in msg and "accept_units=True" in msg and "--" not in msg


def test_the_composite_fit_from_python_names_the_keyword():
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite import fit_composite
    from loadbayes.measurements.record import EventRecord
    from loadbayes.models.zip_motor import CompositeModel

    t = np.arange(0.0, 2.0, 1 / 60)
    v = 11.0 * np.where((t >= 0.5) & (t < 0.7), 0.7, 1.0)
    ev = EventRecord(t, v, 0.6 * (v / 11) ** 2 + 0.4, 0.3 * (v / 11) ** 2, None, "sag.csv")
    with pytest.raises(DataError) as err:
        fit_composite(
            CompositeModel(), [ev], sampler=SamplerSettings(draws=200, burn=100, chains=2)
        )
    msg = str(err.value)
    assert "v_base=11" in msg and "accept_units=True" in msg and "--" not in msg
