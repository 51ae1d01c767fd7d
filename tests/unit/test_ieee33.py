"""Fast checks of the IEEE 33-bus data generator (needs pandapower)."""

from __future__ import annotations

import copy
import functools
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from loadbayes.cases import ieee33
from loadbayes.cases.ieee33 import DEFAULT_ZIP, N_FACTORS, ZIP_BUS, Feeder33
from loadbayes.studies.ieee33_validation import validate

pp = pytest.importorskip("pandapower")
pn = pytest.importorskip("pandapower.networks")

TOL = 1e-10  # the feeder's default tolerance_mva
COLUMNS = [
    "experiment",
    "v_pu",
    "p_true_pu",
    "q_true_pu",
    "p_meas_pu",
    "q_meas_pu",
    "v_meas_pu",
    "converged",
]


@pytest.fixture(scope="module")
def feeder() -> Feeder33:
    return Feeder33()


@functools.cache
def _case():
    return pn.case33bw()


def plain_runpp(factors, zip_p, zip_q):
    """A plain pandapower run on its own copy of the case: the reference for every engine."""
    net = copy.deepcopy(_case())
    (zl,) = net.load.index[net.load.bus == ZIP_BUS]
    others = net.load.bus != ZIP_BUS
    net.load.loc[others, "p_mw"] *= factors
    net.load.loc[others, "q_mvar"] *= factors
    net.load.loc[zl, ["const_z_p_percent", "const_i_p_percent"]] = np.asarray(zip_p[:2]) * 100
    net.load.loc[zl, ["const_z_q_percent", "const_i_q_percent"]] = np.asarray(zip_q[:2]) * 100
    pp.runpp(net, tolerance_mva=TOL, max_iteration=30)
    p0, q0 = net.load.p_mw.at[zl], net.load.q_mvar.at[zl]
    return np.array(
        [
            net.res_bus.vm_pu.at[ZIP_BUS],
            net.res_load.p_mw.at[zl] / p0,
            net.res_load.q_mvar.at[zl] / q0,
        ]
    )


def test_import_does_not_load_pandapower():
    code = "import sys, loadbayes.cases.ieee33; print('pandapower' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_missing_pandapower_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pandapower", None)
    with pytest.raises(ImportError, match=r"pip install loadbayes\[grid\]"):
        ieee33.base_case()


def test_base_case_matches_baran_wu():
    res = ieee33.base_case()
    assert res["min_bus"] == 18
    assert res["min_vm_pu"] == pytest.approx(0.9131, abs=1e-4)
    assert res["losses_kw"] == pytest.approx(202.7, abs=0.1)


def test_exactly_one_load_at_zip_bus(feeder):
    load = feeder.net.load
    assert (load.bus == ZIP_BUS).sum() == 1
    assert load.bus.at[feeder.zip_load] == ZIP_BUS
    assert (feeder.p0_mw, feeder.q0_mvar) == (0.09, 0.04)
    assert len(feeder.factor_loads) == N_FACTORS
    assert ZIP_BUS not in set(load.bus.loc[feeder.factor_loads])
    assert feeder.net.sgen.empty and feeder.net.gen.empty and feeder.net.shunt.empty


@pytest.mark.parametrize(
    "zip_p", [DEFAULT_ZIP, (1.0, 0.0, 0.0), (-0.5, 1.2, 0.3), (1.5, -1.0, 0.5)]
)
def test_pandapower_zip_follows_the_formula(zip_p):
    f = Feeder33(zip_p=zip_p, zip_q=(0.1, 0.6, 0.3), engine="runpp")
    for factors in ieee33.draw_factors(3, seed=11):
        v, p, q, ok = f.run(factors)
        assert ok
        a1, a2, a3 = zip_p
        assert p == pytest.approx(a1 * v**2 + a2 * v + a3, abs=1e-9)
        assert q == pytest.approx(0.1 * v**2 + 0.6 * v + 0.3, abs=1e-9)
        net = f.net
        assert net.res_bus.p_mw.at[ZIP_BUS] == pytest.approx(p * f.p0_mw, abs=1e-12)
        # The network itself: injection V conj(Ybus V) at the bus, to the solver tolerance.
        internal = net._ppc["internal"]
        k = net._pd2ppc_lookups["bus"][ZIP_BUS]
        s_inj = internal["V"][k] * np.conj(internal["Ybus"] @ internal["V"])[k] * net.sn_mva
        assert -s_inj.real == pytest.approx(p * f.p0_mw, abs=TOL * net.sn_mva)
        assert -s_inj.imag == pytest.approx(q * f.q0_mvar, abs=TOL * net.sn_mva)


