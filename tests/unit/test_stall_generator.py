"""The tests' own stalling-load generator (``tests/stall_generator.py``) checked by itself.

It is the truth the threshold's statistical test (``tests/statistical/
test_parts_stall_threshold.py``) fits against, so its physics is checked here, on its
own outputs: motor D stalls when the load bus stays below Vstall for Tstall and not
otherwise, the stalled units draw their impedance and a fraction restarts, and the
feeder's power balances at every sample.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import numpy as np
import pytest

from stall_generator import MOTOR_D, run_curve, simulate, stall_depth, stalled_power

T_ON = 0.1


def _sim(**kw):
    kw = {"dur": 0.15, "t_end": 0.4, "t_on": T_ON, **kw}
    return simulate(**kw)


def test_it_shares_no_code_with_the_package():
    tree = ast.parse(Path(__file__).parents[1].joinpath("stall_generator.py").read_text())
    roots = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import)
             for a in n.names}  # fmt: skip
    roots |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    # The standard library, NumPy and SciPy only: nothing of loadbayes, nor anything else.
    assert roots - set(sys.stdlib_module_names) <= {"numpy", "scipy"}, roots


def test_the_run_curves_meet_at_vbrk_and_give_the_rated_point_at_one():
    p, q = run_curve(np.array([1.0, MOTOR_D["vbrk"] - 1e-9, MOTOR_D["vbrk"]]), MOTOR_D)
    assert p[0] == pytest.approx(1.0)
    assert q[0] == pytest.approx(np.tan(np.arccos(MOTOR_D["comp_pf"])))
    assert p[1] == pytest.approx(p[2]) and q[1] == pytest.approx(q[2])
    # Below Vbrk the compressor draws more P and Q (kp2, kq2 > 0), as PNNL-17796 measured.
    p7, q7 = run_curve(np.array([0.7]), MOTOR_D)
    assert p7[0] == pytest.approx(1 + 12 * 0.16**3.2)
    assert q7[0] == pytest.approx(q[2] + 11 * 0.16**2.5) and q7[0] > q[2]
    ps, qs = stalled_power(np.array([1.0]), MOTOR_D)
    assert ps[0] == pytest.approx(0.1 / 0.02 / 0.98) and qs[0] == pytest.approx(ps[0])


def test_it_stalls_below_vstall_after_tstall_and_not_above():
    # The load bus sits at about 0.663 in a 30 % sag: a Vstall just above it stalls...
    t, v, _, p, q, tr = _sim(depth=0.30, motor_d={"vstall": 0.68, "tstall": 0.025})
    v_fault = tr["v_load"][(t >= T_ON) & (t < T_ON + 0.025)]
    assert v_fault.size and (v_fault < 0.68).all()
    assert tr["stalled"]
    # ... Tstall after the fault began, decided on the internal step: 0.125 s lies
    # between two 60/s samples (0.1167, 0.1333), and the stall is found there.
    assert tr["t_stall"] == pytest.approx(T_ON + 0.025, abs=2 * tr["dt"])
    after = t >= tr["t_stall"]
    assert (tr["running"][after] == 0).all() and (tr["running"][~after] == 1).all()
    # The stalled impedance draws more: P at the recorded bus jumps at the stall.
    assert p[after & (t < T_ON + 0.15)].min() > 1.1 * p[(t > T_ON) & ~after].max()
    # ... and one just below the load bus's voltage does not.
    _, _, _, _, _, tr2 = _sim(depth=0.30, motor_d={"vstall": 0.64})
    assert not tr2["stalled"] and (tr2["running"] == 1).all()
    assert tr2["v_load"].min() == pytest.approx(v_fault[0], abs=1e-9)
    # Below Vstall for less than Tstall: no stall.
    _, _, _, _, _, tr3 = _sim(depth=0.30, dur=0.02, motor_d={"vstall": 0.68, "tstall": 0.05})
    assert not tr3["stalled"]


def test_a_fraction_restarts_after_the_voltage_holds_above_vrst():
    # A stiff feeder: the load bus recovers above Vrst and frst of the units run again.
    t, _, _, _, _, tr = simulate(depth=0.45, dur=0.1, t_on=T_ON, t_end=0.8,
                                 z_fd=complex(0.002, 0.006))  # fmt: skip
    assert tr["stalled"] and tr["restarted"]
    assert tr["running"][-1] == pytest.approx(MOTOR_D["frst"])
    back = t[np.flatnonzero(tr["running"] == MOTOR_D["frst"])[0]]
    assert back == pytest.approx(T_ON + 0.1 + MOTOR_D["trst"], abs=1.5 / 60)


@pytest.mark.parametrize("with_motor", [False, True])
def test_the_feeder_balances_power_at_every_sample(with_motor):
    im = {"mva": 0.3, "rs": 0.04, "xs": 0.1, "xm": 3.0, "rr": 0.03, "h": 0.3, "t0": 0.7,
          "torque": (0, 0, 1)} if with_motor else None  # fmt: skip
    z = complex(0.021, 0.06)
    t, v, _, p, q, tr = simulate(depth=0.36, dur=0.1, t_on=T_ON, t_end=0.3, im=im, z_fd=z)
    i2 = tr["i"] ** 2
    assert np.allclose(p, tr["p_load"] + z.real * i2, atol=1e-9)
    assert np.allclose(q, tr["q_load"] + z.imag * i2, atol=1e-9)
    # |V| = |V_L + Z I| with I = conj(S_L / V_L): the magnitudes agree to the solve's
    # tolerance (|V|^2 = |V_L|^2 + 2 Re(Z S_L*) + |Z|^2 |I|^2).
    s = tr["p_load"] - 1j * tr["q_load"]
    v2 = tr["v_load"] ** 2 + 2 * (z * s).real + abs(z) ** 2 * i2
    assert np.allclose(v, np.sqrt(v2), atol=1e-8)
    if not with_motor:
        assert p[0] == pytest.approx(0.8 + z.real * i2[0]) and tr["p_load"][0] == pytest.approx(0.8)
    assert tr["stalled"]


def test_the_stall_depth_is_where_a_sag_starts_to_stall():
    kw = {"motor_d": {"vstall": 0.66}, "t_on": T_ON}
    d = stall_depth(dur=0.15, tol=1e-3, **kw)
    assert 0.28 < d < 0.33
    assert simulate(depth=d + 2e-3, dur=0.15, t_end=0.3, **kw)[5]["stalled"]
    assert not simulate(depth=d - 2e-3, dur=0.15, t_end=0.3, **kw)[5]["stalled"]
