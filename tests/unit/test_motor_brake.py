"""The negative sequence's braking torque, against computations written here.

``motor_kernel.brake_torque`` gives ``|I_r2|^2 Rr / (2 - s)`` from the motor's T-circuit
at slip ``2 - s``. Here the same circuit is solved by its two mesh equations with
``numpy.linalg.solve`` (the stator loop and the rotor loop, coupled through ``jXm``),
and the motor's swing equation with the term is integrated by SciPy (``solve_ivp``,
DOP853) from a steady state found by ``brentq``, both written without the package's
integrator. Deterministic; the tolerances are the integrator's own (module docstring of
``motor_kernel``: 1e-4 p.u. on the library motors).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from loadbayes.models.motor_kernel import brake_circuit, brake_torque, integrate

WB = 2 * math.pi * 50.0


def _mesh_torque(v2, s, rs, xs, xm, xr, rr):
    # Mesh currents [I2, I_r2] of the T-circuit at slip 2 - s, driven by V2 (stator side).
    r2 = rr / (2.0 - s)
    a = np.array([[rs + 1j * (xs + xm), -1j * xm], [-1j * xm, r2 + 1j * (xr + xm)]])
    i2, ir2 = np.linalg.solve(a, np.array([v2, 0.0]))
    return abs(ir2) ** 2 * r2, i2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_braking_torque_is_the_t_circuits(seed):
    rng = np.random.default_rng(seed)
    for _ in range(50):
        rs, xp, dx = rng.uniform(0.005, 0.1), rng.uniform(0.08, 0.3), rng.uniform(1.0, 3.5)
        tp, s = rng.uniform(0.05, 1.0), rng.uniform(0.0, 1.0)
        xs, xm, rr = brake_circuit(xp, dx, tp, WB)
        # The closure's circuit is the motor's: X' and X, and T' = (Xr + Xm) / (wb Rr).
        assert xs + xm * xs / (xm + xs) == pytest.approx(xp, rel=1e-12)
        assert xs + xm == pytest.approx(xp + dx, rel=1e-12)
        assert (xs + xm) / (WB * rr) == pytest.approx(tp, rel=1e-12)
        v2 = complex(*rng.normal(0, 0.1, 2))
        want, i2 = _mesh_torque(v2, s, rs, xs, xm, xs, rr)
        assert brake_torque(abs(v2), 1.0 - s, rs, xs, xm, rr) == pytest.approx(want, rel=1e-12)
        # Near the locked-rotor impedance, as parts.motor_y2 says: |I2| ~ |V2| / |Rs + jX'|.
        assert abs(i2) == pytest.approx(abs(v2) / abs(complex(rs, xp)), rel=0.3)


def _scipy_motor(t, v, v2, rs, xp, dx, tp, h, t0):
    # Third-order motor (E' in the synchronous frame, load convention), constant load
    # torque t0, the braking torque from the mesh solve; the voltage and |V2| linear
    # between samples, as the package reads samples.
    # The circuit behind X', X - X', T' (Xr = Xs, as parts.motor_y2 closes it).
    xm = math.sqrt((xp + dx) * dx)
    xs, rr = xp + dx - xm, (xp + dx) / (WB * tp)

    def e_steady(s):
        zp = complex(rs, xp)
        k = 1j * dx / zp
        return k * v[0] / (1.0 + 1j * WB * s * tp + k)

    def te(e, u):
        i = (u - e) / complex(rs, xp)
        return (e * np.conj(i)).real, i

    s0 = brentq(lambda s: te(e_steady(s), v[0])[0] - t0, 1e-9, 0.05, xtol=1e-15)
    e0 = e_steady(s0)

    def rhs(tt, y):
        e, w = complex(y[0], y[1]), y[2]
        u = np.interp(tt, t, v)
        b = np.interp(tt, t, v2)
        tq, i = te(e, u)
        de = -1j * WB * (1.0 - w) * e - (e - 1j * dx * i) / tp
        brake = _mesh_torque(b, 1.0 - w, rs, xs, xm, xs, rr)[0] if b else 0.0
        return [de.real, de.imag, (tq - brake - t0) / (2.0 * h)]

    sol = solve_ivp(rhs, (t[0], t[-1]), [e0.real, e0.imag, 1.0 - s0], t_eval=t,
                    method="DOP853", rtol=1e-10, atol=1e-12, max_step=1e-3)  # fmt: skip
    e = sol.y[0] + 1j * sol.y[1]
    s = v * np.conj((v - e) / complex(rs, xp))
    return s.real, sol.y[2]


def test_the_integrated_motor_brakes_as_scipys():
    # A 20 % sag of 0.12 s with |V2| 0.15 (a phase-to-ground fault) on a small fast motor.
    t = np.arange(0.0, 0.5, 1 / 400)
    on = (t >= 0.1) & (t < 0.22)
    v = np.where(on, 0.8, 1.0)
    v2 = np.where(on, 0.15, 0.0)
    motor = dict(rs=0.04, xp=0.12, dx=1.7, tp_s=0.1, h_s=0.15, t0=0.5)
    p_ref, w_ref = _scipy_motor(t, v, v2, 0.04, 0.12, 1.7, 0.1, 0.15, 0.5)
    got = integrate(t, v, None, f_hz=50.0, torque=(0.0, 0.0, 1.0), v2=v2, **motor)
    bal = integrate(t, v, None, f_hz=50.0, torque=(0.0, 0.0, 1.0), **motor)
    assert got is not None and bal is not None
    p, _, states = got
    # Measured: 9.1e-6 p.u. (P) and 1.8e-7 (speed); the braking itself moves P by 0.043.
    assert np.max(np.abs(p - p_ref)) < 1e-4
    assert np.max(np.abs(states[2] - w_ref)) < 1e-5
    assert np.max(np.abs(bal[0] - p)) > 100 * np.max(np.abs(p - p_ref))
    # Balanced: v2 of zeros is the integrator without the term, to the bit.
    zero = integrate(t, v, None, f_hz=50.0, torque=(0.0, 0.0, 1.0), v2=np.zeros(t.size),
                     **motor)  # fmt: skip
    for a, b in zip(zero, bal, strict=True):
        np.testing.assert_array_equal(a, b)
