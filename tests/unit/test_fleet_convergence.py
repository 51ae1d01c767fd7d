"""Pooled fleets say when they have not converged, continue chains exactly, keep a given P0."""

import itertools
import types

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet import hierarchical as H
from loadbayes.fleet.generate import fleet_truth, write_fleet
from loadbayes.fleet.partitions import ReadSpec, find_partitions
from loadbayes.fleet.run import run_fleet
from loadbayes.fleet.stats import finish, partition_stats
from loadbayes.fleet.summary import read_fleet
from loadbayes.models.zip import ZIPModel

SPEC = ReadSpec(class_col="customer_class")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    write_fleet(fleet_truth(30, seed=4, rows=(10, 400)), folder, layout="table")
    return str(folder / "fleet.parquet")


@pytest.fixture
def clock(monkeypatch):
    """The pooled run's clock, 0.6 s a reading: the budget's rounds pinned, not timed.

    With ``max_seconds=3`` the readings after rounds 1, 2 and 3 are 0.6, 1.2 and 1.8 s
    spent; a round runs as long as all before it, so the run stops after the third
    (1.8 + 1.8 > 3) unless every class has converged before: the same rounds on any
    machine (on the wall clock a loaded machine ran fewer, an idle one more), and three,
    so that doubling rounds (240 sweeps) and fixed-length ones (180) differ.
    """
    from loadbayes.fleet import run

    ticks = itertools.count(0.0, 0.6)
    monkeypatch.setattr(run, "time", types.SimpleNamespace(monotonic=lambda: next(ticks)))


def test_too_few_draws_name_the_unconverged_classes(fleet):
    # 2 chains x 40 kept draws: no class can reach ESS 400, so every class is named.
    sampler = SamplerSettings(chains=2, draws=60, burn=20, seed=1)
    res = run_fleet(fleet, SPEC, pool="class", sampler=sampler)
    cls = res.table[res.table["level"] == "class"]
    assert (cls["warnings"].str.contains("not converged")).all()
    assert not cls["converged"].all()
    said = " ".join(res.settings["warnings"])
    for name in cls["class"].unique():
        assert f"class {name!r} not converged" in said
    assert res.settings["stop"].startswith("stopped after 60 sweeps")


def test_the_cli_says_it_on_stderr_and_in_the_file(fleet, tmp_path):
    out = tmp_path / "f.parquet"
    args = ["fit", "zip", fleet, "--by", "bus_id", "--class-col", "customer_class",
            "--pool", "class", "--draws", "60", "--burn", "20", "--chains", "2",
            "--max-seconds", "0", "--out", str(out)]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    assert "warning: class 'residential' not converged" in res.stderr
    assert "class means and spreads" in res.stdout and "not converged" in res.stdout
    table, settings = read_fleet(out)
    assert settings["pool"] == "class" and settings["converged"] is False
    assert any("not converged" in w for w in settings["warnings"])
    assert {"p0", "q0", "dp_dv", "dq_dv"} <= set(table["parameter"].dropna())


def test_a_budget_continues_the_chains_until_the_classes_converge(fleet, clock):
    sampler = SamplerSettings(chains=2, draws=60, burn=20, seed=1)
    one = run_fleet(fleet, SPEC, pool="class", sampler=sampler).settings
    more = run_fleet(fleet, SPEC, pool="class", sampler=sampler, max_seconds=3).settings
    assert more["sweeps"] > one["sweeps"] == 60
    assert ("R-hat < 1.01" in more["stop"]) or ("budget" in more["stop"])
    # Each round runs as many sweeps as all before it (R-hat on the later half of an
    # ever longer chain), not a fixed window that may never show convergence.
    assert more["sweeps"] == 60 * 2 ** (more["rounds"] - 1), more


def test_continued_rounds_keep_the_first_rounds_number_of_draws(fleet, clock):
    # A thinned run: the first round keeps 20 of 60 (one in 2 after 20); every later
    # round keeps no more (memory as in the first round), and never thins less.
    sampler = SamplerSettings(chains=2, draws=60, burn=20, thin=2, seed=1)
    more = run_fleet(fleet, SPEC, pool="class", sampler=sampler, max_seconds=3).settings
    assert more["rounds"] > 1, more
    last = more["sweeps"] // 2
    assert more["kept_thin"] >= 2
    assert len(range(0, last, more["kept_thin"])) <= 20, more


