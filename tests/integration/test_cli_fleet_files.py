"""Issue 25, fleets: ids as file names (H4), --netcdf-dir as one transaction (M8), Dask's
raw log lines (L12), and ids that disagree or mix types (L17).

The fleets are written here (a ZIP bus per id, shares 0.3/0.2/0.5), not by the package.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration

EXE = [sys.executable, "-m", "loadbayes"]
SRC = str(Path(__file__).resolve().parents[2] / "src")
FAST = ["--draws", "300", "--burn", "100", "--chains", "2", "--quiet"]


def bus_rows(bus, n=150, seed=0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.94, 1.06, n)
    return pd.DataFrame(
        {
            "bus_id": bus,
            "v": v,
            "p": 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, n),
            "q": 0.4 * v**2 + 0.1 * v + 0.5 + rng.normal(0, 0.01, n),
        }  # fmt: skip
    )


def run(*args, cwd: Path, monkeypatch):
    monkeypatch.chdir(cwd)
    r = CliRunner().invoke(main, ["fit", "zip", *map(str, args)])
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        raise r.exception
    return r


# ----------------------------------------------------------------- H4: ids as paths
def test_bus_ids_never_choose_where_a_file_goes(tmp_path, monkeypatch):
    (tmp_path / "target").mkdir()
    victim = tmp_path / "target" / "victim.nc"
    victim.write_text("precious")
    ids = ["ok_bus", "../escaped", str(tmp_path / "target" / "victim"), ".hidden", "a%2Fb",
           "a/b"]  # fmt: skip
    pd.concat([bus_rows(b, seed=k) for k, b in enumerate(ids)]).to_csv(
        tmp_path / "ids.csv", index=False
    )
    r = run("ids.csv", "--by", "bus_id", "--out", "f.parquet", "--netcdf-dir", "out/nc",
            "--force", *FAST, cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert victim.read_text() == "precious"
    written = sorted(p.name for p in (tmp_path / "out" / "nc").iterdir())
    assert len(written) == len(ids)  # one each: the encoding is one-to-one
    assert all(not n.startswith(".") and "/" not in n for n in written), written
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["nc"]  # nothing escaped
    assert "ok_bus.nc" in written and "a%2Fb.nc" in written and "a%252Fb.nc" in written
    from loadbayes.posterior import Posterior

    post = Posterior.from_netcdf(tmp_path / "out" / "nc" / "%2E.%2Fescaped.nc")
    assert post.settings["bus"] == "../escaped"


def test_an_id_too_long_for_a_file_name_is_one_line_before_any_fit(tmp_path, monkeypatch):
    long_id = "x" * 300
    pd.concat([bus_rows("ok"), bus_rows(long_id, seed=1)]).to_csv(tmp_path / "ids.csv", index=False)
    r = run("ids.csv", "--by", "bus_id", "--out", "f.parquet", "--netcdf-dir", "nc", *FAST,
            cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2
    line = r.stderr.strip()
    assert len(line.splitlines()) == 1 and "too long for a file name" in line, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ids.csv"]  # nc/ removed too


def test_an_existing_bus_file_is_refused_before_the_fits(tmp_path, monkeypatch):
    pd.concat([bus_rows("b1"), bus_rows("b2", seed=1)]).to_csv(tmp_path / "f.csv", index=False)
    (tmp_path / "nc").mkdir()
    (tmp_path / "nc" / "b2.nc").write_text("old")
    r = run("f.csv", "--by", "bus_id", "--out", "f.parquet", "--netcdf-dir", "nc", *FAST,
            cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2 and "b2.nc" in r.stderr and "--force" in r.stderr, r.stderr
    assert sorted(p.name for p in (tmp_path / "nc").iterdir()) == ["b2.nc"]
    assert (tmp_path / "nc" / "b2.nc").read_text() == "old"
    assert not (tmp_path / "f.parquet").exists()


# ------------------------------------------------------- M8 (+ L12): SIGINT, one line
def _fleet(path: Path, buses: int) -> None:
    pd.concat([bus_rows(f"b{k}", n=200, seed=k) for k in range(buses)]).to_parquet(path)


def _interrupt(folder: Path, extra: list[str], wait_for, sig=signal.SIGINT):
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [*EXE, "fit", "zip", "fleet.parquet", "--by", "bus_id", "--out", "f.parquet",
           "--netcdf-dir", "nc", "--draws", "600", "--burn", "100", "--quiet", *extra]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=folder, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 240
    seen = False
    while not seen and proc.poll() is None and time.monotonic() < deadline:
        seen = wait_for()
        time.sleep(0.02)
    if proc.poll() is None:
        proc.send_signal(sig)
    _, err = proc.communicate(timeout=240)
    return proc.returncode, err, seen


def _staged(folder: Path) -> int:
    """Per-bus files written so far into the hidden staging folder."""
    nc = folder / "nc"
    if not nc.is_dir():
        return 0
    return sum(len(list(d.iterdir())) for d in nc.iterdir() if d.name.startswith("."))


def test_sigint_during_the_per_bus_files_leaves_none_and_says_so(tmp_path):
    """Red-team M8: SIGINT left 22-55 .nc files and said "no output was written"."""
    _fleet(tmp_path / "fleet.parquet", 60)
    code, err, seen = _interrupt(tmp_path, [], lambda: _staged(tmp_path) >= 3)
    left = sorted(p.name for p in tmp_path.iterdir())
    if code == 0:  # finished before the signal: everything, committed together
        assert len(list((tmp_path / "nc").iterdir())) == 60 and "f.parquet" in left
        pytest.skip("the fleet ended before the signal (machine too fast)")
    assert seen, err
    assert code == 130, err
    assert err.strip().splitlines() == ["loadbayes: interrupted; no output was written"], err
    assert left == ["fleet.parquet"], left  # no nc/ (this run made it), no f.parquet


def test_sigint_on_dask_workers_is_one_line(tmp_path):
    """L12: on SIGINT, no raw timestamped ``distributed.*`` lines; M8 on Dask too."""
    pytest.importorskip("distributed", reason="Dask is in the optional 'cluster' extra")
    _fleet(tmp_path / "fleet.parquet", 40)
    code, err, seen = _interrupt(tmp_path, ["--workers", "2"], lambda: _staged(tmp_path) >= 2)
    if code == 0:
        pytest.skip("the fleet ended before the signal (machine too fast)")
    assert code == 130, err
    assert err.strip().splitlines() == ["loadbayes: interrupted; no output was written"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.parquet"]


def test_a_completed_fleet_writes_the_table_and_every_bus_file(tmp_path, monkeypatch):
    _fleet(tmp_path / "fleet.parquet", 5)
    r = run("fleet.parquet", "--by", "bus_id", "--out", "f.parquet", "--netcdf-dir", "nc",
            *FAST, cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "nc").iterdir()) == [f"b{k}.nc" for k in range(5)]
    assert pd.read_parquet(tmp_path / "f.parquet").bus.nunique() == 5


def test_a_signal_in_the_middle_of_the_commit_leaves_every_bus_file(tmp_path, monkeypatch):
    """Red-team H1: SIGINT as the table landed left 0-134 of 800 bus files, and the message
    said every output was written. The signal is sent, to a thread other than the main
    one (as the kernel does when the main thread blocks it), right after the first bus
    file's rename."""
    import threading

    _fleet(tmp_path / "fleet.parquet", 5)
    real, nc = os.replace, (tmp_path / "nc").resolve()

    def signal_through_another_thread():
        ready, go = threading.Event(), threading.Event()

        def pool_thread():
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
            ready.set()
            go.wait()

        helper = threading.Thread(target=pool_thread, daemon=True)
        helper.start()
        ready.wait()
        signal.pthread_kill(helper.ident, signal.SIGINT)
        go.set()
        helper.join()

    def replace(src, dst):
        real(src, dst)
        if Path(dst).resolve().parent == nc and Path(dst).name == "b0.nc":
            signal_through_another_thread()

    monkeypatch.setattr(os, "replace", replace)
    r = run("fleet.parquet", "--by", "bus_id", "--out", "f.parquet", "--netcdf-dir", "nc",
            *FAST, cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 130, r.output
    assert r.stderr.strip().splitlines() == [
        "loadbayes: interrupted after every output was written"
    ], r.stderr
    assert sorted(p.name for p in (tmp_path / "nc").iterdir()) == [f"b{k}.nc" for k in range(5)]
    assert pd.read_parquet(tmp_path / "f.parquet").bus.nunique() == 5


# ------------------------------------------------------------------------------- L17
def test_folder_key_and_column_that_disagree_are_refused(tmp_path, monkeypatch):
    for k in (1, 2):
        (tmp_path / "hv" / f"bus_id={k}").mkdir(parents=True)
        bus_rows("zzz" if k == 1 else str(k), seed=k).to_parquet(
            tmp_path / "hv" / f"bus_id={k}" / "part-0.parquet"
        )
    r = run("hv", "--by", "bus_id", "--out", "f.parquet", *FAST, cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2
    line = r.stderr.strip()
    assert len(line.splitlines()) == 1, r.stderr
    for part in ("bus_id=1/part-0.parquet", "column 'bus_id'", "row 1", "'zzz'"):
        assert part in line, (part, line)


def test_a_readme_in_the_data_folder_is_not_data(tmp_path, monkeypatch):
    for k in (1, 2):
        (tmp_path / "hv" / f"bus_id={k}").mkdir(parents=True)
        bus_rows(str(k), seed=k).drop(columns="bus_id").to_parquet(
            tmp_path / "hv" / f"bus_id={k}" / "part-0.parquet"
        )
    (tmp_path / "hv" / "README.txt").write_text("where these meters are\n")
    r = run("hv", "--by", "bus_id", "--out", "f.parquet", *FAST, cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert sorted(pd.read_parquet(tmp_path / "f.parquet").bus.unique()) == ["1", "2"]
    # a CSV that is not data is still refused, and the message says how to leave it out
    (tmp_path / "hv" / "notes.csv").write_text("note\nhello\n")
    r = run("hv", "--by", "bus_id", "--out", "g.parquet", *FAST, cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2 and "notes.csv" in r.stderr and "glob" in r.stderr, r.stderr


def test_ids_stored_as_different_types_are_said_to_merge(tmp_path, monkeypatch):
    (tmp_path / "mix").mkdir()
    for k, val in enumerate([1, "1", 1.0]):
        bus_rows(val, seed=k).to_parquet(tmp_path / "mix" / f"f{k}.parquet")
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # pytest makes warnings errors; the CLI says them
        r = run("mix", "--by", "bus_id", "--out", "f.parquet", *FAST, cwd=tmp_path,
                monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "stored as float in" in r.stderr and "integer in" in r.stderr, r.stderr
    assert "text in" in r.stderr and "matched as text" in r.stderr
    # one type: no warning
    (tmp_path / "one").mkdir()
    for k in range(2):
        bus_rows(f"b{k}", seed=k).to_parquet(tmp_path / "one" / f"f{k}.parquet")
    r = run("one", "--by", "bus_id", "--out", "g.parquet", *FAST, cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0 and "matched as text" not in r.stderr, r.stderr


def test_ids_that_differ_by_spaces_around_them_are_said_to_merge(tmp_path, monkeypatch):
    # Red-team L6: ' sp' and 'sp ' were read as one bus 'sp' (n 400) without a word.
    pd.concat([bus_rows(" sp", n=120, seed=1), bus_rows("sp ", n=80, seed=2),
               bus_rows("other", seed=3)]).to_csv(tmp_path / "sp.csv", index=False)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # pytest makes warnings errors; the CLI says them
        r = run("sp.csv", "--by", "bus_id", "--out", "f.parquet", *FAST, cwd=tmp_path,
                monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert (
        "bus ids in column 'bus_id' are read without the spaces around them: ' sp' and "
        "'sp ' are bus 'sp'" in r.stderr
    ), r.stderr
    t = pd.read_parquet(tmp_path / "f.parquet")
    assert set(t["bus"]) == {"sp", "other"} and set(t.loc[t.bus == "sp", "n"]) == {200}
    # Ids without spaces: no word.
    bus_rows("b1").to_csv(tmp_path / "plain.csv", index=False)
    r = run("plain.csv", "--by", "bus_id", "--out", "g.parquet", *FAST, cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0 and "spaces around" not in r.stderr, r.stderr


def test_a_header_only_file_in_the_folder_is_skipped_and_named(tmp_path, monkeypatch):
    # Red-team of issue 24: one empty export among a fleet's files stopped every fit.
    # It holds no bus, so it is skipped and named; a folder of nothing else is refused.
    (tmp_path / "day").mkdir()
    for k in (1, 2):
        bus_rows(f"b{k}", seed=k).to_csv(tmp_path / "day" / f"b{k}.csv", index=False)
    (tmp_path / "day" / "b3.csv").write_text("bus_id,v,p,q\n")
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # pytest makes warnings errors; the CLI says them
        r = run("day", "--by", "bus_id", "--out", "f.parquet", *FAST, cwd=tmp_path,
                monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "1 file with no data rows skipped" in r.stderr and "b3.csv" in r.stderr, r.stderr
    assert sorted(pd.read_parquet(tmp_path / "f.parquet").bus.unique()) == ["b1", "b2"]
    (tmp_path / "none").mkdir()
    (tmp_path / "none" / "b3.csv").write_text("bus_id,v,p,q\n")
    r = run("none", "--by", "bus_id", "--out", "g.parquet", *FAST, cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2 and "no data rows in any file" in r.stderr, r.stderr
    assert not (tmp_path / "g.parquet").exists()
