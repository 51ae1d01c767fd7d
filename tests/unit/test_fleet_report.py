"""The fleet report's content, on a small fleet simulated here (not by loadbayes.fleet.generate).

Nine buses in three classes with known ZIP shares: one thin bus (5 rows), one whose
voltage never moves (flat), the rest with +/-4% swings; coordinates x, y per bus. The
pooled and unpooled tables are made by the library in-process (2 chains x 400 draws).
"""

from __future__ import annotations

import html
import re

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.partitions import ReadSpec
from loadbayes.fleet.run import run_fleet
from loadbayes.fleet.summary import write_parquet
from loadbayes.io.errors import DataError
from loadbayes.report.fleet_report import fleet_report, write_fleet_report
from loadbayes.report.fleet_table import load_fleet, read_coords

MIXES = {"res": (0.5, 0.2, 0.6, 0.2), "com": (0.2, 0.3, 0.3, 0.4), "ind": (0.05, 0.1, 0.1, 0.3)}
SETTINGS = SamplerSettings(draws=400, burn=100, chains=2, seed=3)


def _fleet_rows(seed: int = 11) -> pd.DataFrame:
    gen = np.random.default_rng(seed)
    frames = []
    for i in range(9):
        cls = list(MIXES)[i % 3]
        a1, a2, a4, a5 = np.asarray(MIXES[cls]) + 0.03 * gen.standard_normal(4)
        n = 5 if i == 4 else 300
        v = 1.0 + gen.uniform(-0.04, 0.04, n)
        if i == 7:
            v = np.full(n, 0.99)  # flat: the voltage never moved
        p = a1 * v**2 + a2 * v + 1 - a1 - a2 + 0.01 * gen.standard_normal(n)
        q = a4 * v**2 + a5 * v + 1 - a4 - a5 + 0.01 * gen.standard_normal(n)
        frames.append(pd.DataFrame({"bus_id": f"b{i}", "cls": cls, "v": v, "p": p, "q": q,
                                    "x": float(i % 3), "y": float(i // 3)}))  # fmt: skip
    return pd.concat(frames, ignore_index=True)


def _write(table: pd.DataFrame, path, settings: dict) -> None:
    """The table with its settings under the Parquet metadata key 'loadbayes' (as the CLI)."""
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    t = pa.Table.from_pandas(table, preserve_index=False)
    meta = {**(t.schema.metadata or {}), b"loadbayes": json.dumps(settings).encode()}
    pq.write_table(t.replace_schema_metadata(meta), path)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    data = root / "meters.parquet"
    _fleet_rows().to_parquet(data)
    spec = ReadSpec(by="bus_id", class_col="cls")
    out = {}
    for pool in ("class", "none"):
        res = run_fleet(str(data), spec, pool=pool, p0=1.0, q0=1.0, sampler=SETTINGS)
        path = root / f"{pool}.parquet"
        _write(res.table, path, {"data": "meters.parquet", "by": "bus_id", "pool": pool,
                                 "draws": 400, "warnings": ["a run-level sentence"]})  # fmt: skip
        out[pool] = path
    return root, data, out


def _text(page: str) -> str:
    return html.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", page)))


def test_the_pooled_page_has_class_mixes_shrinkage_flags_and_settings(fleet):
    root, _, out = fleet
    ft = load_fleet(out["class"])
    page = fleet_report(ft, source="class.parquet")
    text = _text(page)
    for sec in ("Class mixes", "Shrinkage", "Buses flagged", "Voltage sensitivity", "Settings"):
        assert f"{sec}</h2>" in page
    assert text.index("Summary") < text.index("Contents") < text.index("1. Class mixes")
    # Every class's mean a1 with its interval, as in the table.
    cls = ft.class_rows.set_index(["class", "parameter"])
    for c in MIXES:
        lo = cls.loc[(c, "a1"), "hdi_low"]
        assert c in text and "P: impedance share" in text
        assert np.isfinite(lo)
    assert "ZIP load models of 9 buses in 3 classes" in text
    # The thin and the flat bus are flagged, by id and reason; a normal bus is not thin.
    flagged = ft.flagged().set_index("bus")["reasons"]
    assert "thin: 5 rows" in flagged["b4"]
    assert "flat voltage" in flagged["b7"]
    assert not any(r.startswith("thin") for r in flagged.get("b0", []))
    assert "thin: 5 rows" in text and "flat voltage" in text
    # Without coordinates or unpooled estimates: said, not hidden.
    assert "No coordinates (x/y or lat/lon) in this file" in text
    assert "own (unpooled) estimates: not in this file" in text
    assert page.count("<figure>") == 3  # class mixes, shrinkage, sensitivity
    assert "meters.parquet" in text and "bus_id" in text  # settings from the metadata
    assert "a run-level sentence" in text.split("Contents")[0]  # the run's warnings, first


def test_sensitivity_is_2a1_plus_a2_unless_the_table_has_it(fleet, tmp_path):
    _, _, out = fleet
    ft = load_fleet(out["class"])
    w = ft.wide()
    # A fleet run writes its own dp_dv rows (2 a1 + a2 per draw): used, with intervals;
    # their mean is 2 a1 + a2 of the means (linear).
    s, where, _ = ft.sensitivity("dp_dv")
    assert where == "the table's dp_dv rows"
    np.testing.assert_allclose(s["mean"], 2 * w["a1"] + w["a2"], rtol=1e-6, atol=1e-9)
    # A table without them (an older run): 2 a1 + a2 from the means, said so.
    t0 = ft.table[~ft.table.parameter.str.lower().isin(["dp_dv", "dq_dv"])]
    ft0 = load_fleet(write_parquet(t0, tmp_path / "older.parquet"))
    s, where, unit = ft0.sensitivity("dp_dv")
    np.testing.assert_allclose(s["mean"], 2 * w["a1"] + w["a2"])
    assert where == "2 a1 + a2 (the means only)" and unit == "per unit of P0 per p.u. of V"
    # A table with dP/dV rows named otherwise (and a column the report does not know):
    # used as is.
    t = t0.copy()
    extra = t[(t.level == "bus") & (t.parameter == "a1")].copy()
    extra["parameter"], extra["mean"] = "dP_dV", 0.777
    t = pd.concat([t, extra], ignore_index=True)
    t["new_column"] = 1.0
    path = write_parquet(t, tmp_path / "later.parquet")
    ft2 = load_fleet(path)
    s2, where2, _ = ft2.sensitivity("dp_dv")
    assert where2 == "the table's dP_dV rows" and np.allclose(s2["mean"], 0.777)
    text = _text(fleet_report(ft2))
    assert "dP/dV from the table's dP_dV rows (with intervals)" in text
    assert "new_column" in text  # listed among the columns in the settings


def test_coordinates_and_unpooled_estimates_make_the_map_and_the_pairs(fleet, tmp_path):
    root, data, out = fleet
    page = write_fleet_report(out["class"], tmp_path / "f.html", unpooled=out["none"],
                              coords=data).read_text()  # fmt: skip
    text = _text(page)
    assert "placed at the bus's coordinates (x, y)" in text
    assert "No coordinates" not in text and "not in this file" not in text.split("Settings")[0]
    assert "pooled posterior mean against its own estimate" in text
    with pytest.raises(DataError, match="exists; use --force"):
        write_fleet_report(out["class"], tmp_path / "f.html")
    xy, names = read_coords(data, by="bus_id")
    assert names == ("x", "y") and xy.loc["b5", "x"] == 2.0 and xy.loc["b5", "y"] == 1.0


def test_the_unpooled_page_says_there_is_no_class_estimate(fleet):
    _, _, out = fleet
    text = _text(fleet_report(load_fleet(out["none"])))
    assert "no class estimates in this file" in text
    assert "every bus keeps its own estimate" in text


def test_bad_tables_are_refused_naming_the_file_and_column(fleet, tmp_path):
    root, data, out = fleet
    with pytest.raises(DataError, match=r"meters\.parquet: column 'level': not a loadbayes fleet"):
        load_fleet(data)
    t = pd.read_parquet(out["class"])
    t.drop(columns="r_hat").to_parquet(tmp_path / "no_rhat.parquet")
    with pytest.raises(DataError, match=r"no_rhat\.parquet: column 'r_hat': not a loadbayes"):
        load_fleet(tmp_path / "no_rhat.parquet")
    bad = t.astype({"mean": str})
    bad.loc[3, "mean"] = "abc"
    bad.to_parquet(tmp_path / "text.parquet")
    with pytest.raises(DataError, match=r"text\.parquet: column 'mean', row 4: not a number"):
        load_fleet(tmp_path / "text.parquet")
    (tmp_path / "c.csv").write_text("bus_id,x\nb1,1\n")
    with pytest.raises(DataError, match=r"c\.csv: column 'x': no coordinates"):
        read_coords(tmp_path / "c.csv", by="bus_id")


@pytest.mark.parametrize(
    ("column", "value", "words"),
    [
        ("mean", np.nan, "column 'mean', row 1: nan in a fitted row (parameter 'a1')"),
        ("mean", 1e308, "column 'mean', row 1: 1e+308 in a fitted row (parameter 'a1')"),
        ("hdi_high", np.inf, "column 'hdi_high', row 1: inf in a fitted row"),
        ("sd", -0.5, "column 'sd', row 1: -0.5 is negative: not a posterior sd"),
    ],
)
def test_statistics_that_cannot_be_shown_are_refused_by_row(fleet, tmp_path, column, value, words):
    # Red-team L11: NaN means, 1e308 means and a negative sd made a report (exit 0) with
    # numpy's "Mean of empty slice", matplotlib's "overflow encountered in multiply", or
    # the negative sd shown.
    _, _, out = fleet
    t = pd.read_parquet(out["none"])
    assert t.loc[0, "parameter"] == "a1"
    t.loc[0, column] = value
    t.to_parquet(tmp_path / "bad.parquet")
    with pytest.raises(DataError) as err:
        load_fleet(tmp_path / "bad.parquet")
    assert str(err.value).startswith(f"{tmp_path / 'bad.parquet'}: {words}"), str(err.value)


def test_a_table_with_one_row_twice_is_refused_by_row(fleet, tmp_path):
    # Red-team L1: a pooled table whose class column was set to one value (two classes'
    # rows then share their names) ended in pandas' "The truth value of a Series is
    # ambiguous" (exit 2, no file, no row).
    _, _, out = fleet
    t = pd.read_parquet(out["class"])
    t["class"] = "x"
    t.to_parquet(tmp_path / "one.parquet")
    with pytest.raises(DataError) as err:
        load_fleet(tmp_path / "one.parquet")
    msg = str(err.value)
    assert msg.startswith(f"{tmp_path / 'one.parquet'}: column 'class', row "), msg
    assert "class 'x', parameter 'a1' is on rows" in msg and "one row per" in msg
    from click.testing import CliRunner

    from loadbayes.cli import main

    res = CliRunner().invoke(main, ["report", str(tmp_path / "one.parquet"), "--out",
                                    str(tmp_path / "r.html")])  # fmt: skip
    assert res.exit_code == 2 and res.output.strip() == f"loadbayes: error: {msg}", res.output
    assert not (tmp_path / "r.html").exists()
    t = pd.read_parquet(out["none"])
    pd.concat([t, t.iloc[[3]]]).to_parquet(tmp_path / "twice.parquet")
    with pytest.raises(DataError, match=r"column 'bus', row \d+: bus 'b0', parameter 'a4'"):
        load_fleet(tmp_path / "twice.parquet")


def test_a_later_tables_convergence_words_and_column_are_shown(fleet, tmp_path):
    """The fleet branch's additions (docs/fleet.md there): 'converged', class warnings."""
    _, _, out = fleet
    t = load_fleet(out["class"]).table.copy()
    t["converged"] = True
    t["prior_driven"] = False  # this test is about convergence (that column: the next one)
    note = "not converged: R-hat 1.470 on sd_a1, ESS 7 on sd_a1"
    cls = (t.level == "class") & (t["class"] == "res")
    t.loc[cls, "warnings"] = note
    t.loc[cls & (t.parameter == "sd_a1"), ["r_hat", "ess_bulk", "converged"]] = [1.47, 7.0, False]
    b2 = t.bus == "b2"
    t.loc[b2, "converged"] = False  # its numbers fine, its own verdict not: flagged by it
    t.loc[b2, ["r_hat", "ess_bulk"]] = [1.0, 5000.0]
    _write(t, tmp_path / "later.parquet", {"stop": "the time budget ran out"})
    text = _text(fleet_report(load_fleet(tmp_path / "later.parquet")))
    head = text.split("Contents")[0]
    assert re.search(r"may not have converged in [a-z, ]*\bres: largest R-hat 1\.470", head)
    assert note in head and "The chains stopped: the time budget ran out" in head
    flagged = load_fleet(tmp_path / "later.parquet").flagged().set_index("bus")["reasons"]
    assert flagged["b2"] == ["unconverged (the table's converged column)"]


def test_a_bus_whose_shares_split_is_its_class_is_flagged(fleet, tmp_path):
    """Issue 40: a pooled table's prior_driven rows give the bus a reason in words."""
    _, _, out = fleet
    t = load_fleet(out["class"]).table.copy()
    t["prior_driven"] = False
    t.loc[(t.bus == "b2") & t.parameter.isin(["a1", "a2", "a3"]), "prior_driven"] = True
    _write(t, tmp_path / "split.parquet", {})
    flagged = load_fleet(tmp_path / "split.parquet").flagged().set_index("bus")["reasons"]
    assert "split of a1, a2 is the class's" in flagged["b2"]
    assert not any("split" in r for b, rs in flagged.items() if b != "b2" for r in rs)


def test_the_stop_sentence_of_run_fleet_is_not_stuttered(fleet, tmp_path):
    """run_fleet writes "stopped after N sweeps ...": the page said "stopped: stopped after"."""
    _, _, out = fleet
    t = load_fleet(out["class"]).table
    stop = "stopped after 2500 sweeps per chain: every class's R-hat < 1.01"
    _write(t, tmp_path / "s.parquet", {"stop": stop})
    head = _text(fleet_report(load_fleet(tmp_path / "s.parquet"))).split("Contents")[0]
    assert "The chains stopped after 2500 sweeps per chain" in head
    assert "stopped: stopped" not in head


def test_unpooled_must_be_a_per_bus_fit_of_the_same_buses(fleet, tmp_path):
    """A pooled table, or one of other buses, was drawn as 'each bus's own estimate'."""
    _, _, out = fleet
    with pytest.raises(DataError, match=r"class\.parquet: a pooled fit \(--pool class\)"):
        write_fleet_report(out["class"], tmp_path / "a.html", unpooled=out["class"])
    other = load_fleet(out["none"]).table.assign(bus=lambda t: "x" + t["bus"].astype(str))
    _write(other, tmp_path / "other.parquet", {"pool": "none"})
    with pytest.raises(DataError, match=r"other\.parquet: none of the buses of class\.parquet"):
        write_fleet_report(out["class"], tmp_path / "b.html", unpooled=tmp_path / "other.parquet")
    assert not (tmp_path / "a.html").exists() and not (tmp_path / "b.html").exists()