@pytest.mark.parametrize("engine", ["newton", "recycle"])
@pytest.mark.parametrize("zip_p", [DEFAULT_ZIP, (-0.5, 1.2, 0.3)])
def test_fast_paths_match_plain_runpp(engine, zip_p):
    f = Feeder33(engine=engine, zip_p=zip_p)
    factors = ieee33.draw_factors(5, seed=2)
    got = f.run_many(factors)
    for i, row in enumerate(factors):
        ref = plain_runpp(row, f.zip_p, f.zip_q)
        np.testing.assert_allclose(
            [got["v_pu"][i], got["p_pu"][i], got["q_pu"][i]], ref, rtol=0, atol=1e-8
        )
    np.testing.assert_allclose(got["p_mw"], got["p_pu"] * 0.09, rtol=1e-15)


def test_recycle_recovers_after_a_failed_run():
    f = Feeder33(engine="recycle")
    ones = np.ones(N_FACTORS)
    first = f.run(ones)
    assert not f.run(8 * ones).converged
    assert f.run(ones) == pytest.approx(first, abs=1e-8)


def test_negative_constant_power_share_needs_newton():
    zip_p = (0.8, 0.4, -0.2)
    v, p, _, ok = Feeder33(zip_p=zip_p).run(np.ones(N_FACTORS))
    assert ok and p == pytest.approx(0.8 * v**2 + 0.4 * v - 0.2, abs=1e-12)
    with pytest.raises(ValueError, match="engine='newton'"):
        Feeder33(zip_p=zip_p, engine="runpp")


def test_zip_shares_are_checked():
    with pytest.raises(ValueError, match="must be 1"):
        Feeder33(zip_p=(0.3, 0.3, 0.3))
    with pytest.raises(ValueError, match="engine must be"):
        Feeder33(engine="lightsim")


def test_generate_experiments_is_reproducible_and_documented(feeder):
    df = ieee33.generate_experiments(30, seed=4)
    assert list(df.columns) == COLUMNS
    assert df.experiment.dtype == np.int64 and df.converged.dtype == bool
    pd.testing.assert_frame_equal(df, ieee33.generate_experiments(30, seed=4))
    assert not df.equals(ieee33.generate_experiments(30, seed=5))
    # The factors are draw_factors(n, seed): rebuild the true values from them.
    res = feeder.run_many(ieee33.draw_factors(30, seed=4))
    np.testing.assert_array_equal(df.v_pu, res["v_pu"])
    np.testing.assert_array_equal(df.p_true_pu, res["p_pu"])
    # Noise settings do not move the factors; noise_on_v=0 leaves V untouched.
    quiet = ieee33.generate_experiments(30, seed=4, noise_sd=0.0)
    np.testing.assert_array_equal(quiet.v_pu, df.v_pu)
    np.testing.assert_array_equal(quiet.p_meas_pu, quiet.p_true_pu)
    np.testing.assert_array_equal(df.v_meas_pu, df.v_pu)
    assert df.attrs["n_failed"] == 0 and df.attrs["p0_mw"] == 0.09


def test_failed_power_flows_are_kept_and_counted():
    df = ieee33.generate_experiments(20, seed=3, factor_range=(0.1, 8.0))
    failed = ~df.converged
    assert len(df) == 20 and list(df.experiment) == list(range(20))
    assert 0 < failed.sum() < 20
    assert df.attrs["n_failed"] == failed.sum()
    assert df.loc[failed, COLUMNS[1:-1]].isna().all().all()
    assert df.loc[~failed, COLUMNS[1:-1]].notna().all().all()


def test_validate_is_zero_when_the_estimate_is_the_truth():
    point = validate(DEFAULT_ZIP, DEFAULT_ZIP[:2], n=10, seed=9)
    assert (point[["dv_pu", "dp_pu", "dq_pu"]] == 0).all().all()
    assert point.converged.all() and len(point) == 10
    draws = validate(DEFAULT_ZIP, np.tile(DEFAULT_ZIP, (3, 1)), n=10, seed=9)
    for x in ("v", "p"):
        for col in (f"{x}_est_q2.5_pu", f"{x}_est_q50_pu", f"{x}_est_q97.5_pu"):
            np.testing.assert_array_equal(draws[col], draws[f"{x}_true_pu"])
        assert (draws[f"d{x}_pu"] == 0).all()
    assert (draws.n_draws_ok == 3).all()


def test_validate_sees_a_wrong_estimate():
    out = validate(DEFAULT_ZIP, (0.5, 0.0, 0.5), n=5, seed=9)
    assert (out.dp_pu.abs() > 1e-3).all()
    # A heavier Z share draws less power at V < 1, so V rises.
    assert (out.dv_pu > 0).all() and (out.dp_pu < 0).all()


def test_run_draws_shapes(feeder):
    factors = ieee33.draw_factors(4, seed=1)
    draws = np.array([[0.25, 0.25], [0.3, 0.2], [0.2, 0.3]])
    res = feeder.run_draws(factors, draws)
    assert res["v_pu"].shape == (3, 4)
    np.testing.assert_array_equal(res["v_pu"][0], feeder.run_many(factors)["v_pu"])
