"""The Python API has the CLI's options, checks and one-line errors (issue 15)."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.io.errors import DataError, LoadbayesError, OptionError
from loadbayes.posterior import FitWarning

FAST = {"draws": 600, "burn": 100, "chains": 2, "seed": 1}


def _bus(n=400, seed=0):
    """A bus in kV / MW / Mvar with a timestamp column: ZIP (0.3, 0.25, 0.45) at 11 kV, 5 MW."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.88, 1.08, n)
    return pd.DataFrame(
        {
            "stamp": pd.date_range("2026-01-01", periods=n, freq="min"),
            "V_kV": 11 * x,
            "P_MW": 5 * (0.3 * x**2 + 0.25 * x + 0.45) + rng.normal(0, 0.01, n),
            "Q_Mvar": 2 * (0.6 * x**2 + 0.1 * x + 0.3) + rng.normal(0, 0.01, n),
        }
    )


def _fit(data, sampler=None, **kw):
    """fit_zip with FAST (or ``sampler``) and a DataSpec of ``kw`` over p0 = q0 = 1."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        spec = DataSpec(**{"p0": 1.0, "q0": 1.0, **kw})
        return fit_zip(data, sampler=sampler or SamplerSettings(**FAST), spec=spec)


NAMES = {"v_col": "V_kV", "p_col": "P_MW", "q_col": "Q_Mvar", "v_base": 11.0, "s_base": 5.0}


def test_column_names_bases_and_an_unused_timestamp_column():
    post = _fit(_bus(), t_col="stamp", q0=0.4, **NAMES)
    m = post.mean()
    # 400 samples at 0.01 MW noise pin the shares within a few hundredths.
    assert abs(m["a1"] - 0.3) < 0.1 and abs(m["a3"] - 0.45) < 0.1
    assert abs(m["a4"] - 0.6) < 0.1
    assert post.settings["columns"] == {"v": "V_kV", "p": "P_MW", "q": "Q_Mvar"}
    assert post.settings["time_start"] == "2026-01-01 00:00:00"
    assert post.settings["time_end"].startswith("2026-01-01 06:39")


def test_predict_takes_and_returns_the_data_units():
    post = _fit(_bus(), p0=1.0, q0=0.4, **NAMES)  # a given P0 (the default estimates it)
    pred = post.predict([9.9, 11.0, 12.0])
    assert list(pred["v"]) == [9.9, 11.0, 12.0]
    # At V = v_base the ZIP curve is P0 = 1 p.u. = 5 MW exactly, Q0 = 0.4 p.u. = 2 Mvar.
    assert pred["p_mean"].iloc[1] == pytest.approx(5.0, abs=1e-9)
    assert pred["q_mean"].iloc[1] == pytest.approx(2.0, abs=1e-9)
    assert 4.2 < pred["p_mean"].iloc[0] < 4.8  # 0.9 p.u.: 5 * 0.9**~1 ~ 4.5 MW


def test_a_file_is_fitted_like_the_cli_does(tmp_path):
    df = _bus()
    df.to_csv(tmp_path / "bus.csv", index=False)
    from_file = _fit(str(tmp_path / "bus.csv"), q0=0.4, **NAMES)
    from_frame = _fit(df, q0=0.4, **NAMES)
    # Same data, same seed: the same draws whether read from the file or the DataFrame
    # (CSV keeps 17 significant digits, so the statistics agree to rounding).
    np.testing.assert_allclose(from_file["a1"], from_frame["a1"], rtol=1e-9, atol=1e-9)
    assert from_file.settings["data"].endswith("bus.csv")


def test_the_same_one_line_errors_as_the_cli(tmp_path):
    df = _bus(20)
    df.loc[6, "V_kV"] = -1.0
    df.to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(DataError) as in_file:
        _fit(str(tmp_path / "bad.csv"), **NAMES)
    with pytest.raises(DataError) as in_memory:
        _fit(df, **NAMES)
    # Row 7 (1-based, header excluded) in both, the same words; a CSV cell is quoted as
    # written ('-1.0'), a number in memory is shown as the number.
    same = str(in_memory.value).removeprefix("data: ")
    assert str(in_file.value).replace("'-1.0'", "-1.0").endswith(same)
    assert "column 'V_kV', row 7" in str(in_memory.value)
    assert "\n" not in str(in_memory.value)


def test_a_missing_column_names_the_columns_there():
    with pytest.raises(DataError, match=r"column 'v': not found; the columns are .*'V_kV'"):
        _fit(_bus(10))


def test_errors_are_one_documented_type():
    with pytest.raises(LoadbayesError):
        _fit(_bus(10))
    # bad settings are refused when the settings object is built (a ValueError, as
    # LoadbayesError is; core/ cannot import io/errors.py)
    with pytest.raises(ValueError, match="burn"):
        _fit(_bus(10), sampler=SamplerSettings(draws=100, burn=100), **NAMES)
    with pytest.raises(ValueError, match="v_base"):
        _fit(_bus(10), **{**NAMES, "v_base": -1.0})
    with pytest.raises(LoadbayesError, match="DataFrame"):
        _fit(42)


def test_fit_warnings_are_python_warnings_too():
    x = np.linspace(0.999, 1.001, 50)  # a band far too narrow to separate a1 from a2
    rng = np.random.default_rng(0)
    data = {"v": x, "p": 0.3 * x**2 + 0.2 * x + 0.5 + rng.normal(0, 1e-3, x.size)}
    with pytest.warns(FitWarning, match="cannot be told apart"):
        post = fit_zip(data, sampler=SamplerSettings(**FAST), spec=DataSpec(p0=1.0, q0=1.0))
    assert post.warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit_zip(
            data, warn=False, sampler=SamplerSettings(**FAST), spec=DataSpec(p0=1.0, q0=1.0)
        )  # and silent on request


def test_exp_has_the_same_options():
    df = _bus()
    x = df["V_kV"] / 11
    df["P_MW"] = 5 * x**1.4 + np.random.default_rng(3).normal(0, 0.01, len(df))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        post = fit_exp(
            df,
            sampler=SamplerSettings(**FAST),
            spec=DataSpec(
                f_col="f",
                v_col="V_kV",
                p_col="P_MW",
                q_col=None,
                v_base=11,
                s_base=5,
                p0=1.0,
                q0=1.0,
            ),
        )
    assert abs(post.mean()["np"] - 1.4) < 0.1
    assert post.predict([11.0])["p_mean"].iloc[0] == pytest.approx(5.0, rel=1e-9)


def test_repr_html_is_a_table_with_the_warnings():
    post = _fit(_bus(), q0=0.4, **NAMES)
    text = post._repr_html_()
    assert text.startswith("<div") and "<table>" in text and "a1" in text
    assert ("Warnings" in text) == bool(post.warnings)


# --- loadbayes.fit_composite: the options and checks of `fit composite` (issue 21) ---


def _sag_kv(fs=60.0, seed=0) -> pd.DataFrame:
    """A 30% sag at an 11 kV, 5 MW bus (a static load with a lagging recovery, written here)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 2.0, 1 / fs)
    x = np.where((t >= 0.5) & (t < 0.7), 0.7, 1.0)
    lag = np.exp(-np.clip(t - 0.5, 0, None) / 0.15) * ((t >= 0.5) & (t < 0.7))
    p = 0.5 * x**2 + 0.5 * (1 - 0.6 * lag) + rng.normal(0, 0.005, t.size)
    q = 0.2 * x**2 + 0.1 + 0.3 * lag + rng.normal(0, 0.005, t.size)
    return pd.DataFrame({"time": t, "V_kV": 11 * x, "P_MW": 5 * p, "Q_Mvar": 5 * q})


