"""``loadbayes archive fit``: resumed after a kill, the same on 2 Dask workers, the real record.

The archive is the tests' own (tests/archive_generator.py: a SciPy ZIP + motor behind each
bay); few events and short chains, since what is checked here is the bookkeeping (each
event fitted once, every result kept, the draws independent of where they ran), not the
posterior's accuracy.

The fit in one process that the Dask runs are compared with is made once (``one_process``),
and the two Dask tests share one local cluster of two worker processes (``cluster``, the
way ``Engine(client=...)`` is documented for tests): starting a cluster and loading the
kernels in its workers was most of each test's time. ``Engine(workers=N)``, which starts
its own cluster, is run by tests/integration/test_cli_fleet_files.py (``--workers 2``).
"""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from archive_generator import write_archive
from loadbayes.archive import fit, fits_frame, scan
from loadbayes.cli import main

pytestmark = pytest.mark.integration

#: Short chains: the checks are on bookkeeping and determinism.
RUN = {"draws": 300, "burn": 100, "chains": 2, "seed": 7}


@pytest.fixture(scope="module")
def scanned(tmp_path_factory):
    root = tmp_path_factory.mktemp("fitarchive")
    write_archive(root / "records", records=1, seed=5, specials=False)
    out = scan(root / "records" / "station2", root / "archive.db")
    assert out.usable == 2
    return root / "archive.db"


@pytest.fixture(scope="module")
def one_process(scanned, tmp_path_factory) -> pd.DataFrame:
    """The catalog's events fitted in this process: the parameters the Dask runs must give."""
    here = _copy(scanned, tmp_path_factory.mktemp("one"))
    run = fit(here, **RUN)
    assert run.where == "in-process" and run.done == 2
    return _params(here)


@pytest.fixture(scope="module")
def cluster():
    """A local cluster of two worker processes and its client, shared by the Dask tests.

    Its dashboard on a free loopback port: ``dashboard_address=None`` is distributed's
    default, 8787, and under ``-n 2`` the other test worker's cluster (this fixture's own,
    or test_fleet_dask's) held it once: "Port 8787 is already in use" (30 Nov 2026).
    """
    distributed = pytest.importorskip("dask.distributed")
    with (
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                 dashboard_address="127.0.0.1:0") as local,
        distributed.Client(local) as client,
    ):  # fmt: skip
        yield client


def _copy(db: Path, to: Path) -> Path:
    to.mkdir(parents=True, exist_ok=True)
    shutil.copy(db, to / "archive.db")
    return to / "archive.db"


def _params(db: Path) -> pd.DataFrame:
    with sqlite3.connect(db) as conn:
        return pd.read_sql_query(
            "SELECT event_id, model, name, mean, sd, lo, hi, rhat, ess FROM params "
            "ORDER BY event_id, name",
            conn,
        )


def _fits(db: Path) -> pd.DataFrame:
    with sqlite3.connect(db) as conn:
        return pd.read_sql_query("SELECT event_id, status, seed, finished_at FROM fits", conn)


def test_a_killed_run_resumes_with_nothing_fitted_twice_and_nothing_lost(scanned, tmp_path):
    db = _copy(scanned, tmp_path)
    seen: list[str] = []

    def kill_after_one(result, done, failed, left):
        seen.append(result["event_id"])
        raise KeyboardInterrupt  # the run killed after its first result was committed

    with pytest.raises(KeyboardInterrupt):
        fit(db, progress=kill_after_one, **RUN)
    first = _fits(db)
    assert list(first["event_id"]) == seen and len(seen) == 1
    assert (Path(db).parent / "archive.results").is_dir()
    again: list[str] = []
    run = fit(db, progress=lambda r, *_: again.append(r["event_id"]), **RUN)
    assert (run.done, run.skipped) == (1, 1)
    assert not set(again) & set(seen)  # nothing fitted twice
    both = _fits(db)
    assert len(both) == 2 and set(both["status"]) == {"done"}  # nothing lost
    kept = both.set_index("event_id").loc[seen[0], "finished_at"]
    assert kept == first.set_index("event_id").loc[seen[0], "finished_at"]
    third = fit(db, **RUN)
    assert (third.done, third.failed, third.skipped) == (0, 0, 2)
    frame = fits_frame(db)
    assert list(frame.columns) == ["station", "bay", "event_id", "time", "model", "part", "mean",
                                   "sd", "lo", "hi", "rhat", "ess", "status"]  # fmt: skip
    assert set(frame["part"]) == {"f_m"} and len(frame) == 2
    assert frame["time"].dtype.kind == "M"
    for nc in Path(db).parent.glob("archive.results/*.nc"):
        assert nc.stat().st_size > 0


