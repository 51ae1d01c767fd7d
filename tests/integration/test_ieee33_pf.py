"""End-to-end checks of the 33-bus generator through pandapower (slower than the unit tier)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from loadbayes.cases import ieee33
from loadbayes.cases.ieee33 import DEFAULT_ZIP, Feeder33
from loadbayes.cases.ieee33 import parallel as ieee33_parallel
from loadbayes.studies.ieee33_validation import validate

pytest.importorskip("pandapower")

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def many_shares():
    """60 factor rows and posterior-like shares, and pandapower's own runpp on them.

    The reference runs once for both engines compared with it (it is the slow one).
    """
    rng = np.random.default_rng(20)
    n = 60
    factors = ieee33.draw_factors(n, seed=21)
    # Posterior-like scatter around the truth, including negative Z or I shares.
    zip_p = np.column_stack([0.25 + rng.normal(0, 0.4, n), 0.25 + rng.normal(0, 0.4, n)])
    zip_p[:, 1] = np.minimum(zip_p[:, 1], 1.0 - zip_p[:, 0])  # keep a3 >= 0 for runpp
    zip_q = np.column_stack([rng.uniform(-0.5, 1.0, n), np.zeros(n)])
    kw = {"zip_p": zip_p, "zip_q": zip_q}
    ref = Feeder33(engine="runpp").run_many(factors, **kw)
    assert ref["converged"].all()
    return factors, kw, ref


@pytest.mark.parametrize("engine", ["newton", "recycle"])
def test_fast_paths_match_plain_runpp_over_many_shares(engine, many_shares):
    factors, kw, ref = many_shares
    got = Feeder33(engine=engine).run_many(factors, **kw)
    assert got["converged"].all()
    for key in ("v_pu", "p_pu", "q_pu"):
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=1e-8)


@pytest.mark.parametrize(("engine", "n", "chunk"), [("newton", 150, 60), ("recycle", 80, 25)])
def test_output_is_identical_for_one_and_two_workers(engine, n, chunk, monkeypatch):
    # Small chunks make several of them (3 for newton, 4 for recycle: 25, 25, 25, 5), so
    # each worker takes more than one and the last is short; the recycle engine restarts
    # cold at each chunk. Before, newton ran 450 rows in chunks of 200 and recycle 150 in
    # chunks of 40 (the same code paths, twice the power flows).
    monkeypatch.setattr(ieee33_parallel, "_CHUNK", chunk)
    # Some failures too; noise on V as well. (The unit tier's own run of workers=2, the
    # newton engine on 3 chunks with noise on V, was this case's duplicate: it is here.)
    kw = {"seed": 31, "engine": engine, "factor_range": (0.1, 6.5), "noise_on_v": 0.01}
    one = ieee33.generate_experiments(n, **kw)
    two = ieee33.generate_experiments(n, workers=2, **kw)
    pd.testing.assert_frame_equal(one, two, check_exact=True)
    assert one.attrs == two.attrs
    assert 0 < one.attrs["n_failed"] < n


def test_paper_setting_converges_over_the_expected_voltage_band():
    df = ieee33.generate_experiments(500, seed=0, workers=2)
    assert df.attrs["n_failed"] == 0
    assert 0.55 < df.v_pu.min() and df.v_pu.max() < 0.92
    # The noise is N(0, 0.1) in per unit of P0 and Q0.
    resid = df.p_meas_pu - df.p_true_pu
    assert resid.std() == pytest.approx(0.1, rel=0.15)


def test_posterior_predictive_band_covers_the_truth():
    rng = np.random.default_rng(4)
    # Draws along the paper's a1-a2 ridge (correlation near -1), centred on the truth.
    a1 = 0.25 + rng.normal(0, 0.3, 100)
    draws = np.column_stack([a1, 0.5 - a1 + rng.normal(0, 0.01, 100)])
    out = validate(DEFAULT_ZIP, draws, n=20, seed=8, workers=2)
    assert out.converged.all() and (out.n_draws_ok == 100).all()
    for x in ("v", "p"):
        lo, mid, hi = (out[f"{x}_est_q{q}_pu"] for q in ("2.5", "50", "97.5"))
        assert (lo <= mid).all() and (mid <= hi).all()
        assert ((lo <= out[f"{x}_true_pu"]) & (out[f"{x}_true_pu"] <= hi)).all()
    assert out.attrs["n_draws"] == 100


def test_validate_point_estimate_close_to_truth_is_small():
    out = validate(DEFAULT_ZIP, (0.25, 0.249), n=100, seed=1)
    assert out.converged.all()
    assert out.dv_pu.abs().max() < 1e-4
    assert out.dp_pu.abs().max() < 2e-3


def test_numba_and_scipy_paths_give_the_same_bits_and_the_default_switches(monkeypatch):
    """pandapower compiles its numba kernels in every process (about 5 CPU s); the default
    (``numba=None``) runs SciPy's path until the process has solved ``NUMBA_FROM_FLOWS``
    flows, then numba's. The switch must not change a number: both paths, bit for bit."""
    from loadbayes.cases.ieee33 import feeder as feeder_module

    factors = ieee33.draw_factors(40, seed=5, factor_range=(0.1, 6.5))  # some fail
    for engine in ("newton", "recycle"):
        scipy = Feeder33(engine=engine, numba=False).run_many(factors)
        numba = Feeder33(engine=engine, numba=True).run_many(factors)
        assert 0 < scipy["converged"].sum() < len(factors)
        for key, value in scipy.items():
            np.testing.assert_array_equal(numba[key], value, err_msg=f"{engine}: {key}")
    monkeypatch.setattr(feeder_module, "_PROCESS", {"flows": 0, "numba": False})
    monkeypatch.setattr(feeder_module, "NUMBA_FROM_FLOWS", 50)
    auto = Feeder33()
    auto.run_many(factors[:20])
    assert not auto._numba_now and not auto._opts["numba"]
    auto.run_many(factors[20:])  # 20 + 20 < 50: still SciPy
    assert not auto._numba_now
    auto.run_many(factors[:10])  # the 50th flow: numba from here on, for every feeder
    assert auto._numba_now and auto._opts["numba"] and Feeder33()._numba_now
    assert Feeder33(numba=False)._numba_now is False