def _data(fleet, p0="auto"):
    model = ZIPModel(p0=p0, q0=p0)
    stats = finish(partition_stats(find_partitions(fleet)[0], SPEC, model))
    return H.prepare(stats, model)[0]


@pytest.mark.parametrize("scale", [None, 0.5], ids=["fixed-scale", "learned-scale"])
def test_a_continued_chain_is_one_long_chain(fleet, scale):
    # the learned class scales (spread_scale) are part of the state a chain hands on
    data = _data(fleet)
    seed = H.chain_seeds(3, 1)[0]
    prior = H.HierPrior(spread_scale=scale)
    first = H.run_chain(seed, data, prior, SamplerSettings(chains=1, draws=30, burn=10))
    rest = H.run_chain(first.state, data, prior, SamplerSettings(chains=1, draws=30, burn=10))
    whole = H.run_chain(seed, data, prior, SamplerSettings(chains=1, draws=50, burn=10))
    for name in ("theta", "tau", "p0", "mu", "sigma"):
        joined = np.concatenate([getattr(first, name), getattr(rest, name)])
        np.testing.assert_array_equal(joined, getattr(whole, name))
    assert rest.state.sweeps == 50


def test_a_given_p0_stays_fixed(fleet):
    data = _data(fleet, p0=2.0)
    draws = H.run_chain(
        H.chain_seeds(0, 1)[0], data, H.HierPrior(), SamplerSettings(draws=20, burn=5)
    )
    assert np.all(draws.p0 == np.float32(2.0))


def test_the_p0_draw_is_the_conditional_normal():
    # One bus, P only, theta pinned by a tight prior: s | theta, t ~ N(a'X'y / a'Ga, 1/(t a'Ga)).
    rng = np.random.default_rng(0)
    x = np.column_stack([np.ones(50), rng.uniform(-0.05, 0.05, (50, 2))])
    y = 3.0 * (x @ np.array([1.0, 0.2, 0.3])) + 0.01 * rng.standard_normal(50)
    g3, xy = (x.T @ x)[None], (x.T @ y)[None, None]
    beta = np.linalg.solve(g3[0], xy[0, 0])[None, None]
    ssr = np.array([[y @ y - beta[0, 0] @ xy[0, 0]]])
    theta = np.array([[0.2, 0.3]])
    s, t = np.array([[1.0]]), np.array([[4.0]])
    chol = np.array([[[1e6, 0.0], [0.0, 1e6]]])  # sqrt of a huge prior precision
    u = np.zeros((1, 2))
    zs = np.array([[1.5]])
    H._bus_sweep(np.zeros(1, np.int64), chol, u, np.ones(1, bool), (1e12 * theta), g3, xy,
                 beta, ssr, np.zeros((1, 1), bool), np.full((1, 1), 1e-9), theta.copy(), s, t,
                 np.zeros((1, 2)), zs, np.ones((1, 1)))  # fmt: skip
    a = np.array([1.0, 0.2, 0.3])
    gg, gy = a @ g3[0] @ a, a @ xy[0, 0]
    assert s[0, 0] == pytest.approx(gy / gg + 1.5 / np.sqrt(4.0 * gg), rel=1e-6)


def test_draws_streamed_to_disk_are_the_draws_in_memory(fleet, tmp_path):
    data = _data(fleet)
    seed = H.chain_seeds(2, 1)[0]
    sampler = SamplerSettings(chains=1, draws=250, burn=20, thin=2)  # 115 kept: 2 blocks
    here = H.run_chain(seed, data, H.HierPrior(), sampler)
    there = H.run_chain(seed, data, H.HierPrior(), sampler, store=str(tmp_path / "c.nc"))
    assert isinstance(there.theta, H.StoredDraws)
    for name in ("theta", "tau", "p0"):
        np.testing.assert_array_equal(getattr(there, name)[:, 3:9], getattr(here, name)[:, 3:9])
    np.testing.assert_array_equal(there.mu, here.mu)


