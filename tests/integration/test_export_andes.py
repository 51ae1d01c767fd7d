"""Round trip of the ANDES export: write a case, load it in ANDES, fault it, compare P, Q.

The case written by ``loadbayes.export.andes.writer.write`` is read back by ANDES's own reader,
a three-phase fault is added at its network bus, and ANDES's load P, Q (from the feeder
current) are compared with the package's prediction for the same parameter values
(:func:`loadbayes.cases.composite_reference.predict`, driven by ANDES's bus voltage).

Tolerance: 1e-3 system p.u. on P and Q, the motor's 1e-3 of its rating (mva_m < 1 here)
plus the ZIP's 1e-4 (tests/integration/test_andes_motor.py explains both).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")

import andes  # noqa: E402

from loadbayes.cases.composite_reference import predict  # noqa: E402
from loadbayes.export.andes import writer as export  # noqa: E402
from loadbayes.export.andes.conventions import andes_quiet  # noqa: E402
from loadbayes.export.andes.run import run_tds  # noqa: E402
from loadbayes.models.motor_library import MOTORS  # noqa: E402

pytestmark = pytest.mark.integration

TOL = 1e-3
STEP = 1.0 / 600.0
_m = MOTORS["large_industrial"]
COMPOSITE = {
    "p0": 0.8,
    "q0": 0.2,
    "v0": 1.02,
    "a1": 0.6,
    "a2": -0.2,
    "a3": 0.6,
    "a4": 1.1,
    "a5": -0.3,
    "a6": 0.2,
    "f_m": 0.55,
    "t0": 0.65,
    "q_c": 0.08,
    **{k: getattr(_m, k) for k in ("rs", "xs", "xm", "rr", "xr", "h_s")},
    "a": 0.6,
    "b": 0.1,
    "c": 0.3,
}
HEADER = ["posterior: comp.json (fit composite)", "statistic: mean", "f_m 0.55 [0.5, 0.6]"]


def _faulted(path, bus, *, xf=0.12, t_end=1.2):
    with andes_quiet():
        ss = andes.load(str(path), setup=False, no_output=True, default_config=True)
        ss.add("Fault", {"idx": 1, "bus": bus + 2, "tf": 0.2, "tc": 0.3, "xf": xf})
        ss.setup()
    return ss, run_tds(ss, load_bus=bus, net_bus=bus + 2, t_end_s=t_end, step_s=STEP)


@pytest.fixture(scope="module")
def composite_case(tmp_path_factory):
    out = tmp_path_factory.mktemp("andes") / "load.xlsx"
    paths = export.write(COMPOSITE, out, model="composite", header=HEADER, options={"bus": 7})
    ss, rec = _faulted(out, 7)
    return paths, ss, rec


def test_writes_the_case_and_a_sidecar_with_the_summary(composite_case):
    (case, sidecar), ss, _ = composite_case
    assert case.suffix == ".xlsx" and case.stat().st_size > 0
    text = sidecar.read_text()
    for line in HEADER:
        assert f"# {line}" in text
    assert "Motor3 1:" in text and "solve_power_flow" in text
    # What ANDES read back is what was meant (ZIP percentages, motor on its own base).
    assert ss.ZIP.kpz.v[0] == pytest.approx(60.0) and ss.ZIP.kqi.v[0] == pytest.approx(-30.0)
    assert ss.Motor3.rr1.vin[0] == pytest.approx(_m.rr) and ss.Shunt.n == 1


def test_round_trip_reproduces_the_composite_prediction(composite_case):
    _, _, rec = composite_case
    assert rec["v"].min() < 0.8 * COMPOSITE["v0"]  # the fault makes a real sag
    # The power flow put the load at v0 and at p0, q0.
    assert rec["v"].iloc[0] == pytest.approx(COMPOSITE["v0"], abs=1e-5)
    assert rec["p"].iloc[0] == pytest.approx(COMPOSITE["p0"], abs=1e-5)
    assert rec["q"].iloc[0] == pytest.approx(COMPOSITE["q0"], abs=1e-5)
    pred = predict(COMPOSITE, rec["t_s"], rec["v"], rec["angle_rad"], dt_s=STEP)
    t = pred["t_s"].to_numpy()
    for col in ("p", "q", "p_motor", "q_motor"):
        got = np.interp(t, rec["t_s"], rec[col])
        assert np.max(np.abs(pred[col] - got)) <= TOL, col


def test_zip_export_from_power_in_mw(tmp_path):
    out = tmp_path / "zip.json"
    values = {"a1": 0.3, "a2": 0.5, "a4": -0.2, "a5": 1.0}  # no p0, q0: from the options
    options = {"p_mw": 45.0, "q_mvar": 12, "bus": 3}  # the three-bus case: a network bus
    export.write(values, out, model="zip", header=HEADER, options=options)
    ss, rec = _faulted(out, 3, xf=0.1, t_end=0.5)
    assert ss.PQ.p0.v[0] == pytest.approx(0.45) and ss.PQ.q0.v[0] == pytest.approx(0.12)
    x = rec["v"].to_numpy() / rec["v"].iloc[0]
    p = 0.45 * (0.3 * x**2 + 0.5 * x + 0.2)
    q = 0.12 * (-0.2 * x**2 + 1.0 * x + 0.2)
    assert np.max(np.abs(rec["p"] - p)) <= 1e-4 and np.max(np.abs(rec["q"] - q)) <= 1e-4
    assert x.min() < 0.8


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"model": "exponential"}, "no exponential static load"),
        ({"model": "composite", "out": "load.raw"}, "writes .xlsx or .json"),
        ({"model": "zip", "values": {"a1": 0.5, "a2": 0.5}}, "option 'p_mw'"),
        ({"model": "zip", "values": {**COMPOSITE, "a3": 0.9}}, "sum to 1"),
        ({"model": "composite", "values": {**COMPOSITE, "f_m": 1.5}}, "0 < f_m <= 1"),
    ],
)
def test_refuses_clearly(tmp_path, kwargs, match):
    values = kwargs.pop("values", COMPOSITE)
    out = tmp_path / kwargs.pop("out", "load.xlsx")
    with pytest.raises(ValueError, match=match):
        export.write(values, out, header=HEADER, options={}, **kwargs)
    assert not out.exists()


def test_bases_reach_the_case_and_the_motor_draws_f_m_p0(tmp_path):
    # A draw in per unit of an 80 MVA base, exported on ANDES's 100 MVA system base at
    # 11 kV. Its mva_m is deliberately inconsistent (9.9, twice and more the right
    # rating): the motor must still draw f_m x P0, the best-determined number of a fit.
    draw = {**COMPOSITE, "p0": 0.52, "q0": 0.21, "v0": 0.98, "f_m": 0.436, "mva_m": 9.9}
    out = tmp_path / "based.json"
    opts = {"s_base_mva": 80.0, "vn_kv": 11.0}
    export.write(draw, out, model="composite", header=HEADER, options=opts)
    with andes_quiet():
        ss = andes.load(str(out), no_output=True, default_config=True)
        assert ss.PFlow.run()  # ANDES's own power flow, the case's _config
    mw = 100.0  # ANDES's system base
    assert set(ss.Bus.Vn.v) == {11.0} and ss.Motor3.Vn.v[0] == 11.0
    assert ss.Bus.v.v[0] == pytest.approx(0.98, abs=1e-6)
    assert ss.Motor3.p.v[0] * mw == pytest.approx(0.436 * 0.52 * 80.0, rel=1e-6)
    assert (ss.PQ.p0.v[0] + ss.Motor3.p.v[0]) * mw == pytest.approx(0.52 * 80.0, rel=1e-6)
    q_load = ss.PQ.q0.v[0] + ss.Motor3.q.v[0] - ss.Shunt.b.v[0] * 0.98**2
    assert q_load * mw == pytest.approx(0.21 * 80.0, rel=1e-6)
    assert ss.Motor3.Sn.v[0] != pytest.approx(9.9 * 80.0, rel=0.05)
