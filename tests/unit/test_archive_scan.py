"""``loadbayes archive scan`` on an archive the tests write (tests/archive_generator.py).

Three stations (names in GB18030, ASCII and Latin-1), two bays each, records in COMTRADE
1991, 1999 and 2013, ASCII and the three binary forms, one with two sample rates, and the
files an archive also holds: a record with no dip, a malformed ``.cfg``, a ``.dat`` cut
short, a ``.cfg`` without its ``.dat``.
"""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from archive_generator import STATIONS, write_archive
from loadbayes.archive import scan
from loadbayes.archive.names import bay_kind, read_rules
from loadbayes.cli import main
from loadbayes.io.errors import DataError


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    root = tmp_path_factory.mktemp("archive")
    truth = write_archive(root / "records", records=2, seed=3)
    return root, truth


def _scanned(archive, tmp_path, **kw):
    root, truth = archive
    folder = tmp_path / "records"
    shutil.copytree(root / "records", folder)
    db = tmp_path / "archive.db"
    out = scan(folder, db, **kw)
    return folder, db, out, truth


def _rows(db, sql):
    with sqlite3.connect(db) as conn:
        return conn.execute(sql).fetchall()


def test_stations_bays_and_events_are_found_as_the_generator_wrote_them(archive, tmp_path):
    folder, db, out, truth = _scanned(archive, tmp_path)
    records = truth[truth["special"] == ""]
    assert out.new == records["file"].nunique() + 4
    stations = {
        r[0]: r[1] for r in _rows(db, "SELECT station, encoding FROM files WHERE status = 'ok'")
    }
    # Each name as written, whatever the .cfg's encoding ('Größe' in Latin-1 is one GB18030
    # ideograph: read as such before the reader's detection was fixed).
    assert stations == {"城东变电站": "gb18030", "Riverside 132kV": "utf-8",
                        "Umspannwerk Größe": "latin-1"}  # fmt: skip
    kinds = dict(_rows(db, "SELECT DISTINCT bay, kind FROM bays"))
    assert kinds == {"1号主变_高压侧": "transformer", "10kV出线1": "feeder",
                     "TX1 HV": "transformer", "Feeder 2": "feeder", "Trafo 1": "transformer",
                     "Abgang Süd": "unknown"}  # fmt: skip
    revisions = {
        r[0] for r in _rows(db, "SELECT revision || format FROM files WHERE status = 'ok'")
    }
    assert revisions >= {"1999ASCII", "1991ASCII", "2013BINARY", "1999BINARY", "2013BINARY32"}
    ev = pd.DataFrame(
        _rows(db, "SELECT station, bay, time, depth, usable FROM events"),
        columns=["station", "bay", "time", "depth", "usable"],
    )
    assert len(ev) == len(records)  # one dip per record and bay, none in the no-dip record
    assert ev["usable"].all()
    ev["time"] = pd.to_datetime(ev["time"])
    true = records.assign(time=pd.to_datetime(records["time"]))
    true["time_true"] = true["time"]
    both = pd.merge_asof(ev.sort_values("time"), true.sort_values("time"), on="time",
                         by=["station", "bay"], direction="nearest",
                         suffixes=("", "_true"))  # fmt: skip
    # Each dip's start within a cycle and a half (one-cycle phasors, one a cycle) of the
    # generator's, on the recorder's clock (a 1991 date read month first), and its depth
    # (a balanced dip) to 1 % of nominal.
    late = (both["time"] - both["time_true"]).dt.total_seconds()
    assert np.all(np.abs(late) < 0.03), late
    assert np.all(np.abs(both["depth"] - both["depth_true"]) < 0.01)


def test_broken_files_are_listed_with_their_reasons_and_the_scan_goes_on(archive, tmp_path):
    folder, db, out, _ = _scanned(archive, tmp_path)
    broken = {p.rsplit("/", 1)[-1]: why for p, why in out.broken_files}
    assert set(broken) == {"bad_cfg.cfg", "short_dat.cfg", "no_dat.cfg"}
    assert broken["bad_cfg.cfg"].startswith("line 10: expected the line frequency alone")
    assert "truncated binary data" in broken["short_dat.cfg"]
    assert "no_dat.dat not found" in broken["no_dat.cfg"]
    (why,) = {r[0] for r in _rows(db, "SELECT b.reason FROM bays b JOIN files f USING (file_id) "
                                      "WHERE f.path LIKE '%no_dip.cfg'")}  # fmt: skip
    assert why == "no voltage dip of 4 % or more"