COMPOSITE_COLS = {"t_col": "time", "v_col": "V_kV", "p_col": "P_MW", "q_col": "Q_Mvar"}


def _kv_spec(**kw):
    """The columns of :func:`_sag_kv` and its bases (11 kV, 5 MVA)."""
    from loadbayes.core.settings import DataSpec

    return DataSpec(**COMPOSITE_COLS, **kw)


def test_fit_composite_is_the_top_package_s_with_the_cli_checks(tmp_path):
    import loadbayes
    from loadbayes import CompositeModel
    from loadbayes.fit.composite import COMPOSITE_DEFAULTS, fit_composite

    assert "fit_composite" in loadbayes.__all__ and loadbayes.fit_composite is fit_composite
    path = tmp_path / "sag.csv"
    _sag_kv().to_csv(path, index=False)
    spec = _kv_spec(v_base=11, s_base=5)
    # Model options refused as the CLI refuses them, when the model is built.
    for kw, match in (
        ({"torque": (1, 1, 0)}, "A \\+ B \\+ C must be 1"),
        ({"nu": 4}, "nu needs likelihood 'student-t'"),
        ({"priors": {"xx": (1.0, 0.5)}}, "NAME must be one of rs, x_prime"),
        ({"priors": {"h_s": (-1.0, 0.5)}}, "positive and finite"),
        ({"f_hz": 5}, "10-1000 Hz"),
    ):
        with pytest.raises(OptionError, match=match):
            CompositeModel(**kw)
    # Iterations no sampler can run: refused when the settings are built.
    with pytest.raises(ValueError, match="burn"):
        COMPOSITE_DEFAULTS.with_(draws=100, burn=100)
    # A negative seed: refused by the fit before any reading or sampling.
    with pytest.raises(OptionError, match="seed"):
        loadbayes.fit_composite(CompositeModel(), str(path), spec=spec,
                                sampler=COMPOSITE_DEFAULTS.with_(seed=-1))  # fmt: skip
    # kV without --v-base: the one-line unit error of `fit zip` (a traceback before).
    with pytest.raises(DataError, match=r"sag.csv: column 'V_kV'.*not per unit.*v_base"):
        loadbayes.fit_composite(CompositeModel(), str(path), spec=_kv_spec())
    # A table is checked as a file is: column and 1-based row.
    bad = _sag_kv()
    bad.loc[10, "time"] = bad.loc[8, "time"]
    with pytest.raises(DataError, match=r"column 'time', row 11.*does not increase"):
        loadbayes.fit_composite(CompositeModel(), bad, spec=spec)
    # One recording given twice (a table twice, or a file and its copy): refused, from
    # Python as from the CLI (it was fitted as two events, intervals narrower by sqrt 2).
    with pytest.raises(DataError, match="this recording is given twice"):
        loadbayes.fit_composite(CompositeModel(), [_sag_kv(), _sag_kv()], spec=spec)
    (tmp_path / "copy.csv").write_bytes(path.read_bytes())
    with pytest.raises(DataError, match=r"copy.csv: column 'V_kV': the same recording as"):
        loadbayes.fit_composite(CompositeModel(), [str(path), str(tmp_path / "copy.csv")],
                                spec=spec)  # fmt: skip


