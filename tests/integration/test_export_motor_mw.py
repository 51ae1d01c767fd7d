"""One conversion: every export's motor draws f_m x P0 (x s_base) of the same draw.

Issue 23: PSS/E and ANDES disagreed by 9 % on the motor (38.1 against 34.9 MW) because one
route took the posterior's ``mva_m`` times the own-base P of the mean motor. The draw
below carries an ``mva_m`` that is deliberately inconsistent (twice the right rating):
a writer that used it would write twice the MW.
"""

import math

import pytest

from loadbayes.export import get
from loadbayes.export.loadparts import load_parts
from loadbayes.export.psse import read_loads
from loadbayes.models.motor import MotorParams, steady_state

pytestmark = pytest.mark.integration

DRAW = {
    "p0": 0.52, "q0": 0.21, "v0": 0.98, "a1": 0.3, "a2": 0.2, "a3": 0.5, "a4": 0.6,
    "a5": 0.3, "a6": 0.1, "f_m": 0.436, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018,
    "xr": 0.10, "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6, "mva_m": 9.9,
}  # fmt: skip
S_BASE = 80.0
HEADER = ["loadbayes composite posterior from c.json; exported: mean"]


def _expected():
    # Written here from the motor's physics, not through the export's code.
    params = MotorParams(rs=0.031, xs=0.10, xm=3.2, rr=0.018, xr=0.10, h_s=0.7)
    op = steady_state(params, v_pu=0.98, t0=0.6)
    p_m = 0.436 * 0.52 * S_BASE
    return p_m, p_m / op.p, op.q * p_m / op.p


def test_load_parts_motor_is_f_m_p0_whatever_mva_m_says():
    parts = load_parts(DRAW, model="composite", options={"s_base_mva": S_BASE})
    p_m, mva, q_m = _expected()
    assert parts.motor.p_mw == pytest.approx(p_m, rel=1e-12)
    assert parts.motor.mva == pytest.approx(mva, rel=1e-9)
    assert parts.motor.q_mvar == pytest.approx(q_m, rel=1e-9)
    assert parts.p_total == pytest.approx(0.52 * S_BASE, rel=1e-12)
    assert not math.isclose(mva, 9.9 * S_BASE, rel_tol=0.05)  # the trap is a real one


def test_psse_and_pandapower_write_the_same_motor_mw(tmp_path):
    import pandapower as pp

    p_m, mva, q_m = _expected()
    opts = {"s_base_mva": S_BASE, "bus": 3, "motor_record": "cim5bl"}
    get("psse").write(DRAW, tmp_path / "c.raw", model="composite", header=HEADER, options=opts)
    assert read_loads(tmp_path / "c.raw")["M"]["pl"] == pytest.approx(p_m, rel=1e-9)
    get("pandapower").write(DRAW, tmp_path / "n.json", model="composite", header=HEADER,
                            options={"s_base_mva": S_BASE})  # fmt: skip
    net = pp.from_json(str(tmp_path / "n.json"))
    assert net.motor.pn_mech_mw.iloc[0] == pytest.approx(p_m, rel=1e-9)
    assert net.motor.sn_mva.iloc[0] == pytest.approx(mva, rel=1e-9)
    pp.runpp(net)
    assert net.res_motor.p_mw.iloc[0] == pytest.approx(p_m, rel=1e-9)


def test_a_fitted_composite_gives_one_motor_mw_in_pandapower_and_psse(tmp_path):
    """The CLI on a real fit's JSON (tests/data/README.md: Q shares edited into [0, 1])."""
    import json
    from pathlib import Path

    import pandapower as pp
    from click.testing import CliRunner

    from loadbayes.cli import main
    from loadbayes.export.cmld import read_cmldblu2

    src = Path(__file__).parents[1] / "data" / "composite_example_fit.json"
    par = json.loads(src.read_text())["parameters"]
    expected = par["f_m"]["mean"] * par["p0"]["mean"] * 10.0  # s_base_mva 10 in the fit
    mw = {}
    for fmt, name, extra in (("pandapower", "n.json", []), ("psse", "a.raw", []),
                             ("psse", "b.raw", ["--motor-record", "cim5bl"])):  # fmt: skip
        # The fit's a2 is negative: exported with --force-unphysical (issue 40)
        r = CliRunner().invoke(main, ["export", str(src), "--to", fmt, "--out",
                                      str(tmp_path / name), "--force-unphysical",
                                      *extra])  # fmt: skip
        assert r.exit_code == 0, r.output
        assert "note" not in r.output  # the fit's bases were used, nothing assumed
    mw["pandapower"] = pp.from_json(str(tmp_path / "n.json")).motor.pn_mech_mw.iloc[0]
    mw["cmldblu2"] = read_cmldblu2(tmp_path / "a.dyr")["Fma"] * read_loads(
        tmp_path / "a.raw")["1"]["pl"]  # fmt: skip
    mw["cim5bl"] = read_loads(tmp_path / "b.raw")["M"]["pl"]
    for route, value in mw.items():
        assert value == pytest.approx(expected, rel=1e-9), route


def test_andes_case_motor_draws_the_same_mw(tmp_path):
    # ANDES solves the exported case's power flow on its own; its Motor3 must draw
    # f_m x P0 x s_base at the load bus, as the other two exports write.
    import andes

    p_m, mva, _ = _expected()
    out = tmp_path / "case.json"
    get("andes").write(DRAW, out, model="composite", header=HEADER,
                       options={"s_base_mva": S_BASE})  # fmt: skip
    ss = andes.load(str(out), setup=True, no_output=True, default_config=False)
    assert ss.Motor3.Sn.v[0] == pytest.approx(mva, rel=1e-6)
    ss.PFlow.run()
    assert ss.PFlow.converged
    v = ss.Bus.v.v[ss.Bus.idx2uid(ss.Motor3.bus.v[0])]
    assert v == pytest.approx(0.98, abs=1e-6)
    # Motor3's p is on the system base (ss.config.mva).
    assert ss.Motor3.p.v[0] * ss.config.mva == pytest.approx(p_m, rel=1e-4)
