"""The pooled chains in threads: the same bits as one chain after another, on disk or not."""

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.parallel import ChainsStopped
from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet import hierarchical as H
from loadbayes.fleet import run
from loadbayes.fleet.engine import Engine
from loadbayes.fleet.stats import FleetStats
from loadbayes.models.zip import ZIPModel


def _stats(seed=0, buses=30):
    """Per-bus Gram matrices of a ZIP fleet made here (3 classes, P and Q, known P0)."""
    rng = np.random.default_rng(seed)
    names = ("1", "z1", "z2", "rp", "rq")
    grams, lo, hi, n = [], [], [], []
    for _ in range(buses):
        rows = int(rng.integers(20, 200))
        x = 1.0 + rng.uniform(-0.05, 0.05, rows)
        shares = np.array([0.4, 0.3, 0.5, 0.2]) + 0.05 * rng.standard_normal(4)
        # r = P / P0 - 1 = a1 (x^2 - 1) + a2 (x - 1) + noise, likewise Q
        z1, z2 = x**2 - 1.0, x - 1.0
        rp = shares[0] * z1 + shares[1] * z2 + 0.01 * rng.standard_normal(rows)
        rq = shares[2] * z1 + shares[3] * z2 + 0.01 * rng.standard_normal(rows)
        cols = np.stack([np.ones(rows), z1, z2, rp, rq], axis=1)
        grams.append(cols.T @ cols)
        lo.append(cols.min(axis=0))
        hi.append(cols.max(axis=0))
        n.append(rows)
    classes = np.array([("a", "b", "c")[b % 3] for b in range(buses)], dtype=object)
    return FleetStats(
        names, np.array([f"bus{b}" for b in range(buses)], dtype=object), classes,
        np.array(grams), np.array(n), np.array(lo), np.array(hi), np.zeros(buses, bool),
        np.zeros(buses, np.int64),
    )  # fmt: skip


SAMPLER = SamplerSettings(chains=4, draws=120, burn=20, seed=5)


def _fit(monkeypatch, threads, stream):
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", str(threads))
    monkeypatch.setattr(run, "STREAM_BYTES", 0 if stream else 2**40)
    model = ZIPModel(v0=1.0, p0=1.0, q0=1.0, with_q=True)
    return run.fit_fleet(_stats(), model, pool="class", sampler=SAMPLER, accept_units=True)


@pytest.mark.parametrize("stream", [False, True])
def test_chains_in_two_threads_give_the_same_table_as_in_one(monkeypatch, stream):
    one = _fit(monkeypatch, 1, stream)
    two = _fit(monkeypatch, 2, stream)
    assert one.attrs["loadbayes"]["streamed"] is stream
    assert (one["level"] == "bus").sum() > 0 and one["mean"].notna().all()
    pd.testing.assert_frame_equal(one, two, check_exact=True)


def test_a_failing_chain_stops_the_others(monkeypatch):
    # One chain raises: the run fails with that error, not with a hang or a partial table.
    calls = []
    real = H.run_chain

    def flaky(start, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("chain 2 broke")
        return real(start, *args, **kwargs)

    monkeypatch.setattr(H, "run_chain", flaky)
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "2")
    data, _ = H.prepare(_stats(), ZIPModel(with_q=True))
    with pytest.raises(RuntimeError, match="chain 2 broke"):
        run._map_chains(Engine(), [(s, None) for s in H.chain_seeds(1, 4)], data,
                        H.HierPrior(), SAMPLER)  # fmt: skip


def test_a_set_stop_flag_ends_a_chain_within_a_sweep():
    import threading

    data, _ = H.prepare(_stats(), ZIPModel(with_q=True))
    stop = threading.Event()
    stop.set()
    with pytest.raises(ChainsStopped):
        H.run_chain(H.chain_seeds(1, 1)[0], data, H.HierPrior(), SAMPLER, stop=stop)


def test_summary_batches_in_threads_change_nothing(monkeypatch):
    data, _ = H.prepare(_stats(), ZIPModel(with_q=True))
    chains = [H.run_chain(s, data, H.HierPrior(), SAMPLER) for s in H.chain_seeds(2, 3)]
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "1")
    one = H.summarize_chains(data, chains, SAMPLER, batch=128)
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "2")
    many = H.summarize_chains(data, chains, SAMPLER, batch=7)
    assert len(one) == 3 * 10 + 30 * 12  # classes: 6 shares, 4 spreads
    pd.testing.assert_frame_equal(one, many, check_exact=True)


def test_one_blas_thread_caps_the_pools_during_the_call_only():
    """The composite fit's small least squares run on one BLAS thread, then the pools are
    as they were (threadpoolctl; a 2,402 x 7 lstsq cost 160 times the CPU on two)."""
    from threadpoolctl import threadpool_info

    from loadbayes.core.parallel import one_blas_thread
    from loadbayes.fit.composite import driver, reading

    def counts():
        return [p["num_threads"] for p in threadpool_info()]

    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=2):  # the suite's workers cap BLAS at one (conftest)
        before = counts()
        inside = one_blas_thread(counts)()
        assert inside and all(n == 1 for n in inside)
        assert counts() == before
    # Where the fit spends its BLAS: the reading's two NLS fits, and NLS + chains.
    for f in (reading.choose_reading, driver.fit_composite):
        names = [f.__code__.co_name]
        while hasattr(f, "__wrapped__"):
            f = f.__wrapped__
            names.append(f.__code__.co_name)
        assert "capped" in names
