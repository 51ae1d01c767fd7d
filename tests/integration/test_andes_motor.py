"""The package's motor and ZIP against ANDES 2.0's ``Motor3`` and ``ZIP`` (docs/andes.md).

Each event is simulated once by ANDES (module-scoped fixture, about 3-4 s each) and then
reproduced by the package's own motor simulator, driven by ANDES's terminal voltage
(magnitude and angle). Every convention in docs/andes.md is proved by one assertion here:
a wrong time base, inertia, torque map, base or frame makes one of them fail (the negative
controls show by how much).

Tolerances, and why:
- Motor P, Q: 1e-3 of the motor's rating. ANDES integrates with the implicit trapezoid at
  a fixed 1/600 s step: its local error on the flux oscillation (frequency up to
  wb * slip, about 20-40 rad/s during a sag) is of order (h w)^2 / 12, about 1e-4 of the
  state; the package's DOP853 at rtol 1e-9 adds nothing visible. Seen: 1.5e-5 to 6e-5.
- Static (ZIP) P, Q: 1e-4 system p.u., ANDES's Newton tolerance on the algebraic
  equations (``TDS.config.tol``). Seen: about 3e-6.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")

from loadbayes.cases.andes_sim import simulate  # noqa: E402
from loadbayes.cases.composite_reference import predict  # noqa: E402
from loadbayes.cases.motor_sim import MOTORS  # noqa: E402
from loadbayes.models.motor import steady_state  # noqa: E402

pytestmark = pytest.mark.integration

MOTOR_TOL = 1e-3  # of the motor's rating (module docstring)
STATIC_TOL = 1e-4  # system p.u.

# Two motors, three sag depths, both torque models, a shunt and a negative ZIP share.
EVENTS = {
    "small_15": {"motor": "small_industrial", "sag_depth": 0.15},
    "small_50": {"motor": "small_industrial", "sag_depth": 0.5, "fault_s": 0.15},
    "large_30": {
        "motor": replace(MOTORS["large_industrial"], a=0.5, b=0.2, c=0.3),
        "sag_depth": 0.3,
        "f_m": 0.6,
        "t0": 0.7,
        "q_c": 0.1,
        "zip_p": (0.7, -0.2, 0.5),
        "zip_q": (1.2, -0.4, 0.2),
    },
}


@pytest.fixture(scope="module")
def events():
    return {name: simulate(**kw) for name, kw in EVENTS.items()}


@pytest.fixture(scope="module")
def reproduced(events):
    return {name: _reproduce(ev) for name, ev in events.items()}


def _reproduce(event, **override):
    r = event.record
    angle = None if override.pop("_no_angle", False) else r["angle_rad"]
    values = {**event.truth, **override}
    pred = predict(values, r["t_s"], r["v"], angle, dt_s=event.settings["step_s"])
    t = pred["t_s"].to_numpy()
    andes = {c: np.interp(t, r["t_s"], r[c]) for c in ("p_motor", "q_motor", "p_static")}
    andes["q_static"] = np.interp(t, r["t_s"], r["q_static"])
    return pred, andes


def _motor_error(event, pred, andes):
    mva = event.truth["mva_m"]
    return max(
        np.max(np.abs(pred["p_motor"] - andes["p_motor"])) / mva,
        np.max(np.abs(pred["q_motor"] - andes["q_motor"])) / mva,
    )


@pytest.mark.parametrize("name", list(EVENTS))
def test_sag_depth_and_truth_are_as_asked(events, name):
    ev, kw = events[name], EVENTS[name]
    assert abs(ev.settings["sag_depth"] - kw["sag_depth"]) <= 0.01
    # The power flow put the load bus at v0 and the motor at its share of p0.
    assert ev.truth["v0"] == pytest.approx(1.0, abs=1e-5)
    assert ev.truth["p0"] == pytest.approx(1.0, abs=1e-5)
    assert ev.truth["f_m"] == pytest.approx(kw.get("f_m", 0.4), abs=1e-5)
    # The motor's rating is what ANDES was given (Sn on the system base).
    assert ev.settings["motor3"]["Sn"] == pytest.approx(ev.truth["mva_m"] * 100.0)
    assert ev.record["f"].iloc[0] == pytest.approx(60.0, abs=1e-6)


@pytest.mark.parametrize("name", list(EVENTS))
def test_initial_state_matches_loadbayes_steady_state(events, name):
    # Proves the bases: ANDES's c1..c3 are on the system base, so t0 = (c1 + c2 + c3) /
    # mva_m on the motor's own, and Sn = mva_m * Sb scales P, Q by mva_m.
    ev = events[name]
    op = steady_state(ev.motor, v_pu=ev.truth["v0"], t0=ev.truth["t0"])
    assert ev.record["slip"].iloc[0] == pytest.approx(op.slip, rel=1e-6)
    assert ev.record["p_motor"].iloc[0] == pytest.approx(ev.truth["mva_m"] * op.p, abs=1e-7)
    assert ev.record["q_motor"].iloc[0] == pytest.approx(ev.truth["mva_m"] * op.q, abs=1e-7)


def _torque(ev, a, b, c):
    w = 1.0 - ev.record["slip"].to_numpy()
    return ev.truth["mva_m"] * ev.truth["t0"] * (a * w**2 + b * w + c)


def test_torque_is_the_code_reading_not_milanos(events):
    # ANDES 2.0 evaluates tm = aa + bb s + c2 s^2, i.e. c2 w^2 + (2 c3 - c2) w + (c1 + c2 -
    # c3); Milano's book reads c1 + c2 w + c3 w^2. The two differ by (c2 - c3) s^2, here
    # about 4e-6 (s near 0.007): small, but a thousand times what separates ANDES's tm
    # from the code's reading (2e-9, its Newton accuracy), at every step.
    ev = events["large_30"]
    m = ev.motor
    tm = ev.record["tm"].to_numpy()
    # rtol: tm is an algebraic variable, solved by ANDES's Newton steps (seen: 4e-9).
    np.testing.assert_allclose(tm, _torque(ev, m.a, m.b, m.c), rtol=1e-7, atol=0)
    c1, c2, c3 = (ev.settings["motor3"][k] for k in ("c1", "c2", "c3"))
    aa = c1 + c2 + c3
    assert np.min(np.abs(tm - _torque(ev, c3 / aa, c2 / aa, c1 / aa))) > 1e-6


@pytest.mark.parametrize("name", list(EVENTS))
def test_motor_power_matches_andes(events, reproduced, name):
    assert _motor_error(events[name], *reproduced[name]) <= MOTOR_TOL


@pytest.mark.parametrize("name", list(EVENTS))
def test_static_part_matches_andes_zip(reproduced, name):
    pred, andes = reproduced[name]
    for col in ("p_static", "q_static"):
        assert np.max(np.abs(pred[col] - andes[col])) <= STATIC_TOL, col


@pytest.mark.parametrize(
    ("override", "why"),
    [
        ({"_no_angle": True}, "the bus angle moves in a fault: the motor must see it"),
        ({"h_s": 2 * MOTORS["small_industrial"].h_s}, "ANDES's M is 2H, not H"),
        ({"f_hz": 50.0}, "the time base is wb = 2 pi fn, in seconds"),
    ],
)
def test_negative_controls_fail_by_far(events, override, why):
    # Each convention, broken on purpose, misses ANDES by far more than the tolerance.
    ev = events["small_50"]
    assert _motor_error(ev, *_reproduce(ev, **override)) > 10 * MOTOR_TOL, why