def test_a_rescan_reads_only_new_or_changed_files(archive, tmp_path):
    folder, db, first, truth = _scanned(archive, tmp_path)
    ids = dict(_rows(db, "SELECT event_id, time FROM events"))
    rows = _rows(db, "SELECT path, hash, status, reason, station FROM files ORDER BY path")
    two = tmp_path / "two.db"
    assert scan(folder, two, workers=2).line() == first.line()  # read by 2 processes
    assert _rows(two, "SELECT path, hash, status, reason, station FROM files ORDER BY path") == rows
    assert dict(_rows(two, "SELECT event_id, time FROM events")) == ids
    again = scan(folder, db)
    assert (again.new, again.changed, again.unchanged) == (0, 0, first.new)
    assert dict(_rows(db, "SELECT event_id, time FROM events")) == ids
    # One record changed (a sample of its .dat), one added, and the other one of station 2
    # copied and moved.
    files = sorted(folder.glob("station2/*.cfg"))
    dat = files[0].with_suffix(".dat")
    raw = bytearray(dat.read_bytes())
    raw[-3] ^= 0x01
    dat.write_bytes(bytes(raw))
    (folder / "new").mkdir()
    for suffix in (".cfg", ".dat"):
        shutil.copy(files[1].with_suffix(suffix), folder / "new" / ("copy" + suffix))
        shutil.move(files[-1].with_suffix(suffix), folder / "new" / ("moved" + suffix))
    extra = write_archive(tmp_path / "more", records=1, seed=9, specials=False)
    added = Path(extra["file"].iloc[0])
    for suffix in (".cfg", ".dat"):
        shutil.copy(added.with_suffix(suffix), folder / "new" / ("x" + suffix))
    third = scan(folder, db)
    assert (third.new, third.changed, third.moved, third.duplicates) == (1, 1, 1, 1)
    assert third.unchanged == first.new - 2  # the changed one and the moved one
    now = dict(_rows(db, "SELECT event_id, time FROM events"))
    kept = set(ids) & set(now)
    assert len(kept) == len(ids) - 2  # the changed record's two bays got new ids


def test_a_5_percent_dip_is_an_event_which_the_sag_threshold_misses(tmp_path):
    import datetime as dt

    from archive_generator import RATE, _waves, simulate_bay, write_record
    from loadbayes.recordings.events import find_sags

    st = STATIONS[1]
    t = np.arange(int(1.1 * RATE)) / RATE
    prof = lambda x: 0.95 if 0.2 <= x < 0.3 else 1.0  # noqa: E731
    s = [simulate_bay(t, prof, [0.2, 0.3], 0.3)[0] for _ in st.bays]
    vt = np.array([prof(x) for x in t])
    v, cur = _waves(t, vt, s, st.mva, np.random.default_rng(0))
    (tmp_path / "r").mkdir()
    write_record(tmp_path / "r" / "shallow.cfg", st, dt.datetime(2025, 3, 1), v, cur)
    out = scan(tmp_path / "r", tmp_path / "a.db")
    assert out.events == 2 and out.usable == 2
    (depth,) = {round(r[0], 2) for r in _rows(tmp_path / "a.db", "SELECT depth FROM events")}
    assert depth == 0.05
    assert find_sags(t, vt) == []  # IEEE 1159's 0.9 (`loadbayes events`' default) misses it


def test_bay_rules_from_the_user_come_before_the_defaults(archive, tmp_path):
    rules = tmp_path / "rules.toml"
    rules.write_text('"Abgang" = "feeder"\n"Feeder 2" = "skip"\n', encoding="utf-8")
    folder, db, out, _ = _scanned(archive, tmp_path, rules=rules)
    kinds = dict(_rows(db, "SELECT DISTINCT bay, kind FROM bays"))
    assert kinds["Abgang Süd"] == "feeder" and kinds["Feeder 2"] == "skip"
    (status,) = {r[0] for r in _rows(db, "SELECT status FROM bays WHERE bay = 'Feeder 2'")}
    assert status == "skipped"
    assert not _rows(db, "SELECT 1 FROM events WHERE bay = 'Feeder 2'")


@pytest.mark.parametrize(
    ("name", "kind"),
    [("1号主变_高压侧_201开关_I", "transformer"), ("10kV出线3", "feeder"),
     ("TX1 HV", "transformer"), ("T2", "transformer"), ("Feeder 7", "feeder"),
     ("220kV母联_200开关_I", "coupler"),
     ("220kV线路1", "line"), ("Bay 9", "unknown"), ("Station load", "load")],
)  # fmt: skip
def test_the_default_bay_rules(name, kind):
    assert bay_kind(name) == kind


def test_a_bad_rules_file_is_one_line_naming_it(tmp_path):
    bad = tmp_path / "rules.toml"
    bad.write_text('"主变" = 3\n', encoding="utf-8")
    with pytest.raises(DataError, match=r"rules.toml: rule '主变': the kind must be text"):
        read_rules(bad)
    bad.write_text('"re:[" = "feeder"\n', encoding="utf-8")
    with pytest.raises(DataError, match="not a regular expression"):
        read_rules(bad)


