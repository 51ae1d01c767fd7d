"""``loadbayes fit zip DATA --by ...`` through the CLI (in-process engine)."""

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.fleet.generate import fleet_truth, write_fleet

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def hive(tmp_path_factory):
    folder = tmp_path_factory.mktemp("meters")
    write_fleet(fleet_truth(9, seed=4, rows=(20, 400)), folder, layout="hive")
    return folder


def _run(*args):
    return CliRunner().invoke(main, ["fit", "zip", *map(str, args)])


def test_fleet_table_from_a_hive_folder(hive, tmp_path):
    out = tmp_path / "fleet.parquet"
    res = _run(hive, "--by", "bus_id", "--class-col", "customer_class", "--out", out,
               "--pool", "class", "--draws", "300", "--burn", "100", "--max-seconds", "5",
               "--quiet")  # fmt: skip
    assert res.exit_code == 0, res.output
    t = pd.read_parquet(out)
    assert set(t.level) == {"bus", "class"}
    assert t[t.level == "bus"].bus.nunique() == 9
    again = _run(hive, "--by", "bus_id", "--out", out, "--quiet")
    assert again.exit_code == 2 and "exists; use --force" in again.stderr


def test_fleet_refuses_single_bus_outputs_and_bad_data_in_one_line(hive, tmp_path):
    res = _run(
        hive, "--by", "bus_id", "--json", tmp_path / "x.json", "--out", tmp_path / "f.parquet"
    )  # noqa: E501
    assert res.exit_code == 2 and "--json is for one bus" in res.stderr
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "a.csv").write_text("bus_id,v,p,q\nb1,1.0,1.0,1.0\nb1,x,1.0,1.0\n")
    res = _run(bad, "--by", "bus_id", "--out", tmp_path / "f.parquet")
    assert res.exit_code == 2
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and "a.csv" in line and "row 2" in line
    res = _run(hive, "--out", tmp_path / "f.parquet")  # one bus needs --json
    assert res.exit_code == 2 and "--json" in res.output


def test_a_bus_in_kv_gets_a_warning_row_and_the_others_are_fitted(tmp_path):
    """Issue 14 for fleets: a bus whose V is in kV is refused by name, per bus."""
    rng = np.random.default_rng(5)
    frames = []
    for bus, scale in (("ok", 1.0), ("kv", 12.47)):
        v = rng.uniform(0.92, 1.06, 200)
        p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, v.size)
        frames.append(pd.DataFrame({"bus_id": bus, "v": v * scale, "p": p}))
    src = tmp_path / "two.csv"
    pd.concat(frames).to_csv(src, index=False)
    out = tmp_path / "fleet.parquet"
    res = _run(src, "--by", "bus_id", "--q-col", "none", "--out", out,
               "--draws", "300", "--burn", "100", "--quiet")  # fmt: skip
    assert res.exit_code == 0, res.output
    table = pd.read_parquet(out)
    kv = table[table["bus"] == "kv"]
    assert len(kv) == 1 and "not per unit" in kv["warnings"].iloc[0]
    assert "--v-base 12.47" in kv["warnings"].iloc[0]
    assert (table[table["bus"] == "ok"]["parameter"] == "a1").any()


def _kv_fleet(path, buses=3, scale=11.0, nan_rows=()):
    rng = np.random.default_rng(7)
    frames = []
    for i in range(buses):
        v = rng.uniform(0.95, 1.05, 60)
        p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.005, v.size)
        frames.append(pd.DataFrame({"bus_id": f"b{i}", "v": v * scale, "p": p}))
    table = pd.concat(frames, ignore_index=True)
    table.loc[list(nan_rows), "p"] = np.nan
    table.to_csv(path, index=False)
    return path


def test_a_fleet_none_of_whose_buses_can_be_fitted_is_refused_and_nothing_written(tmp_path):
    """A whole fleet in kV (no --v-base) exited 0 with a table of 'not fitted' rows only."""
    src = _kv_fleet(tmp_path / "kv.csv")
    out = tmp_path / "fleet.parquet"
    res = _run(src, "--by", "bus_id", "--q-col", "none", "--out", out,
               "--draws", "200", "--burn", "50", "--quiet")  # fmt: skip
    assert res.exit_code == 2
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and "kv.csv: none of the 3 buses" in line
    assert "--v-base 11" in line and not out.exists()
    res = _run(src, "--by", "bus_id", "--q-col", "none", "--out", out, "--v-base", "11",
               "--draws", "200", "--burn", "50", "--quiet")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert out.exists()


