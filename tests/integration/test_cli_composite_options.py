"""``fit composite --likelihood student-t`` and ``--torque estimate``: JSON, bad values."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.cli import main

pytestmark = pytest.mark.integration

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
