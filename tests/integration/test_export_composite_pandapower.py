"""A composite load into pandapower: the static part's power flows against the fitted model.

The draw's static shares are in [0, 1] (what ``fit composite --shares bounded`` gives);
the expected P and Q are written here from the composite model's equations
(docs/composite.md), not through the export's code.
"""

import pytest

from loadbayes.export import get
from loadbayes.models.motor import MotorParams, steady_state

pytestmark = pytest.mark.integration

DRAW = {
    "p0": 0.9, "q0": 0.3, "v0": 0.97, "a1": 0.35, "a2": 0.25, "a3": 0.4, "a4": 0.55,
    "a5": 0.3, "a6": 0.15, "f_m": 0.45, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018,
    "xr": 0.10, "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6,
}  # fmt: skip
S = 5.0
HEADER = ["loadbayes composite posterior from c.json; exported: mean"]
VOLTAGES = (0.80, 0.90, 0.97, 1.00, 1.05)


def _motor():
    params = MotorParams(rs=0.031, xs=0.10, xm=3.2, rr=0.018, xr=0.10, h_s=0.7)
    op = steady_state(params, v_pu=0.97, t0=0.6)
    p_m = 0.45 * 0.9 * S
    return p_m, op.q * p_m / op.p


def _static(v):
    # Composite model: P_zip = (1 - f_m) p0 (a1 x^2 + a2 x + a3); Q_zip = q0 (a4 ..), the
    # motor's Q at v0 cancelled by its capacitor q_c = Q_m(v0) (constant impedance).
    x = v / 0.97
    p = (1 - 0.45) * 0.9 * S * (0.35 * x**2 + 0.25 * x + 0.4)
    q = 0.3 * S * (0.55 * x**2 + 0.3 * x + 0.15)
    return p, q


@pytest.mark.parametrize("motor_as", ["power", "impedance"])
def test_power_flows_at_five_voltages_match_the_fitted_static_model(tmp_path, motor_as):
    import pandapower as pp

    out = tmp_path / "net.json"
    opts = {"s_base_mva": S, "vn_kv": 11.0, "motor_as": motor_as}
    get("pandapower").write(DRAW, out, model="composite", header=HEADER, options=opts)
    net = pp.from_json(str(out))
    p_m, q_m = _motor()
    assert len(net.load) == 1
    for vm in VOLTAGES:
        net.ext_grid.vm_pu = vm
        pp.runpp(net)
        p, q = _static(vm)
        assert net.res_load.p_mw.iloc[0] == pytest.approx(p, rel=1e-9), vm
        assert net.res_load.q_mvar.iloc[0] == pytest.approx(q, rel=1e-9), vm
        x2 = (vm / 0.97) ** 2
        shunt_q = net.res_shunt.q_mvar.sum()
        if motor_as == "power":
            assert net.res_motor.p_mw.iloc[0] == pytest.approx(p_m, rel=1e-9)
            assert net.res_motor.q_mvar.iloc[0] == pytest.approx(q_m, rel=1e-9)
            assert shunt_q == pytest.approx(-q_m * x2, rel=1e-9)  # the capacitor alone
        else:
            assert net.res_shunt.p_mw.sum() == pytest.approx(p_m * x2, rel=1e-9)
            assert shunt_q == pytest.approx(q_m * x2 - q_m * x2, abs=1e-9)
        # At v0 the elements draw the whole load: p0 and q0 in MW, Mvar. (pandapower's
        # res_ext_grid is not used: with the load on the slack bus it ignores the ZIP's
        # voltage dependence, seen on pandapower 3.x.)
        if vm == 0.97:
            p_all = net.res_load.p_mw.sum() + net.res_shunt.p_mw.sum()
            q_all = net.res_load.q_mvar.sum() + shunt_q
            if motor_as == "power":
                p_all += net.res_motor.p_mw.sum()
                q_all += net.res_motor.q_mvar.sum()
            assert p_all == pytest.approx(0.9 * S, rel=1e-9)
            assert q_all == pytest.approx(0.3 * S, rel=1e-9)
    assert net.load.const_z_p_percent.iloc[0] + net.load.const_i_p_percent.iloc[0] <= 100


def test_shares_outside_zero_one_are_refused_naming_options(tmp_path):
    bad = dict(DRAW, a4=1.9, a5=-0.2, a6=-0.7)
    with pytest.raises(ValueError, match=r"Q: .* exceed 100 %.*--stat median.*--shares bounded"):
        get("pandapower").write(bad, tmp_path / "n.json", model="composite", header=HEADER,
                                options={"s_base_mva": S})  # fmt: skip
    assert not (tmp_path / "n.json").exists()
