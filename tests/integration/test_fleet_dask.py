"""The fleet on a real Dask LocalCluster: same bits as in-process, and a killed worker."""

import os

import pandas as pd
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.engine import Engine
from loadbayes.fleet.generate import fleet_truth, write_fleet
from loadbayes.fleet.partitions import ReadSpec
from loadbayes.fleet.run import run_fleet

pytestmark = pytest.mark.integration
distributed = pytest.importorskip("dask.distributed")

SAMPLER = SamplerSettings(draws=400, burn=100)
SPEC = ReadSpec(class_col="customer_class")


@pytest.fixture(scope="module")
def client():
    # One cluster for the module: starting one costs seconds. Its dashboard on a free
    # loopback port: dashboard_address=None is distributed's default, 8787, which another
    # test worker's cluster could hold at that moment (test_archive_fit's did once).
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0"
        ) as cluster,
        distributed.Client(cluster) as c,
    ):
        yield c


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    write_fleet(fleet_truth(24, seed=3, rows=(20, 1500)), folder, layout="files", buses_per_file=3)
    return str(folder)


@pytest.mark.parametrize("pool", ["none", "class"])
def test_cluster_result_is_bit_identical_to_in_process(client, fleet, pool):
    here = run_fleet(fleet, SPEC, pool=pool, sampler=SAMPLER, batch_buses=5).table
    with Engine(client=client) as eng:
        there = run_fleet(fleet, SPEC, pool=pool, sampler=SAMPLER, engine=eng, batch_buses=5)
    assert there.engine.startswith("dask")
    pd.testing.assert_frame_equal(here, there.table, check_exact=True)
    # the tasks' own CPU time and the wait for them are measured (the one-process note)
    assert 0.0 < eng.task_cpu_seconds
    assert 0.0 < eng.map_seconds


def test_a_killed_worker_loses_and_duplicates_no_bus(client, fleet):
    here = run_fleet(fleet, SPEC, sampler=SAMPLER, batch_buses=2).table
    killed = []

    def kill_one(n):
        if not killed:
            victim = sorted(client.scheduler_info()["workers"])[0]
            killed.append(victim)
            try:  # the worker dies mid-call: the call itself fails
                client.run(os._exit, 1, workers=[victim], wait=False)
            except Exception:  # noqa: BLE001
                pass

    with Engine(client=client) as eng:
        there = run_fleet(
            fleet, SPEC, sampler=SAMPLER, engine=eng, batch_buses=2, progress_files=kill_one
        ).table
    assert killed
    pd.testing.assert_frame_equal(here, there, check_exact=True)
    assert there.groupby(["bus", "parameter"]).size().max() == 1
    client.wait_for_workers(2, timeout=60)


def test_pooled_fit_on_one_worker_with_draws_on_disk_is_bit_identical(fleet, monkeypatch):
    # One worker process (the chains run there in turn), the draws streamed to disk
    # by the worker and read back by the client: the same table as in process.
    from loadbayes.fleet import run

    sampler = SamplerSettings(chains=2, draws=200, burn=50, seed=9)
    here = run_fleet(fleet, SPEC, pool="class", sampler=sampler).table
    monkeypatch.setattr(run, "STREAM_BYTES", 0)
    with Engine(workers=1) as eng:
        there = run_fleet(fleet, SPEC, pool="class", sampler=sampler, engine=eng)
    assert there.engine == "dask (1 workers)" and there.settings["streamed"]
    pd.testing.assert_frame_equal(here, there.table, check_exact=True)


def _listening(pid: int) -> list[tuple[str, int]]:
    """(address, port) of every listening TCP socket of ``pid`` and its children."""
    psutil = pytest.importorskip("psutil")
    procs = [psutil.Process(pid), *psutil.Process(pid).children(recursive=True)]
    out = []
    for p in procs:
        with __import__("contextlib").suppress(psutil.Error):
            out += [c.laddr for c in p.net_connections(kind="inet") if c.status == "LISTEN"]
    return [(a.ip, a.port) for a in out]


@pytest.mark.parametrize("dashboard", [False, True])
def test_a_local_cluster_listens_on_loopback_only_and_its_dashboard_is_off_unless_asked(
    dashboard,
):
    # The red-team's H9: LocalCluster(dashboard_address=":0") served the dashboard on
    # 0.0.0.0 (every interface) for the whole run, listing the workers to anyone.
    import urllib.error
    import urllib.request

    def status(url: str) -> int:
        try:
            with urllib.request.urlopen(url, timeout=10) as r:
                return r.status
        except urllib.error.HTTPError as err:
            return err.code

    with Engine(workers=1, dashboard=dashboard) as eng:
        socks = _listening(os.getpid())
        http = eng._own[-1].scheduler.http_server
        port = next(iter(http._sockets.values())).getsockname()[1]
        url = f"http://127.0.0.1:{port}"
        pages = [status(url + p) for p in ("/status", "/info/main/workers.html")]
        link = eng.dashboard_link
    assert socks, "no listening socket found: the check would pass vacuously"
    assert all(ip in ("127.0.0.1", "::1") for ip, _ in socks), socks
    if dashboard:
        assert link.startswith("http://127.0.0.1:") and pages == [200, 200]
    else:
        assert link is None and pages == [404, 404]