def test_drop_invalid_says_how_many_rows_it_dropped_in_a_fleet(tmp_path):
    """As for one bus (and as --help promises); the fleet dropped them silently."""
    src = _kv_fleet(tmp_path / "m.csv", scale=1.0, nan_rows=(3, 70, 71))
    out = tmp_path / "fleet.parquet"
    res = _run(src, "--by", "bus_id", "--q-col", "none", "--out", out, "--drop-invalid",
               "--draws", "200", "--burn", "50", "--quiet")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "3 rows with invalid values were dropped (--drop-invalid)" in res.stderr


def test_report_of_a_damaged_parquet_says_parquet_not_json(tmp_path):
    """A .parquet without Parquet's magic bytes was read as JSON: 'not a JSON result'."""
    bad = tmp_path / "fleet.parquet"
    bad.write_bytes(b"")
    res = CliRunner().invoke(main, ["report", str(bad), "--out", str(tmp_path / "r.html")])
    assert res.exit_code == 2
    assert "not a readable Parquet file" in res.stderr and "JSON" not in res.stderr
    assert not (tmp_path / "r.html").exists()


def test_accept_units_fits_a_fleet_and_keeps_the_unit_checks_words_on_its_rows(tmp_path):
    """--help: 'the unit check then warns instead of refusing'; a fleet dropped the words."""
    src = _kv_fleet(tmp_path / "kv.csv", buses=2)
    out = tmp_path / "fleet.parquet"
    res = _run(src, "--by", "bus_id", "--q-col", "none", "--out", out, "--accept-units",
               "--draws", "200", "--burn", "50", "--quiet")  # fmt: skip
    assert res.exit_code == 0, res.output
    t = pd.read_parquet(out)
    assert t["parameter"].notna().all()
    assert t["warnings"].str.startswith("units: voltage averages 1").all()
    assert t["warnings"].str.contains("not per unit (--v-base 11)", regex=False).all()


def test_a_bus_in_two_classes_across_files_is_named_as_written(tmp_path):
    """The message read "bus np.str_('b0') is in class ...": NumPy's repr, not the id."""
    (tmp_path / "m").mkdir()
    rows = "\n".join(f"b0,{c},{1 + 0.01 * i},{1 + 0.01 * i}" for i, c in enumerate("xxxyyy"))
    lines = rows.splitlines()
    (tmp_path / "m" / "a.csv").write_text("bus_id,cls,v,p\n" + "\n".join(lines[:3]) + "\n")
    (tmp_path / "m" / "b.csv").write_text("bus_id,cls,v,p\n" + "\n".join(lines[3:]) + "\n")
    res = _run(tmp_path / "m", "--by", "bus_id", "--class-col", "cls", "--pool", "class",
               "--q-col", "none", "--out", tmp_path / "f.parquet", "--quiet")  # fmt: skip
    assert res.exit_code == 2
    assert "bus 'b0' is in class 'y' at " in res.stderr and "np." not in res.stderr
    assert "but in class 'x' at " in res.stderr


def test_a_missing_bus_column_lists_the_files_columns_as_for_v_p_q(tmp_path):
    """'no column bus_id' did not say the header had ' bus_id', nor that the file was empty."""
    (tmp_path / "a.csv").write_text(" bus_id,v,p\nb1,1.0,1.0\n")
    res = _run(tmp_path / "a.csv", "--by", "bus_id", "--out", tmp_path / "f.parquet")
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1
    assert "(the columns are ' bus_id', 'v', 'p' (did you mean ' bus_id'?))" in res.stderr
    (tmp_path / "e.csv").write_text("")
    res = _run(tmp_path / "e.csv", "--by", "bus_id", "--out", tmp_path / "f.parquet")
    assert res.exit_code == 2 and "e.csv: no column 'bus_id' (the file is empty)" in res.stderr
