"""``loadbayes events``: one transaction, no stale files, its input never overwritten.

Records written here (a flat 1 p.u. voltage with 30% sags of 0.2 s every 4 s, 50
samples/s), not by the package.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration


def _record(path, seconds=60.0, every=4.0):
    t = np.arange(int(seconds * 50)) / 50
    v = np.ones_like(t)
    for s in np.arange(5, seconds - 3, every):
        v[(t >= s) & (t < s + 0.2)] = 0.7
    df = pd.DataFrame({"t_s": t, "v": v, "p": v, "q": 0.4 * v})
    df.to_csv(path, index=False)
    return df


def _run(*args):
    return CliRunner().invoke(main, ["events", *map(str, args)])


def _last(res):
    return res.output.strip().splitlines()[-1]


def test_a_signal_while_writing_leaves_nothing(tmp_path, monkeypatch):
    _record(tmp_path / "rec.csv")
    import loadbayes.io.tables as tables

    real, calls = tables.write_table, []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(tables, "write_table", interrupted)
    res = _run(tmp_path / "rec.csv", "--out", tmp_path / "ev", "--quiet")
    assert res.exit_code == 130, res.output
    assert _last(res) == "loadbayes: interrupted; no output was written"
    assert not (tmp_path / "ev").exists()  # the folder it made, and every temporary, gone


def test_force_leaves_exactly_the_events_listed(tmp_path):
    _record(tmp_path / "long.csv", seconds=60.0)
    _record(tmp_path / "short.csv", seconds=20.0)
    assert _run(tmp_path / "long.csv", "--out", tmp_path / "ev", "--quiet").exit_code == 0
    res = _run(tmp_path / "short.csv", "--out", tmp_path / "ev", "--force", "--quiet")
    assert res.exit_code == 0, res.output
    listed = pd.read_csv(tmp_path / "ev" / "events.csv")["file"].tolist()
    files = sorted(p.name for p in (tmp_path / "ev").iterdir() if p.name != "events.csv")
    assert files == sorted(listed) and len(listed) == 3


@pytest.mark.parametrize("name", ["events.csv", "event_001.csv"])
def test_the_input_is_never_overwritten(tmp_path, name):
    (tmp_path / "ow").mkdir()
    df = _record(tmp_path / "ow" / name, seconds=20.0)
    res = _run(tmp_path / "ow" / name, "--out", tmp_path / "ow", "--force", "--quiet")
    assert res.exit_code == 2
    assert "would overwrite the input record" in _last(res)
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "ow" / name), df)


def test_located_time_error_option_errors_and_a_summary(tmp_path):
    df = _record(tmp_path / "rec.csv", seconds=120.0)  # 28 events
    df.loc[100, "t_s"] = df.loc[99, "t_s"]
    df.to_csv(tmp_path / "dup.csv", index=False)
    res = _run(tmp_path / "dup.csv", "--out", tmp_path / "d")
    assert res.exit_code == 2
    assert "column 't_s', row 101: t_s must be strictly increasing" in _last(res)
    for opt, value in (("--pre", "nan"), ("--post", "inf"), ("--min-duration", "nan")):
        res = _run(tmp_path / "rec.csv", "--out", tmp_path / "d", opt, value)
        assert res.exit_code == 2 and _last(res).startswith(f"loadbayes: error: {opt} ")
    res = _run(tmp_path / "rec.csv", "--out", tmp_path / "d")
    assert res.exit_code == 0
    lines = res.output.strip().splitlines()
    assert len(lines) == 12 and "18 more (listed in" in lines[-1]  # 28 events, 10 shown


def test_a_signal_while_removing_stale_events_waits_for_the_last(tmp_path, monkeypatch):
    # After the commit, --force removes the earlier run's event files under a hold of
    # SIGINT/SIGTERM. A per-thread signal mask held only in the main thread: the kernel
    # gave a signal sent to the process to another thread (here an idle one, as a BLAS or
    # Arrow pool's), Python ran the handler in the main thread at once, and the removal
    # stopped after the first file, leaving files events.csv does not list.
    import os
    import pathlib
    import signal
    import threading

    _record(tmp_path / "long.csv", seconds=60.0)
    _record(tmp_path / "short.csv", seconds=20.0)
    assert _run(tmp_path / "long.csv", "--out", tmp_path / "ev", "--quiet").exit_code == 0
    real, removed = pathlib.Path.unlink, []

    def unlink_then_a_signal(self, *args, **kwargs):
        real(self, *args, **kwargs)
        removed.append(self.name)
        if len(removed) == 1 and self.name.startswith("event_"):
            os.kill(os.getpid(), signal.SIGINT)

    idle = threading.Event()
    other = threading.Thread(target=idle.wait, daemon=True)
    other.start()
    monkeypatch.setattr(pathlib.Path, "unlink", unlink_then_a_signal)
    try:
        res = _run(tmp_path / "short.csv", "--out", tmp_path / "ev", "--force", "--quiet")
    finally:
        idle.set()
        other.join()
    monkeypatch.undo()
    assert res.exit_code == 130, res.output
    assert _last(res) == "loadbayes: interrupted after every output was written"
    listed = pd.read_csv(tmp_path / "ev" / "events.csv")["file"].tolist()
    files = sorted(p.name for p in (tmp_path / "ev").iterdir() if p.name != "events.csv")
    assert files == sorted(listed) and len(listed) == 3
    assert len([n for n in removed if n.startswith("event_")]) == 13 - 3  # all stale ones


@pytest.mark.parametrize("out", ["", "-"])
def test_an_empty_or_dash_out_is_refused(tmp_path, monkeypatch, out):
    # Red-team L5: --out '' wrote the events into the working folder, "written to " (blank).
    monkeypatch.chdir(tmp_path)
    _record(tmp_path / "rec.csv")
    res = _run("rec.csv", "--out", out)
    assert res.exit_code == 2, res.output
    assert res.output.strip() == f"loadbayes: error: --out {out!r}: give the folder to write to"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv"]


def test_an_empty_cell_names_a_remedy_events_has(tmp_path):
    # Red-team L2: the message offered --drop-invalid, which events does not have.
    df = _record(tmp_path / "rec.csv")
    df.loc[5, "v"] = np.nan
    df.to_csv(tmp_path / "holed.csv", index=False)
    res = _run(tmp_path / "holed.csv", "--out", tmp_path / "ev")
    assert res.exit_code == 2, res.output
    assert "holed.csv: column 'v', row 6: empty cell" in res.output
    assert "drop-invalid" not in res.output and "fill the cell or delete the row" in res.output


def test_a_record_table_without_phasor_rows_is_refused(tmp_path):
    # Red-team L13: a `read comtrade` table with amplitude rows only gave "0 event(s)".
    t = np.arange(200) / 50
    pd.DataFrame({"t_s": t, "v": np.ones_like(t), "p": 1.0, "q": 0.4, "segment": 0,
                  "kind": "amplitude"}).to_csv(tmp_path / "amp.csv", index=False)  # fmt: skip
    res = _run(tmp_path / "amp.csv", "--out", tmp_path / "ev")
    assert res.exit_code == 2, res.output
    assert "amp.csv: no phasor rows (200 amplitude rows)" in res.output
    assert not (tmp_path / "ev").exists()


def test_a_sidecar_of_another_format_says_which(tmp_path):
    # Red-team L4: a sidecar with "format": "other" was said to have "no 'format' key".
    t = np.arange(200) / 50
    pd.DataFrame({"t_s": t, "v": np.ones_like(t), "p": 1.0, "q": 0.4, "segment": 0,
                  "kind": "phasor"}).to_csv(tmp_path / "r.csv", index=False)  # fmt: skip
    (tmp_path / "r.csv.meta.json").write_text('{"format": "other"}')
    res = _run(tmp_path / "r.csv", "--out", tmp_path / "ev")
    assert res.exit_code == 2, res.output
    assert "r.csv.meta.json: not a loadbayes record metadata file (format 'other'" in res.output
    (tmp_path / "r.csv.meta.json").write_text("[1, 2]")
    res = _run(tmp_path / "r.csv", "--out", tmp_path / "ev")
    assert "not a loadbayes record metadata file (no 'format' key)" in res.output
    assert not (tmp_path / "ev").exists()
