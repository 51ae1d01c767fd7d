"""Every fit is reachable from ``loadbayes`` and its result has ``summary()``, ``plot()``
and ``to_arviz()``, with the groups ``az.loo`` and ``az.plot_ppc`` need or a one-line
error naming what is missing and why (issue 40).

Short chains: the test is of the results' interface, not of the numbers.
"""

from __future__ import annotations

import warnings

import matplotlib
import numpy as np
import pandas as pd
import pytest

import loadbayes
from loadbayes.cases.composite_sim import simulate_event
from loadbayes.cases.examples import zip_day_frame
from loadbayes.cases.motor_sim import simulate
from loadbayes.measurements.steps import find_steps
from loadbayes.models.motor_fit import DATA_COLUMNS
from loadbayes.models.zip import ZIPModel

matplotlib.use("Agg")

FAST = loadbayes.SamplerSettings(draws=300, burn=100, chains=2, seed=1)
SPEC = loadbayes.DataSpec(v_base=11, s_base=5, t_col="time")


def test_every_fit_is_reachable_from_loadbayes():
    for name in ("fit_zip", "fit_exp", "fit_im", "fit_im_file", "fit_steps", "fit_robust",
                 "fit_zip_drift", "fit_composite", "track_zip"):  # fmt: skip
        assert callable(getattr(loadbayes, name)), name
        assert name in loadbayes.__all__ and name in dir(loadbayes)
    from loadbayes import fit_exp  # noqa: F401  (the newcomer's ImportError)


@pytest.fixture(scope="module")
def day() -> pd.DataFrame:
    return zip_day_frame().iloc[:600]


def _zip(day):
    return loadbayes.fit_zip(day, spec=SPEC, sampler=FAST)


def _drift(day):
    return loadbayes.fit_zip(day, spec=SPEC, level="drift", sampler=FAST)


def _exp(day):
    return loadbayes.fit_exp(day, spec=SPEC, sampler=FAST)


def _steps(day):
    v, p, q = day["v"].to_numpy() / 11, day["p"].to_numpy() / 5, day["q"].to_numpy() / 5
    t = np.arange(len(v)) * 60.0
    steps, _ = find_steps(v, p, q, t=t)
    return loadbayes.fit_steps(v, p, q, steps=steps, t=t, sampler=FAST)


def _im(_day):
    df = simulate("krause_3hp", noise=0.05, seed=4, t_end_s=1.0)
    return loadbayes.fit_im({k: df[k].to_numpy() for k in DATA_COLUMNS}, sampler=FAST)


def _robust(_day):
    rng = np.random.default_rng(0)
    v = rng.uniform(0.95, 1.05, 200)
    p = 0.3 * v**2 + 0.3 * v + 0.4 + rng.standard_t(3, 200) * 0.002
    q = 0.4 * (0.5 * v**2 + 0.3 * v + 0.2) + rng.normal(0, 0.002, 200)
    return loadbayes.fit_robust(ZIPModel(), {"v": v, "p": p, "q": q}, sampler=FAST)


def _composite(_day):
    ev, _ = simulate_event(t_end_s=1.5, fs=60, seed=3)
    from loadbayes.fit.composite import fit_composite

    return fit_composite(loadbayes.CompositeModel(window_s=0), [ev], sampler=FAST)


FITS = {"zip": _zip, "drift": _drift, "exp": _exp, "steps": _steps, "im": _im,
        "robust": _robust, "composite": _composite}  # fmt: skip


@pytest.mark.parametrize("kind", sorted(FITS))
def test_every_result_summarises_plots_and_goes_to_arviz(kind, day):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = FITS[kind](zip_day_frame() if kind == "steps" else day)
        summary = result.summary()
        assert isinstance(summary, pd.DataFrame) and len(summary) > 0
        fig = result.plot()
        assert isinstance(fig, matplotlib.figure.Figure) and fig.axes
        matplotlib.pyplot.close(fig)
        idata = result.to_arviz()
        assert "posterior" in idata.groups()
        post = getattr(result, "posterior", result)
        if post.pointwise_missing() is None:
            assert {"log_likelihood", "posterior_predictive"} <= set(idata.groups()), kind
            assert result.loo() is not None
        else:
            assert "log_likelihood" not in idata.groups()
            with pytest.raises(ValueError) as err:
                result.loo()
            msg = str(err.value)
            assert "\n" not in msg and "log_likelihood" in msg and "az.loo" in msg


def test_a_track_says_in_one_line_what_it_lacks(day, tmp_path):
    day.to_csv(tmp_path / "bus.csv", index=False)
    track = loadbayes.track_zip(str(tmp_path / "bus.csv"), v_base=11, s_base=5, t_col="time")
    for method in ("summary", "plot", "to_arviz"):
        with pytest.raises(TypeError) as err:
            getattr(track, method)()
        assert "\n" not in str(err.value) and "iterate" in str(err.value)