def test_the_command_scans_and_says_what_it_found_in_one_line_per_broken_file(archive, tmp_path):
    root, _ = archive
    db = tmp_path / "a.db"
    r = CliRunner().invoke(main, ["archive", "scan", str(root / "records"), "--catalog", str(db)])
    assert r.exit_code == 0, r.output
    assert "3 broken file(s)" in r.output and "broken: " in r.output
    r = CliRunner().invoke(
        main, ["archive", "scan", str(tmp_path / "nowhere"), "--catalog", str(db)]
    )
    assert r.exit_code == 2
    assert r.output.strip().splitlines() == [
        f"loadbayes: error: {tmp_path / 'nowhere'}: folder not found"
    ]


def test_the_example_archive_is_scanned_with_its_broken_files_and_truth(tmp_path):
    from loadbayes.cases.archive_example import archive_files

    for name, content in archive_files(records=1).items():
        (tmp_path / "ex" / name).parent.mkdir(exist_ok=True)
        (tmp_path / "ex" / name).write_bytes(content)
    out = scan(tmp_path / "ex", tmp_path / "a.db")
    assert (out.new, out.broken, out.events, out.usable) == (5, 2, 6, 6)
    truth = pd.read_csv(tmp_path / "ex" / "truth.csv")
    assert len(truth) == 6 and truth["f_m"].between(0.05, 0.9).all()
    stations = {r[0] for r in _rows(tmp_path / "a.db", "SELECT DISTINCT station FROM events")}
    assert stations == set(truth["station"])


def test_fits_that_fail_are_recorded_with_their_reason_and_not_retried_unless_asked(
    archive, tmp_path
):
    from loadbayes.archive import failures_frame, fit

    folder, db, out, _ = _scanned(archive, tmp_path)
    for dat in folder.rglob("*.dat"):
        dat.unlink()  # the records gone after the scan: every fit fails, none stops the run
    run = fit(db, draws=100, burn=0)
    assert (run.done, run.failed) == (0, out.usable)
    failed = failures_frame(db).query("what == 'fit'")
    assert len(failed) == out.usable
    assert failed["reason"].str.contains(r"zip\+motor: .*\.dat not found", regex=True).all()
    assert (fit(db).failed, fit(db).skipped) == (0, out.usable)
    assert fit(db, retry_failed=True, draws=100, burn=0).failed == out.usable


def test_the_defaults_are_the_composite_fits_first_round_with_the_chains_on_the_cores(
    archive, tmp_path, monkeypatch
):
    # Before, 3,000 draws after 1,000 x 2 chains: the chains of 2 of 6 example events had
    # not mixed on the share, and the pool left them out (archive/fit.py says the numbers).
    import importlib

    from loadbayes.fit.composite.driver import COMPOSITE_DEFAULTS
    from loadbayes.fleet.engine import Engine

    fit_module = importlib.import_module("loadbayes.archive.fit")
    d = COMPOSITE_DEFAULTS
    assert (fit_module.DRAWS, fit_module.BURN, fit_module.CHAINS) == (d.draws, d.burn, d.chains)
    from loadbayes.commands.archive import archive_fit_cmd

    shown = {p.name: p.default for p in archive_fit_cmd.params}
    assert (shown["draws"], shown["burn"], shown["chains"]) == (d.draws, d.burn, d.chains)
    _, db, out, _ = _scanned(archive, tmp_path)
    seen = []
    monkeypatch.setattr(Engine, "map", lambda self, func, items, **kw: seen.extend(items) or [])
    fit_module.fit(db)
    # In this process one event runs at a time, so its chains take the cores (threads None:
    # the fit's default); a Dask worker's task keeps one thread (the same draws either way:
    # test_archive_fit's one process against two workers).
    assert len(seen) == out.usable
    assert {(t.draws, t.burn, t.chains, t.threads) for t in seen} == {(6000, 4000, 4, None)}
    assert fit_module.FitTask.__dataclass_fields__["threads"].default == 1


def test_the_demo_says_which_events_intervals_miss_their_truth_and_on_which_side():
    from loadbayes.studies.archive import _misses

    def frame(means):
        return pd.DataFrame({"mean": means, "true": 1.0, "covered": [m == 1.0 for m in means]})

    assert _misses(frame([1.0, 1.0])) == ""
    assert _misses(frame([1.0, 1.1])).startswith("; the one that misses it (above) is read")
    assert "the 2 that miss it (all above) are" in _misses(frame([1.2, 1.1]))
    assert "(all above) are read further from it than each one's noise allows: a bias" in (
        _misses(frame([1.2, 1.1])))  # fmt: skip
    mixed = _misses(frame([1.2, 0.9]))
    assert "the 2 that miss it (1 above, 1 below) are" in mixed and "bias" not in mixed