def test_fit_composite_names_the_new_place_of_an_old_keyword():
    # The options moved into objects (issue 34): a call written for the old signature
    # gets one line saying what to write instead, not Python's bare TypeError.
    import loadbayes
    from loadbayes import CompositeModel
    from loadbayes.fit.composite.api import read

    df = _sag_kv()
    with pytest.raises(TypeError, match=r"draws= is now sampler=SamplerSettings\(draws=100\)"):
        loadbayes.fit_composite(CompositeModel(), df, draws=100)
    with pytest.raises(TypeError) as err:
        loadbayes.fit_composite(CompositeModel(), df, torque="estimate", v_col="V_kV")
    msg = str(err.value)
    assert "\n" not in msg
    assert "torque= is now model=CompositeModel(torque='estimate')" in msg
    assert "v_col= is now spec=DataSpec(v_col='V_kV')" in msg
    with pytest.raises(TypeError, match=r"v_base= is now spec=DataSpec\(v_base=11\)"):
        read(df, v_base=11)


def test_fit_composite_without_a_model_says_what_to_write():
    import loadbayes

    df = _sag_kv()
    for call in (lambda: loadbayes.fit_composite(df), lambda: loadbayes.fit_composite(df, df)):
        with pytest.raises(TypeError, match=r"fit_composite\(CompositeModel\(\.\.\.\), data"):
            call()


def test_fit_composite_takes_event_ids_written_as_text():
    from loadbayes.fit.composite.api import read

    a, b = _sag_kv(), _sag_kv()
    b["V_kV"] = 11.0 - (11.0 - b["V_kV"]) * 1.5  # a deeper sag of the same load
    both = pd.concat([a.assign(event="sag A"), b.assign(event=" sag B ")])
    events = read(both, _kv_spec(v_base=11.0, s_base=5.0))
    assert [e.name for e in events] == ["data[event=sag A]", "data[event=sag B]"]
    assert events[0].n == len(a) and events[1].n == len(b)


def test_fit_composite_reads_files_and_tables_alike(tmp_path):
    import loadbayes
    from loadbayes import CompositeModel, SamplerSettings

    path = tmp_path / "sag.csv"
    df = _sag_kv()
    df.to_csv(path, index=False)
    run = {"spec": _kv_spec(v_base=11.0, s_base=5.0),
           "sampler": SamplerSettings(draws=120, burn=60, chains=1, seed=2)}  # fmt: skip
    a = loadbayes.fit_composite(CompositeModel(), str(path), **run).posterior
    b = loadbayes.fit_composite(CompositeModel(), df, **run).posterior
    assert a.settings["files"] == [str(path)] and "files" not in b.settings
    # Per unit after the bases: P0 = 5 MW / 5 MVA = 1, Q0 = 1.5 Mvar / 5 = 0.3.
    assert a.mean()["p0"] == pytest.approx(1.0, abs=0.01)
    assert a.mean()["q0"] == pytest.approx(0.3, abs=0.01)
    np.testing.assert_allclose(a.draws["f_m"], b.draws["f_m"], rtol=1e-6)