def test_a_streamed_pooled_fit_gives_the_same_table(fleet, monkeypatch):
    from loadbayes.fleet import run

    sampler = SamplerSettings(chains=2, draws=120, burn=20, seed=4)
    here = run_fleet(fleet, SPEC, pool="class", sampler=sampler)
    monkeypatch.setattr(run, "STREAM_BYTES", 0)  # stream every draw to disk
    there = run_fleet(fleet, SPEC, pool="class", sampler=sampler, max_seconds=1e-9)
    assert there.settings["streamed"] and not here.settings["streamed"]
    pd.testing.assert_frame_equal(here.table, there.table, check_exact=True)


def test_the_chains_run_on_while_a_class_ess_is_short_of_400():
    # The warnings call a class unconverged at ESS < 400 even with R-hat < 1.01; the
    # run-on rule is the same (a one-class fleet stopped "converged" at ESS 398 before).
    from loadbayes.fleet.run import classes_converged

    s = SamplerSettings(chains=4, draws=2500, burn=500)
    assert classes_converged([1.003, 1.004], [398.0, 2000.0], s) == (False, True)
    assert classes_converged([1.003, 1.004], [400.0, 2000.0], s) == (True, True)
    assert classes_converged([1.011, 1.004], [4000.0, 2000.0], s) == (False, True)
    # too few kept draws for ESS 400 ever (a round keeps the first round's number): R-hat
    small = SamplerSettings(chains=2, draws=60, burn=20)
    assert classes_converged([1.003], [70.0], small) == (True, False)
    assert classes_converged([1.003], [70.0], SamplerSettings(chains=1, draws=60, burn=20)) == (
        None,
        False,
    )


def _fleet_file(tmp_path, buses, rows: int, *, seed: int):
    """A ZIP fleet of ``buses`` = [(class, voltage half-width)], ``rows`` rows each."""
    rng = np.random.default_rng(seed)
    frames = []
    for i, (cls, width) in enumerate(buses):
        x = 1 + rng.uniform(-width, width, rows)
        p = 1.5 * (0.3 * x**2 + 0.4 * x + 0.3) * (1 + rng.normal(0, 0.003, x.size))
        q = 0.5 * (0.5 * x**2 + 0.2 * x + 0.3) * (1 + rng.normal(0, 0.003, x.size))
        frames.append(pd.DataFrame({"bus_id": f"b{i}", "customer_class": cls, "v": x,
                                    "p": p, "q": q}))  # fmt: skip
    path = tmp_path / "f.parquet"
    pd.concat(frames, ignore_index=True).to_parquet(path)
    return path


def test_a_class_whose_buses_all_have_flat_voltage_says_the_prior_decides_its_mean(tmp_path):
    """Its class means were the hyperprior's (intervals of +/-15) on rows without a word."""
    path = _fleet_file(tmp_path, [("flat", 1e-5)] * 4 + [("moving", 0.05)] * 4, 150, seed=3)
    sampler = SamplerSettings(chains=2, draws=300, burn=100, seed=0)
    res = run_fleet(str(path), SPEC, pool="class", p0="auto", q0="auto", sampler=sampler)
    cls = res.table[res.table["level"] == "class"].groupby("class")["warnings"].first()
    assert cls["flat"].startswith("the prior decides the class mean of a1, a2, a4, a5")
    assert "the prior decides" not in cls["moving"]
    assert any(w.startswith("class 'flat': the prior decides") for w in res.settings["warnings"])


def test_a_class_of_one_bus_says_its_spreads_are_the_priors(tmp_path):
    """One bus holds no variation between buses: its class's sd_* repeated the prior's
    0.1 on clean rows (red-team finding); a class of five buses gets no such note."""
    path = _fleet_file(tmp_path, [("alone", 0.05)] + [("many", 0.05)] * 5, 200, seed=5)
    sampler = SamplerSettings(chains=2, draws=300, burn=100, seed=0)
    res = run_fleet(str(path), SPEC, pool="class", p0="auto", q0="auto", sampler=sampler)
    cls = res.table[res.table["level"] == "class"]
    alone = cls[cls["class"] == "alone"].set_index("parameter")["warnings"]
    assert alone["sd_a1"].startswith("only 1 bus in this class: its spreads (sd_a1,")
    assert "only 1 bus" not in alone["a1"]  # the mean is the bus's own estimate
    assert not cls.loc[cls["class"] == "many", "warnings"].str.contains("only").any()
    assert any(w.startswith("class 'alone': only 1 bus") for w in res.settings["warnings"])