def test_one_process_and_two_dask_workers_give_the_same_results(
    scanned, one_process, cluster, tmp_path
):
    there = _copy(scanned, tmp_path / "two")
    run = fit(there, client=cluster, **RUN)
    assert run.where == "dask (2 workers)" and run.done == 2
    b = _params(there)
    assert len(one_process) > 0
    # bit for bit: seeds from the events, not the order
    pd.testing.assert_frame_equal(one_process, b)


def _real():
    for folder in Path(__file__).resolve().parents:
        if (folder / "shared" / "real" / "xtz.cfg").is_file():
            return folder / "shared" / "real" / "xtz.cfg"
    return None


@pytest.mark.skipif(_real() is None, reason="shared/real is not beside the repository")
def test_the_real_record_goes_through_archive_scan_and_fit(tmp_path):
    real = _real()
    folder = tmp_path / "records" / "xtz"
    folder.mkdir(parents=True)
    for suffix in (".cfg", ".dat"):
        shutil.copy(real.with_suffix(suffix), folder)
    rules = tmp_path / "rules.toml"
    # Transformer #1 alone (one bay, two faults) keeps the test short.
    rules.write_text('"1号主变" = "transformer"\n\'re:.\' = "skip"\n', encoding="utf-8")
    db = tmp_path / "archive.db"
    runner = CliRunner()
    r = runner.invoke(main, ["archive", "scan", str(tmp_path / "records"), "--catalog", str(db),
                             "--rules", str(rules)])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "2 event(s) found, 2 usable" in r.output
    with sqlite3.connect(db) as conn:
        (row,) = conn.execute("SELECT station, recorder, encoding, revision FROM files")
        kinds = dict(conn.execute("SELECT bay, kind FROM bays"))
    assert row == ("xtz", "220kV线路", "gb18030", "1999")
    assert kinds["1号主变_高压侧_201开关_I"] == "transformer"
    assert kinds["2号主变_高压侧_202开关_I"] == "skip"
    r = runner.invoke(main, ["archive", "fit", "--catalog", str(db), "--draws", "300", "--burn",
                             "100"])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "2 fitted, 0 failed" in r.output
    frame = fits_frame(db)
    assert len(frame) == 2 and set(frame["bay"]) == {"1号主变_高压侧_201开关_I"}
    # The fault and the reclose 1.1 s later, on the recorder's clock.
    assert list(frame["time"].dt.strftime("%Y-%m-%d %H:%M:%S")) == [
        "2023-05-12 19:45:25", "2023-05-12 19:45:26"]  # fmt: skip


def test_a_worker_killed_on_a_local_cluster_loses_no_event(scanned, one_process, cluster, tmp_path):
    # Issue 38: a worker killed in the middle of a run loses no event. After the first
    # result the worker still fitting the other event is killed (os._exit); Dask re-runs
    # its task on the worker that is left (or the one the nanny restarts), and the
    # catalog ends with every event fitted once, the same bits as in one process.
    # The cluster is the one the test above ran on (its workers warm): this test kills
    # one of them, so it runs last.
    import os

    client = cluster
    there = _copy(scanned, tmp_path / "two")
    killed: list[str] = []

    def kill_busy(result, done, failed, left):
        busy = [w for w, keys in client.processing().items() if keys]
        if left and busy and not killed:
            killed.append(busy[0])
            try:  # the worker dies mid-call: the call itself may fail
                client.run(os._exit, 1, workers=[busy[0]], wait=False)
            except Exception:  # noqa: BLE001
                pass

    run = fit(there, client=client, progress=kill_busy, **RUN)
    assert killed, "no worker was busy when the first result came back"
    assert (run.done, run.failed) == (2, 0)
    fits = _fits(there)
    assert len(fits) == 2 and set(fits["status"]) == {"done"}
    pd.testing.assert_frame_equal(one_process, _params(there))
