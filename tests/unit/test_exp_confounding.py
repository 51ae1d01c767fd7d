"""``fit exp`` says when its one level is confounded with the voltage, as ``fit zip`` does.

A day whose load level follows the hour while the voltage falls as the load rises (the
head voltage answering to the load): one level P0 reads the daily profile as voltage
dependence and the exponent comes out far below zero. The fit must say so in fit zip's
words, with the residuals' drift when it has the time of each row; a well-specified day
(constant level) must not be flagged (the drift test's false alarm is 0.1%; fixed seed).
"""

import numpy as np
import pandas as pd
from click.testing import CliRunner

from loadbayes import DataSpec, SamplerSettings, fit_exp
from loadbayes.cli import main

SAMPLER = SamplerSettings(draws=1500, burn=500, chains=2, seed=1)


def _day(confounded: bool, seed: int = 1) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    t = np.arange(1440) * 60.0
    level = 1 + 0.5 * np.clip(np.sin(2 * np.pi * (t / 3600 - 8) / 24), 0, None)
    v = 1.03 - 0.02 * (level - 1) + 0.0005 * rng.standard_normal(t.size)
    scale = level if confounded else 1.0
    p = scale * v**1.2 + 0.005 * rng.standard_normal(t.size)
    return pd.DataFrame({"time": t, "v": v, "p": p})


def test_a_confounded_level_is_said_with_the_drift_of_the_residuals():
    post = fit_exp(_day(True), spec=DataSpec(t_col="time", q_col=None), sampler=SAMPLER,
                   warn=False)  # fmt: skip
    said = [w for w in post.warnings if w.startswith("the load level changes")]
    assert len(said) == 1
    assert "dP/dV at v0 is negative" in said[0] and "residuals drift with time" in said[0]


def test_without_a_time_column_the_sign_alone_is_said_with_the_hint():
    post = fit_exp(_day(True), spec=DataSpec(q_col=None), sampler=SAMPLER, warn=False)
    said = [w for w in post.warnings if w.startswith("the load level changes")]
    assert len(said) == 1 and "(the time column: --t-col)" in said[0]


def test_a_constant_level_is_not_flagged():
    post = fit_exp(_day(False), spec=DataSpec(t_col="time", q_col=None), sampler=SAMPLER,
                   warn=False)  # fmt: skip
    assert not [w for w in post.warnings if w.startswith("the load level changes")]
    assert post.settings["residual_drift"]["p_value"] > 1e-3


def test_the_command_takes_a_time_column(tmp_path):
    data = tmp_path / "day.csv"
    _day(True).to_csv(data, index=False)
    r = CliRunner().invoke(main, ["fit", "exp", str(data), "--t-col", "time", "--q-col", "none",
                                  "--draws", "1500", "--burn", "500", "--quiet"])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "residuals drift with time" in r.output
