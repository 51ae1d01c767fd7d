"""Exports read back: pandapower power flows, PSS/E files parsed (by us and by ANDES)."""

from pathlib import Path

import numpy as np
import pytest

from loadbayes.export import check_model, get
from loadbayes.export.loadparts import load_parts, zip_of_exponent
from loadbayes.export.psse import read_dyr, read_loads

pytestmark = pytest.mark.integration

ZIP = {"a1": 0.45, "a2": -0.15, "a3": 0.70, "a4": 1.6, "a5": -0.9, "a6": 0.3, "p0": 0.8,
       "q0": 0.3}  # fmt: skip
HEADER = ["loadbayes zip posterior from post.json; exported: mean", "a1: 0.45 (0.01) [0.43, 0.47]"]


def zip_model(values, v, v0=1.0, s_base=1.0):
    x = np.asarray(v) / v0
    p = values["p0"] * (values["a1"] * x**2 + values["a2"] * x + values["a3"]) * s_base
    q = values["q0"] * (values["a4"] * x**2 + values["a5"] * x + values["a6"]) * s_base
    return p, q


def test_dispatcher_and_models():
    assert get("psse").SUFFIXES == (".raw", ".dyr")
    with pytest.raises(ValueError, match="unknown export format 'matpower'"):
        get("matpower")
    with pytest.raises(ValueError, match="model 'im' cannot be exported"):
        check_model("im")


@pytest.mark.parametrize("v0", [1.0, 0.97])
def test_pandapower_power_flow_reproduces_the_zip(tmp_path, v0):
    import pandapower as pp

    pp_mod = get("pandapower")
    out = tmp_path / "net.json"
    opts = {"s_base_mva": 100.0, "v0": v0, "vn_kv": 20.0}
    written = pp_mod.write(ZIP, out, model="zip", header=HEADER, options=opts)
    assert written == [out, tmp_path / "net.json.summary.txt"]
    assert "a1: 0.45 (0.01)" in written[1].read_text()
    assert "negative" in written[1].read_text()  # a2, a5 < 0: noted, and exact
    net = pp.from_json(str(out))
    for vm in (0.75, 0.85, 0.95, 1.0, 1.05):
        net.ext_grid.vm_pu = vm
        pp.runpp(net)
        p, q = zip_model(ZIP, vm, v0=v0, s_base=100.0)
        assert net.res_bus.vm_pu.iloc[0] == pytest.approx(vm)
        assert net.res_load.p_mw.iloc[0] == pytest.approx(p, rel=1e-9)
        assert net.res_load.q_mvar.iloc[0] == pytest.approx(q, rel=1e-9)


def test_pandapower_refuses_what_it_cannot_hold(tmp_path):
    import pandapower as pp

    pp_mod = get("pandapower")
    neg_p = dict(ZIP, a1=0.9, a2=0.4, a3=-0.3)
    with pytest.raises(ValueError, match=r"P: constant-impedance 90 % \+ constant-current 40 %"):
        pp_mod.write(neg_p, tmp_path / "a.json", model="zip", header=HEADER, options={})
    assert not (tmp_path / "a.json").exists()
    # pandapower itself refuses it in the power flow: the reason for refusing first.
    net = pp.create_empty_network()
    b = pp.create_bus(net, 20.0)
    pp.create_ext_grid(net, b)
    pp.create_load(net, b, 1.0, const_z_p_percent=90, const_i_p_percent=40)
    with pytest.raises(ValueError, match="less or equal to 100"):
        pp.runpp(net)
    # A net with another load on the bus: shares would be averaged, unweighted.
    pp.create_load(net, b, 1.0)
    net.load = net.load.iloc[1:]
    src = tmp_path / "given.json"
    pp.to_json(net, str(src))
    with pytest.raises(ValueError, match="averages the Z and I shares"):
        pp_mod.write(ZIP, tmp_path / "b.json", model="zip", header=HEADER,
                     options={"net": str(src), "bus": b})  # fmt: skip
    # Overwriting that load instead is fine.
    pp_mod.write(ZIP, tmp_path / "c.json", model="zip", header=HEADER,
                 options={"net": str(src), "load_index": 1, "s_base_mva": 1.0})  # fmt: skip
    net2 = pp.from_json(str(tmp_path / "c.json"))
    assert net2.load.at[1, "const_z_p_percent"] == pytest.approx(45.0)


