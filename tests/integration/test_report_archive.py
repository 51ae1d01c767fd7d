"""``loadbayes report archive.db``: an archive's catalog into one self-contained HTML page.

The archive is the tests' own (tests/archive_generator.py: one record per station, two
bays each, and the special files: no dip, a malformed .cfg, a .dat cut short, a .cfg
without its .dat). The fits are written into the catalog as ``archive fit`` writes them
(:func:`loadbayes.archive.catalog.record_fit`) with the generator's true shares and a
known sd, so the report's pooling runs on known inputs in seconds, with no sampler; one
fit is recorded as failed.
"""

from __future__ import annotations

import html
import json
import re

import pandas as pd
import pytest
from click.testing import CliRunner

from archive_generator import STATIONS, write_archive
from loadbayes.archive import events_frame, scan, units_frame
from loadbayes.archive.catalog import connect, record_fit
from loadbayes.cli import main

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def catalog(tmp_path_factory):
    root = tmp_path_factory.mktemp("reportarchive")
    truth = write_archive(root / "records", records=1, seed=3)
    db = root / "archive.db"
    scan(root / "records", db)
    ev = events_frame(db)
    rows = truth[truth["special"] == ""]
    run = {"model": "zip+motor", "seed": 0, "draws": 300, "burn": 100, "chains": 2,
           "per_cycle": 4}  # fmt: skip
    with connect(db) as conn:
        for i, e in enumerate(ev.itertuples()):
            if i == 0:  # one fit the data refused
                record_fit(conn, {**run, "event_id": e.event_id, "status": "failed",
                                  "reason": "the motor cannot start"})  # fmt: skip
                continue
            f_m = rows[(rows["station"] == e.station) & (rows["bay"] == e.bay)]["f_m"].iloc[0]
            share = {"name": "f_m", "share": True, "mean": f_m, "sd": 0.03, "lo": f_m - 0.06,
                     "hi": f_m + 0.06, "rhat": 1.0, "ess": 800.0}  # fmt: skip
            record_fit(conn, {**run, "event_id": e.event_id, "status": "done",
                              "params": [share], "rhat_max": 1.0, "ess_min": 800.0})  # fmt: skip
    return db, truth


def _text(path) -> str:
    page = path.read_text(encoding="utf-8")
    page = re.sub(r"<style>.*?</style>", "", page, flags=re.S)
    return html.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", page)))


def test_the_catalog_tables_count_what_the_generator_wrote(catalog):
    db, truth = catalog
    units = units_frame(db)
    ok = units[units["status"] == "ok"]
    assert len(ok) == 6 and set(ok["station"]) == {s.name for s in STATIONS}
    # One record a bay, plus the no-dip record's two bays at Riverside (read, no event).
    assert ok["events"].sum() == 6 and ok["fitted"].sum() == 5 and ok["fit_failed"].sum() == 1
    assert ok["no_event_files"].sum() == 2


def test_report_of_a_catalog_pools_its_fits_and_lists_what_failed(catalog, tmp_path):
    db, truth = catalog
    out = tmp_path / "archive.html"
    r = CliRunner().invoke(main, ["report", str(db), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "500 draws x 4 chains" in r.output
    page = out.read_text(encoding="utf-8")
    assert "<script" not in page and "http" not in page.split("<body>")[1].split("data:")[0]
    assert page.count("data:image/png;base64,") == 1  # the composition, inline
    text = _text(out)
    for s in STATIONS:
        assert s.name in text and all(b in text for b in s.bays)
    for section in ("Stations and bays", "Events per month", "Composition over the year",
                    "What failed, and why"):  # fmt: skip
        assert section in text
    assert "pooled here from the catalog's zip+motor fits: 500 draws x 4 chains" in text
    # Each broken file by name with the reader's reason, the failed fit with its line.
    assert re.search(r"special/no_dat\.cfg [^|]*data file no_dat\.dat not found", text)
    assert re.search(r"special/bad_cfg\.cfg .*line", text)
    assert "special/short_dat.cfg" in text
    assert "zip+motor: the motor cannot start" in text
    assert re.search(r"1 file\(s\) were read but no bay had a dip .*special/no_dip\.cfg", text)
    month = pd.to_datetime(truth[truth["special"] == ""]["time"]).dt.month
    assert len(month) == 6  # every event's month is in the table: 2 bays a record
    assert "Events left out of the pool: no fit (it failed; see below): 1." in text


def test_report_reads_a_pool_json_instead_of_pooling(catalog, tmp_path):
    db, _ = catalog
    runner = CliRunner()
    pool = tmp_path / "pool.json"
    r = runner.invoke(main, ["archive", "pool", "--catalog", str(db), "--draws", "60",
                             "--chains", "2", "--out", str(pool), "--quiet"])  # fmt: skip
    assert r.exit_code == 0, r.output
    d = json.loads(pool.read_text(encoding="utf-8"))
    out = tmp_path / "archive.html"
    r = runner.invoke(main, ["report", str(db), "--out", str(out), "--pool", str(pool)])
    assert r.exit_code == 0, r.output
    text = _text(out)
    assert "read from pool.json (archive pool --out)" in text
    first = d["parts"]["f_m"]["monthly"][0]
    assert f"{first['mean']:.2f} [{first['low']:.2f}, {first['high']:.2f}]" in text
    # Nothing overwritten without --force.
    r = runner.invoke(main, ["report", str(db), "--out", str(out), "--pool", str(pool)])
    assert r.exit_code == 2 and "exists" in r.output


def test_bad_options_and_files_are_one_line_errors(catalog, tmp_path):
    db, _ = catalog
    runner = CliRunner()
    out = str(tmp_path / "x.html")
    not_pool = tmp_path / "fit.json"
    not_pool.write_text(json.dumps({"parts": {"f_m": {"units": []}}}), encoding="utf-8")
    cases = [
        (["report", str(db), "--out", out, "--truth", "a1=0.3"], "--truth is not for an archive"),
        (["report", str(db), "--out", out, "--pool", str(not_pool)],
         "fit.json: not the JSON of loadbayes archive pool --out"),
        (["report", str(not_pool), "--out", out, "--pool", str(not_pool)],
         "--pool is for an archive's catalog"),
    ]  # fmt: skip
    for args, words in cases:
        r = runner.invoke(main, [*args, "--quiet"])
        assert r.exit_code == 2, r.output
        assert words in r.output and len(r.output.strip().splitlines()) == 1, r.output
        assert "Traceback" not in r.output
    not_db = tmp_path / "other.db"
    not_db.write_text("station,time\n", encoding="utf-8")
    r = runner.invoke(main, ["report", str(not_db), "--out", out])
    assert r.exit_code == 2 and "not a loadbayes archive catalog" in r.output, r.output
    assert not (tmp_path / "x.html").exists()


def test_example_archive_takes_its_size_and_the_others_refuse_it(tmp_path):
    runner = CliRunner()
    out = tmp_path / "small"
    r = runner.invoke(main, ["example", "archive", str(out), "--records", "2", "--bays", "1"])
    assert r.exit_code == 0, r.output
    truth = pd.read_csv(out / "truth.csv")
    assert len(truth) == 6 and truth.groupby("station")["bay"].nunique().max() == 1
    assert len(list(out.glob("*.cfg"))) == 6 + 2  # 3 stations x 2 records, 2 broken
    r = runner.invoke(main, ["example", "zip", "--records", "2"])
    assert r.exit_code == 2 and "--records and --bays are for the archive example" in r.output
