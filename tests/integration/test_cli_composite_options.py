"""``fit composite --likelihood student-t`` and ``--torque estimate``: JSON, bad values."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.cli import main

#: The fit's announced-cost probe is skipped (tests/conftest.py: no_cost_probe): no test
#: here checks the announcement, and the draws do not depend on it.
pytestmark = [pytest.mark.integration, pytest.mark.usefixtures("no_cost_probe")]

SHORT = ["--draws", "300", "--burn", "150", "--chains", "2", "--quiet"]


def _csv(path):
    ev, _ = simulate_event("small_industrial", depth=0.3, seed=1, t_end_s=2.0)
    pd.DataFrame({"t_s": ev.t, "v": ev.v, "p": ev.p, "q": ev.q}).to_csv(path, index=False)


def _run(*args):
    return CliRunner().invoke(main, ["fit", "composite", *map(str, args)])


def test_student_t_json_names_nu_and_flagged(tmp_path):
    _csv(tmp_path / "sag.csv")
    out = tmp_path / "comp.json"
    res = _run(tmp_path / "sag.csv", "--json", out, "--likelihood", "student-t", *SHORT)
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    assert "nu_p" in d["parameters"] and "nu_q" in d["parameters"]
    assert d["settings"]["likelihood"] == "student-t"
    assert set(d["settings"]["flagged"]) == {"p", "q"}
    out2 = tmp_path / "fixed.json"
    res = _run(
        tmp_path / "sag.csv", "--json", out2, "--likelihood", "student-t", "--nu", "4", *SHORT
    )
    assert res.exit_code == 0, res.output
    d = json.loads(out2.read_text())
    assert "nu_p" not in d["parameters"] and d["settings"]["nu"] == 4.0


@pytest.mark.parametrize(
    "extra",
    [
        ["--likelihood", "student-t", "--nu", "x"],
        ["--likelihood", "student-t", "--nu", "-2"],
        ["--nu", "4"],
    ],
)
def test_bad_nu_exits_2(tmp_path, extra):
    _csv(tmp_path / "sag.csv")
    res = _run(tmp_path / "sag.csv", "--json", tmp_path / "o.json", *extra, *SHORT)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output


def test_torque_estimate_reports_shares_with_their_spread(tmp_path):
    _csv(tmp_path / "sag.csv")
    out = tmp_path / "comp.json"
    res = _run(tmp_path / "sag.csv", "--json", out, "--torque", "estimate", *SHORT)
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    for name in ("a", "b", "c"):
        assert d["parameters"][name]["sd"] > 0
    assert d["settings"]["torque"] == "estimate"
    assert "torque" in d["identifiability"]


@pytest.mark.parametrize("bad", ["1,1", "x", "0.5,0.5,0.5", "estimate,1"])
def test_bad_torque_exits_2(tmp_path, bad):
    _csv(tmp_path / "sag.csv")
    res = _run(tmp_path / "sag.csv", "--json", tmp_path / "o.json", "--torque", bad, *SHORT)
    assert res.exit_code == 2, res.output
    assert "--torque" in res.output and "Traceback" not in res.output


def test_shares_bounded_prior_and_budget_reach_the_json(tmp_path):
    _csv(tmp_path / "sag.csv")
    out = tmp_path / "b.json"
    res = _run(tmp_path / "sag.csv", "--json", out, "--shares", "bounded", "--prior",
               "a4=0.5,0.2", "--prior", "f_m=0.5,0.2", *SHORT)  # fmt: skip
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    assert d["settings"]["coefficient_prior"] == {
        "shares": "bounded",
        "normal": {"a4": [0.5, 0.2], "f_m": [0.5, 0.2]},
    }
    for name in ("a1", "a2", "a3", "a4", "a5", "a6", "f_m"):
        p = d["parameters"][name]
        assert 0.0 <= p["hdi_low"] <= p["hdi_high"] <= 1.0, name
    # --draws given: exactly that many (no run-on until converged).
    assert "until_converged" not in d["settings"]
    assert "lag1_autocorrelation" in d["settings"]["residuals"]


@pytest.mark.parametrize(
    "args, words",
    [
        (["--prior", "a7=0.1,0.1"], "--prior"),
        (["--prior", "a1=0.1,-1"], "SD positive"),
        (["--shares", "tight"], "--shares"),
        (["--max-seconds", "0"], "--max-seconds"),
        (["--window-s", "2"], "--window-s"),
        (["--shares", "bounded", "--likelihood", "student-t"], "normal only"),
    ],
)
def test_bad_composite_options_are_one_line(tmp_path, args, words):
    _csv(tmp_path / "sag.csv")
    res = _run(tmp_path / "sag.csv", "--json", tmp_path / "x.json", *args, *SHORT)
    assert res.exit_code == 2, res.output
    assert words in res.output and "Traceback" not in res.output
    assert not (tmp_path / "x.json").exists()


@pytest.mark.parametrize(
    "args, words",
    [
        # Red-team L1: an sd of 1e-300 overflowed ("overflow encountered in multiply") and
        # ended in "no starting coefficients where the coefficient prior is positive".
        (["--prior", "a1=0.3,1e-300"], "--prior: a1: SD 1e-300 is below 1e-06"),
        # L12: a median of 1e300 gave two raw overflow warnings and a fit; a mean outside
        # [0, 1] for a share held in [0, 1] was accepted.
        (["--prior", "h_s=1e300,1"], "--prior: h_s: MEDIAN 1e+300 is outside [1e-06, 1e+06]"),
        (["--prior", "h_s=0.5,50"], "--prior: h_s: SD_LOG 50 is above 5"),
        (
            ["--shares", "bounded", "--prior", "f_m=2,0.1"],
            "--prior: f_m: MEAN 2 is outside [0, 1], where --shares bounded holds f_m",
        ),
    ],
)
def test_priors_that_cannot_be_sampled_are_one_line(tmp_path, args, words):
    _csv(tmp_path / "sag.csv")
    res = _run(tmp_path / "sag.csv", "--json", tmp_path / "x.json", *args, *SHORT)
    assert res.exit_code == 2, res.output
    line = res.output.strip()
    assert "\n" not in line and words in line, line
    assert not (tmp_path / "x.json").exists()


@pytest.mark.parametrize(
    "extra, absent",
    [(["--noise", "ar1"], "rho_p"), (["--torque", "estimate"], "log_a_over_c")],
)
def test_the_baseline_json_of_ar1_noise_and_estimated_torque(tmp_path, extra, absent):
    # The NLS baseline has no rho nor torque log-ratios: it summarises its own draws (its
    # JSON was a KeyError traceback, exit 1, for both).
    _csv(tmp_path / "sag.csv")
    base = tmp_path / "base.json"
    res = _run(tmp_path / "sag.csv", "--json", tmp_path / "c.json", "--baseline-json", base,
               *extra, *SHORT)  # fmt: skip
    assert res.exit_code == 0, res.output
    d = json.loads(base.read_text())
    assert absent not in d["parameters"] and "f_m" in d["parameters"]
