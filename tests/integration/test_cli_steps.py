"""``loadbayes steps``: the table of steps and the fit from their windows (issue 22)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration

COLS = ["--v-col", "V_kV", "--p-col", "P_MW", "--q-col", "Q_Mvar", "--v-base", "13.8"]
FAST = ["--draws", "1500", "--burn", "300", "--chains", "2", "--quiet"]
STEPS = (100, 200, 300, 420)


def _csv(path, n=500, seed=0, stamp="iso"):
    """A feeder in kV / MW: a rising load, four 1% voltage steps, ZIP (0.4, 0.35, 0.25)."""
    rng = np.random.default_rng(seed)
    level = np.linspace(4.0, 6.0, n) * (1 + 0.001 * np.cumsum(rng.normal(0, 1, n)) / 10)
    x = 1.02 - 0.02 * np.linspace(0, 1, n)
    for j, i in enumerate(STEPS):
        x[i:] += 0.01 * (1 if j % 2 == 0 else -1)
    p = level * (0.4 * x**2 + 0.35 * x + 0.25) * (1 + 0.002 * rng.standard_normal(n))
    q = 0.3 * level * (1.2 * x**2 + 0.8 * x - 1.0) * (1 + 0.005 * rng.standard_normal(n))
    times = pd.date_range("2026-06-01", periods=n, freq="min")
    df = pd.DataFrame(
        {
            "time": times.strftime("%Y-%m-%dT%H:%M:%S") if stamp == "iso" else np.arange(n) * 60.0,
            "V_kV": 13.8 * x * (1 + 0.0005 * rng.standard_normal(n)),
            "P_MW": p,
            "Q_Mvar": q,
        }
    )
    df.to_csv(path, index=False)
    return df


def test_table_and_fit(tmp_path):
    path = tmp_path / "day.csv"
    _csv(path)
    out, js = tmp_path / "steps.csv", tmp_path / "fit.json"
    res = CliRunner().invoke(main, ["steps", str(path), *COLS, "--t-col", "time", "--out",
                                    str(out), "--json", str(js), *FAST])  # fmt: skip
    assert res.exit_code == 0, res.output
    table = pd.read_csv(out)
    assert list(table["row"]) == [i + 1 for i in STEPS]  # 1-based data rows
    assert table["time"].iloc[0] == "2026-06-01T01:40:00"
    doc = json.loads(js.read_text())
    d = doc["derived"]["dP/dV"]
    assert d["hdi_low"] < 1.15 < d["hdi_high"]
    assert len(doc["steps"]) == 4 and doc["method"] == "gibbs-steps"
    # nothing is overwritten without --force
    again = CliRunner().invoke(main, ["steps", str(path), *COLS, "--out", str(out), *FAST])
    assert again.exit_code == 2 and "--force" in again.output


def test_bad_time_cell_is_one_line_with_its_row(tmp_path):
    path = tmp_path / "day.csv"
    df = _csv(path)
    df.loc[6, "time"] = "yesterday"
    df.to_csv(path, index=False)
    res = CliRunner().invoke(main, ["steps", str(path), *COLS, "--t-col", "time", *FAST])
    assert res.exit_code == 2
    line = res.output.strip()
    assert "\n" not in line and "column 'time'" in line and "row 7" in line


def test_no_steps_no_fit(tmp_path):
    path = tmp_path / "flat.csv"
    _csv(path)
    df = pd.read_csv(path)
    df["V_kV"] = 13.8 * (1 + 0.0005 * np.random.default_rng(1).standard_normal(len(df)))
    df.to_csv(path, index=False)
    res = CliRunner().invoke(main, ["steps", str(path), *COLS, "--json", "-", *FAST])
    assert res.exit_code == 2
    assert "0 voltage step(s) found" in res.output and "at least two" in res.output


def test_no_steps_with_a_table_is_said_once(tmp_path):
    # Red-team L7: --min-step 1e308 printed pandas' "Empty DataFrame / Columns: [...] /
    # Index: []" after the count; the count alone says it.
    path = tmp_path / "day.csv"
    _csv(path)
    out = tmp_path / "s.csv"
    res = CliRunner().invoke(main, ["steps", str(path), *COLS, "--t-col", "time", "--min-step",
                                    "1e308", "--out", str(out)])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert res.output.strip().splitlines() == [
        line for line in res.output.strip().splitlines() if "0 voltage step(s) found" in line
    ]
    assert "Empty DataFrame" not in res.output and "Index: []" not in res.output
    assert list(pd.read_csv(out).columns)[:3] == ["time", "v_before", "dv"]  # the header


@pytest.mark.parametrize("how", ["semicolon", "gb18030"])
def test_the_time_column_of_a_spreadsheets_csv(tmp_path, how):
    # A ';'-separated file, and one with Chinese names in GB18030: the V, P, Q reader
    # took them; the time column's own reader said "no time column 'time'".
    df = _csv(tmp_path / "day.csv")
    path = tmp_path / f"{how}.csv"
    if how == "semicolon":
        df.to_csv(path, index=False, sep=";")
    else:
        df = df.rename(columns={"time": "时间"})
        path.write_bytes(df.to_csv(index=False).encode("gb18030"))
    t_col = "time" if how == "semicolon" else "时间"
    out = tmp_path / "steps.csv"
    args = ["steps", str(path), *COLS, "--t-col", t_col, "--out", str(out), "--quiet"]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    assert pd.read_csv(out)["time"].iloc[0] == "2026-06-01T01:40:00"
    bad = CliRunner().invoke(main, [*args[:-3], "--t-col", "nope", "--quiet"])
    assert bad.exit_code == 2 and "no column 'nope'" in bad.output


def test_timestamps_with_a_comma_before_the_fraction(tmp_path):
    df = _csv(tmp_path / "day.csv")
    df["time"] = df["time"] + ",5"  # ISO 8601: 01:40:00,5
    df.to_csv(tmp_path / "comma.csv", index=False)
    out = tmp_path / "steps.csv"
    res = CliRunner().invoke(main, ["steps", str(tmp_path / "comma.csv"), *COLS, "--t-col",
                                    "time", "--out", str(out), "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert pd.read_csv(out)["time"].iloc[0] == "2026-06-01T01:40:00,5"
