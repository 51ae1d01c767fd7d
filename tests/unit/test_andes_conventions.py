"""The ANDES convention maps and the motor simulator's angle input (no ANDES needed)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from loadbayes.cases import motor_sim
from loadbayes.cases.composite_reference import predict
from loadbayes.export.andes.case import CompositeCase
from loadbayes.export.andes.conventions import (
    motor3_fields,
    motor_from_motor3,
    torque_from_andes,
    torque_to_andes,
    zip_fields,
)
from loadbayes.models.motor_library import MOTORS

SMALL = MOTORS["small_industrial"]


@pytest.mark.parametrize(("a", "b", "c"), [(1, 0, 0), (0.5, 0.2, 0.3), (0, 0, 1), (0.2, 0.9, -0.1)])
def test_torque_map_round_trips_and_matches_andes_formula(a, b, c):
    c1, c2, c3 = torque_to_andes(0.7, a, b, c)
    assert torque_from_andes(c1, c2, c3) == pytest.approx((0.7, a, b, c))
    # ANDES 2.0: tm = aa + bb s + c2 s^2, aa = c1 + c2 + c3, bb = -c2 - 2 c3.
    for s in (0.0, 0.02, 0.3, 1.0):
        andes_tm = (c1 + c2 + c3) + (-c2 - 2 * c3) * s + c2 * s**2
        w = 1 - s
        assert andes_tm == pytest.approx(0.7 * (a * w**2 + b * w + c), abs=1e-12)


def test_motor3_fields_round_trip_with_bases():
    motor = replace(SMALL, a=0.5, b=0.2, c=0.3)
    fields = motor3_fields(motor, t0=0.6, mva_m=0.4, base_mva=100.0, vn_kv=110.0)
    assert fields["Sn"] == pytest.approx(40.0)
    # The torque is on the system base: c1 + c2 + c3 = t0 * mva_m.
    assert fields["c1"] + fields["c2"] + fields["c3"] == pytest.approx(0.24)
    back, t0, mva_m = motor_from_motor3(fields, 100.0)
    assert (t0, mva_m) == pytest.approx((0.6, 0.4))
    for name in ("rs", "xs", "xm", "rr", "xr", "h_s", "a", "b", "c", "f_hz"):
        assert getattr(back, name) == pytest.approx(getattr(motor, name)), name


def test_zip_fields_are_percent_and_refuse_bad_shares():
    assert zip_fields((0.5, -0.1, 0.6), (1, 0, 0)) == pytest.approx(
        {"kpz": 50, "kpi": -10, "kpp": 60, "kqz": 100, "kqi": 0, "kqp": 0}
    )
    with pytest.raises(ValueError, match="sum to 1"):
        zip_fields((0.5, 0.5, 0.5), (1, 0, 0))


def test_case_splits_p0_q0_between_motor_zip_and_shunt():
    values = {"p0": 0.9, "q0": 0.2, "v0": 1.03, "a1": 0.2, "a2": 0.3, "a4": 0.1, "a5": 0.1}
    values |= {"f_m": 0.5, "t0": 0.6, "q_c": 0.05}
    values |= {k: getattr(SMALL, k) for k in ("rs", "xs", "xm", "rr", "xr", "h_s")}
    case = CompositeCase.from_values(values, with_motor=True)
    assert case.motor_pq.real == pytest.approx(0.45)
    assert case.static_pq + case.motor_pq - 1j * case.q_c == pytest.approx(0.9 + 0.2j)
    # Ohm's law: the source voltage drives exactly p0 + j q0 into a bus at v0.
    i = (case.v_src - case.v0) / (case.z_src + complex(0.002, 0.02))
    assert case.v0 * i.conjugate() == pytest.approx(0.9 + 0.2j)


def test_constant_angle_changes_nothing_and_a_moving_one_is_a_frequency_change():
    sag = motor_sim.sag(0.3, 0.2, 0.1)
    kw = {"disturbance": sag, "t_end_s": 0.6, "dt_s": 0.005, "noise": 0.0}
    plain = motor_sim.simulate(SMALL, **kw)
    fixed = motor_sim.simulate(SMALL, angle=motor_sim.constant(0.7), **kw)
    for col in ("p", "q", "w"):
        np.testing.assert_allclose(fixed[col], plain[col], atol=1e-9)
    np.testing.assert_allclose(np.hypot(fixed["ud"], fixed["uq"]), plain["ud"], atol=1e-12)
    # A bus angle rising at 2 pi * 0.5 rad/s is a 0.5 Hz rise in frequency: the rotor
    # follows it, so its speed ends about 0.5/60 p.u. above the fixed-phase case.
    drift = motor_sim.ramp(2 * math.pi * 0.5 * 3.0, 0.0, 3.0, v0_pu=0.0)
    moved = motor_sim.simulate(SMALL, angle=drift, **{**kw, "t_end_s": 3.0})
    ref = motor_sim.simulate(SMALL, **{**kw, "t_end_s": 3.0})
    assert moved["w"].iloc[-1] - ref["w"].iloc[-1] == pytest.approx(0.5 / 60, rel=0.05)


def test_reference_prediction_is_steady_at_constant_voltage():
    values = {"p0": 0.9, "q0": 0.2, "a1": 0.2, "a2": 0.3, "a3": 0.5, "a4": 0.1, "a5": 0.1}
    values |= {"a6": 0.8, "f_m": 0.5, "t0": 0.6, "q_c": 0.05}
    values |= {k: getattr(SMALL, k) for k in ("rs", "xs", "xm", "rr", "xr", "h_s")}
    t = np.linspace(0, 0.5, 51)
    pred = predict(values, t, np.full(t.size, 1.02), dt_s=0.01)
    np.testing.assert_allclose(pred["p"], 0.9, atol=1e-9)
    np.testing.assert_allclose(pred["q"], 0.2, atol=1e-9)
    np.testing.assert_allclose(pred["p_motor"], 0.45, atol=1e-9)
