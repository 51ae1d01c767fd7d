"""``loadbayes fit composite``: a fit from CSV files, and bad input (exit 2, located)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.cli import main

#: The fit's announced-cost probe is skipped (tests/conftest.py: no_cost_probe): no test
#: here checks the announcement, and the draws do not depend on it.
pytestmark = [pytest.mark.integration, pytest.mark.usefixtures("no_cost_probe")]

SHORT = ["--draws", "600", "--burn", "300", "--chains", "2", "--quiet"]


def _csv(path, depth=0.3, seed=0, **kw):
    ev, truth = simulate_event("small_industrial", depth=depth, seed=seed, t_end_s=2.0, **kw)
    df = pd.DataFrame({"t_s": ev.t, "v": ev.v, "p": ev.p, "q": ev.q})
    df.to_csv(path, index=False)
    return df, truth


def _run(*args):
    return CliRunner().invoke(main, ["fit", "composite", *map(str, args)])


def test_two_events_fit_and_the_contract(tmp_path):
    a, truth = _csv(tmp_path / "sag1.csv", 0.3, 1)
    _csv(tmp_path / "sag2.csv", 0.45, 2)
    out = tmp_path / "comp.json"
    res = _run(tmp_path / "sag1.csv", tmp_path / "sag2.csv", "--json", out, *SHORT)
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    assert d["model"] == "composite"
    params = d["parameters"]
    for name in (
        "p0",
        "q0",
        "v0",
        "a1",
        "a2",
        "a3",
        "a4",
        "a5",
        "a6",
        "f_m",
        "rs",
        "xs",
        "xm",
        "rr",
        "xr",
        "h_s",
        "a",
        "b",
        "c",
        "t0",
        "x_prime",
        "x_open",
        "t_prime_s",
        "f_hz",
        "mva_m",
        "q_c",
        "tau_p",
        "tau_q",
        "f_m_e1",
        "p0_e1",
    ):
        assert name in params, name
    assert params["p0"]["mean"] == pytest.approx(truth["p0"], abs=0.01)
    assert params["v0"]["mean"] == pytest.approx(1.0)
    ident = d["identifiability"]
    assert set(ident["parameters"]) == {
        "log_rs_t0",
        "log_x_prime_t0",
        "log_dx_t0",
        "log_t_prime",
        "log_h_over_t0",
    }
    assert "rating" in ident["summary"]
    # Same seed, same draws; outputs are not overwritten without --force.
    again = _run(tmp_path / "sag1.csv", tmp_path / "sag2.csv", "--json", out, *SHORT)
    assert again.exit_code == 2 and "exists" in again.output
    out2 = tmp_path / "again.json"
    assert _run(tmp_path / "sag1.csv", tmp_path / "sag2.csv", "--json", out2, *SHORT).exit_code == 0
    assert json.loads(out2.read_text())["parameters"] == params


def test_one_file_with_an_event_column_and_a_frequency(tmp_path):
    a, _ = _csv(tmp_path / "a.csv", 0.3, 1)
    b, _ = _csv(tmp_path / "b.csv", 0.4, 2)
    both = pd.concat([a.assign(event=1), b.assign(event=7)])
    both["f"] = 60.0
    both.to_csv(tmp_path / "both.csv", index=False)
    out = tmp_path / "o.json"
    res = _run(tmp_path / "both.csv", "--json", out, *SHORT)
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    assert [e["name"] for e in d["settings"]["events"]] == [
        f"{tmp_path / 'both.csv'}[event=1]",
        f"{tmp_path / 'both.csv'}[event=7]",
    ]


def _bad(tmp_path, mutate, *extra):
    df, _ = _csv(tmp_path / "ok.csv")
    df = mutate(df.copy())
    path = tmp_path / "bad.csv"
    df.to_csv(path, index=False)
    res = _run(path, "--json", tmp_path / "o.json", *SHORT, *extra)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    line = res.output.strip().splitlines()[-1]
    assert line.startswith(f"loadbayes: error: {path}")
    return line


def test_time_going_backwards(tmp_path):
    def back(df):
        df.loc[10, "t_s"] = df.loc[8, "t_s"]
        return df

    line = _bad(tmp_path, back)
    assert "column 't_s', row 11" in line and "does not increase" in line


def test_gap_in_the_sampling(tmp_path):
    line = _bad(tmp_path, lambda df: df.drop(index=range(40, 50)).reset_index(drop=True))
    assert "column 't_s', row 41" in line and "gap" in line


def test_event_shorter_than_the_motor(tmp_path):
    # 40 samples squeezed into 0.16 s: under the 0.2 s that even a short event needs (40
    # samples of 0.65 s that start steady and see the sag are a short event, accepted).
    line = _bad(tmp_path, lambda df: df.iloc[:40].assign(t_s=lambda d: d["t_s"] / 4))
    assert "column 't_s'" in line and "shorter than the motor's time constants" in line


def test_no_voltage_change(tmp_path):
    def flat(df):
        df["v"] = 1.0 + 1e-4 * np.sin(np.arange(len(df)))
        return df

    line = _bad(tmp_path, flat)
    assert "column 'v'" in line and "never changes" in line


def test_missing_time_column_and_non_numeric(tmp_path):
    line = _bad(tmp_path, lambda df: df.drop(columns="t_s"))
    assert "t_s" in line

    def text(df):
        df["p"] = df["p"].astype(object)
        df.loc[5, "p"] = "abc"
        return df

    line = _bad(tmp_path, text)
    assert "column 'p', row 6" in line


def test_bad_options(tmp_path):
    _csv(tmp_path / "ok.csv")
    res = _run(tmp_path / "ok.csv", "--json", tmp_path / "o.json", "--torque", "1,1,0")
    assert res.exit_code == 2 and "A + B + C" in res.output
    res = _run(tmp_path / "ok.csv", "--json", tmp_path / "o.json", "--prior", "xx=1,1")
    assert res.exit_code == 2 and "NAME must be one of" in res.output


def test_the_table_says_units_and_what_one_sag_fixes_of_the_static_part(tmp_path):
    # One sag shows the static part at two voltages: the table carries a unit on every
    # row, and the undetermined ZIP shares are said with the combinations that are fixed.
    _csv(tmp_path / "sag.csv", 0.3, 1)
    out = tmp_path / "o.json"
    res = _run(tmp_path / "sag.csv", "--json", out, "--draws", "400", "--burn", "200",
               "--chains", "2", "--plot", tmp_path / "c.png")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lines = res.output.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("composite posterior"))
    assert "95% low" in lines[head + 1]
    rows = {ln.split()[0]: ln for ln in lines[head + 2 : head + 20] if ln.endswith("]")}
    assert rows["t_prime_s"].endswith("[s]") and rows["x_prime"].endswith("[p.u. motor base]")
    assert rows["p0"].endswith("[p.u. system base]") and rows["f_m"].endswith("[-]")
    static = json.loads(out.read_text())["identifiability"]["static_part"]
    p = static["events"][0]["p"]
    assert not p["determined"] and p["correlation"] < -0.9
    assert any(ln.startswith("static P of event 1") for ln in lines)
    assert any(ln.startswith("  2 a1 + a2 = ") for ln in lines)
    assert "the static (ZIP) part is not determined for P of" in res.output
