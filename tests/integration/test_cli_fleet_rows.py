"""Fleets fitted bus by bus from their rows (issue 39): ``fit zip --level drift --by`` and
``cvr --by``, through the CLI on feeders from tests/cvr_generator.py (in-process engine)."""

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cvr_generator import Feeder, feeder, zip_fleet  # noqa: E402
from loadbayes.cli import main  # noqa: E402
from loadbayes.fleet.summary import read_fleet  # noqa: E402

pytestmark = pytest.mark.integration

COLS = ["--t-col", "time", "--v-col", "v_kv", "--p-col", "p_mw", "--v-base", "12.47"]


@pytest.fixture(scope="module")
def fleet_csv(tmp_path_factory):
    cols, truth = zip_fleet(3, days=3)
    df = pd.DataFrame(cols)
    df["cls"] = np.where(df["feeder"] == "F02", "com", "res")
    path = tmp_path_factory.mktemp("drift") / "fleet.csv"
    df.to_csv(path, index=False)
    return path, truth


def _run(*args):
    return CliRunner().invoke(main, [*map(str, args)])


def test_drift_fleet_pooled_by_class_and_its_report(fleet_csv, tmp_path):
    path, truth = fleet_csv
    out = tmp_path / "f.parquet"
    res = _run("fit", "zip", path, "--level", "drift", "--by", "feeder", "--class-col", "cls",
               "--pool", "class", "--q-col", "none", "--v-noise", "0.0005", *COLS,
               "--draws", "300", "--burn", "100", "--out", out)  # fmt: skip
    assert res.exit_code == 0, res.output
    t, settings = read_fleet(out)
    assert settings["level"] == "drift" and settings["v_noise"] == 0.0005
    assert settings["pool"] == "class" and settings["pooled"] == ["dp_dv", "dq_dv"]
    cls = t[t.level == "class"]
    assert set(cls["class"]) == {"res", "com"}
    assert set(cls.parameter) == {"dp_dv", "sd_dp_dv"}
    bus = t[(t.level == "bus") & (t.parameter == "dp_dv")]
    assert sorted(bus.bus) == ["F00", "F01", "F02"]
    assert bus.shrinkage.between(0, 1).all()  # the class's weight in each bus's estimate
    assert {"a1", "a2", "a3", "tau_p", "drift_p"} <= set(t.parameter.dropna())
    # one bus of class com: its spread is the prior's, said on stderr
    assert "only 1 bus(es) of class 'com'" in res.stderr
    page = tmp_path / "f.html"
    rep = _run("report", out, "--out", page, "--quiet")
    assert rep.exit_code == 0, rep.output
    text = page.read_text(encoding="utf-8")
    assert "dp_dv" in text and "per unit of the level P0(t)" in text  # not the data's units


def test_drift_fleet_refusals_are_one_line(fleet_csv, tmp_path):
    path, _ = fleet_csv
    out = tmp_path / "x.parquet"
    base = ("fit", "zip", path, "--level", "drift", "--by", "feeder", "--out", out)
    cases = {
        ("--v-col", "v_kv", "--p-col", "p_mw"): "--level drift needs the time",
        (*COLS, "--pool", "class"): "needs the class column",
        (*COLS, "--netcdf-dir", tmp_path / "nc"): "--netcdf-dir is for the static fleet",
        (*COLS, "--v-noise", "auto"): "not auto",
    }
    for extra, words in cases.items():
        res = _run(*base, *extra)
        assert res.exit_code == 2 and words in res.stderr, (extra, res.output)
        assert len(res.stderr.strip().splitlines()) == 1 and not out.exists()
    res = _run(*base[:6], "bus_id", "--out", out, *COLS)
    assert res.exit_code == 2 and "no bus column 'bus_id'" in res.stderr
    fixed = _run("fit", "zip", path, "--by", "feeder", "--out", out, "--v-noise", "0.001", *COLS)
    assert fixed.exit_code == 2 and "--v-noise is for one bus or --level drift" in fixed.stderr
    # a bad cell stops the fleet, named by its file and data row there (not the bus's row)
    bad = pd.read_csv(path, dtype=str)
    bad.loc[1000, "v_kv"] = "abc"
    bad_path = tmp_path / "bad.csv"
    bad.to_csv(bad_path, index=False)
    res = _run("fit", "zip", bad_path, "--level", "drift", "--by", "feeder", "--out", out, *COLS)
    assert res.exit_code == 2 and not out.exists()
    assert res.stderr.strip().splitlines()[-1] == (
        f"loadbayes: error: {bad_path}: column 'v_kv', row 1001: non-numeric value 'abc'"
    )


def test_cvr_fleet_table_flags_and_page(tmp_path):
    frames = []
    for i in range(2):
        cols, _ = feeder(500 + i, Feeder(days=12))
        frames.append(pd.DataFrame(cols).assign(feeder=f"feeder {i}"))
    path = tmp_path / "cvr.csv"
    pd.concat(frames).to_csv(path, index=False)
    out = tmp_path / "cvr.parquet"
    res = _run("cvr", path, "--by", "feeder", *COLS, "--q-col", "none", "--schedule-col",
               "cvr_on", "--weather-col", "temp_c", "--draws", "500", "--out", out)  # fmt: skip
    assert res.exit_code == 0, res.output
    t, settings = read_fleet(out)
    assert settings["kind"] == "cvr-fleet" and settings["buses"] == 2
    bus = t[t.level == "bus"]
    assert set(bus.parameter) == {"cvr_p", "dp_dv"}
    assert (bus.hdi_low < bus["mean"]).all() and (bus["mean"] < bus.hdi_high).all()
    # the generator's head answers to the load (0.003 p.u./MW) and has glitches: flagged
    assert bus.warnings.str.startswith("head voltage answers to the load").all()
    assert bus.warnings.str.contains("glitches left out").all()
    facts = settings["feeders"]["feeder 0"]
    assert facts["head_answers_to_load"] and facts["glitches"]["spikes_v"] == 1
    lines = res.stdout.splitlines()
    assert lines[0].startswith("feeder by feeder") and "head V answers to load" in lines[1]
    page = tmp_path / "cvr.html"
    rep = _run("report", out, "--out", page, "--quiet")
    assert rep.exit_code == 0, rep.output
    text = page.read_text(encoding="utf-8")
    assert "Feeder by feeder" in text and "feeder 1" in text and "<figure>" in text
    for bad, words in ((("--json", tmp_path / "a.json"), "--json is for one feeder"),
                       ((), "--out")):  # fmt: skip
        again = _run("cvr", path, "--by", "feeder", *COLS, *bad, "--force")
        assert again.exit_code == 2 and words in again.stderr