def test_psse_raw_round_trip_and_andes_reads_it(tmp_path):
    pytest.importorskip("andes")
    import andes

    psse = get("psse")
    out = tmp_path / "case.raw"
    written = psse.write(ZIP, out, model="zip", header=HEADER,
                         options={"bus": 7, "s_base_mva": 100.0, "v0": 0.98})  # fmt: skip
    assert written == [out, tmp_path / "case.raw.summary.txt"]
    rec = read_loads(out)["1"]
    assert rec["bus"] == 7
    for v in (0.7, 0.9, 1.0, 1.1):
        p, q = zip_model(ZIP, v, v0=0.98, s_base=100.0)
        assert rec["pl"] + rec["ip"] * v + rec["yp"] * v**2 == pytest.approx(p, rel=1e-9)
        assert rec["ql"] + rec["iq"] * v - rec["yq"] * v**2 == pytest.approx(q, rel=1e-9)
    # An independent reader of the v33 format: ANDES turns the record into P, Q at the
    # bus's case voltage (v0 here) with the same formula.
    # file=False and a log_path: ANDES makes a new /tmp/andes-* folder whenever it is None
    andes.config_logger(stream_level=50, file=False, log_path=str(tmp_path))
    ss = andes.load(str(out), setup=True, no_output=True, default_config=True)
    p0, q0 = zip_model(ZIP, 0.98, v0=0.98, s_base=1.0)
    assert ss.PQ.p0.v[0] == pytest.approx(p0, rel=1e-9)
    assert ss.PQ.q0.v[0] == pytest.approx(q0, rel=1e-9)
    assert ss.PFlow.run() and ss.PFlow.converged


COMPOSITE = {
    "p0": 1.0, "q0": 0.45, "v0": 1.0, "a1": 0.4, "a2": 0.3, "a3": 0.3, "a4": 0.5, "a5": 0.3,
    "a6": 0.2, "f_m": 0.4, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018, "xr": 0.18,
    "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6, "q_c": 0.05,
}  # fmt: skip


def test_psse_composite_dyr_round_trip(tmp_path):
    from loadbayes.models.motor import MotorParams, steady_state

    psse = get("psse")
    out = tmp_path / "comp.raw"
    opts = {"bus": 3, "s_base_mva": 100.0, "motor_record": "cim5bl"}
    written = psse.write(COMPOSITE, out, model="composite", header=HEADER, options=opts)
    assert [Path(p).suffix for p in written] == [".raw", ".dyr", ".txt"]
    dyr = read_dyr(tmp_path / "comp.dyr")
    params = MotorParams(rs=0.031, xs=0.10, xm=3.2, rr=0.018, xr=0.18, h_s=0.7)
    op = steady_state(params, v_pu=1.0, t0=0.6)
    mva = 0.4 * 100.0 / op.p  # f_m p0 on the system base over P per unit of the motor's
    assert dyr["bus"] == 3 and dyr["id"] == "M" and dyr["IT"] == 1
    for k, val in {"RA": 0.031, "XA": 0.10, "XM": 3.2, "R1": 0.018, "X1": 0.18, "R2": 0.0,
                   "X2": 0.0, "H": 0.7, "D": 2.0, "MBASE": mva}.items():  # fmt: skip
        assert dyr[k] == pytest.approx(val, rel=1e-9), k
    loads = read_loads(out)
    assert loads["M"]["pl"] == pytest.approx(40.0, rel=1e-9)
    assert loads["M"]["ql"] == pytest.approx(op.q * mva, rel=1e-9)
    # The static record plus the motor's record reproduce p0, q0 at v0.
    st = loads["1"]
    assert st["pl"] + st["ip"] + st["yp"] + loads["M"]["pl"] == pytest.approx(100.0)
    assert st["ql"] + st["iq"] - st["yq"] + loads["M"]["ql"] == pytest.approx(45.0)
    # The static shares (of the non-motor part) survive; q_c sits in YQ (capacitive > 0).
    assert st["yp"] / (st["pl"] + st["ip"] + st["yp"]) == pytest.approx(0.4)
    q_static = 45.0 - loads["M"]["ql"] + 5.0
    assert st["yq"] == pytest.approx(-0.5 * q_static + 5.0)


def test_exponential_written_as_its_closest_zip():
    for n, shares in ((0.0, [0, 0, 1]), (1.0, [0, 1, 0]), (2.0, [1, 0, 0])):
        got, err = zip_of_exponent(n)
        np.testing.assert_allclose(got, shares, atol=1e-12)
        assert err < 1e-12
    got, err = zip_of_exponent(1.5)
    assert 1e-4 < err < 0.02 and got.sum() == pytest.approx(1.0)
    parts = load_parts({"np": 1.5, "nq": 2.0, "p0": 1.0, "q0": 0.5}, model="exponential",
                       options={})  # fmt: skip
    assert parts.p(1.0) == pytest.approx(1.0)
    assert parts.q(0.9) == pytest.approx(0.5 * 0.81)
    assert "closest ZIP" in parts.notes[0]
