"""A ZIP part and a third-order induction motor under one sag: SciPy only, for the validate tests.

Written from the equations of docs/composite.md and nothing of the package's motor code:
the motor is integrated by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-9) from its own
steady state (the first root of electrical minus load torque, ``T0 w^2``, by ``brentq``),
driven by a sag whose 5 ms ramps fall between samples, as a fault recorder's phasors see
a fault. Optionally a slow reactive part the fitted model lacks (a first-order lag of the
voltage's fall) and one-cycle phasor windows (the mean over a window centred on each
stamp, from a fine grid), both for the honest band's tests.

Used by ``tests/integration/test_validate_cli.py`` (a CSV with straddle flags) and
``tests/statistical/test_validate_band.py`` (EventRecords).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

F_HZ = 50.0
WB = 2 * math.pi * F_HZ
#: The motor (per unit on its own base, seconds) and its loading T0 (torque T0 w^2).
MOTOR = {"rs": 0.03, "xp": 0.16, "dx": 2.6, "tp": 0.12, "h": 0.4, "t0": 0.7}
ZIP = (0.5, 0.2, 0.3, 0.6, 0.1, 0.3)  # a1..a6
F_M = 0.45
NOISE = 0.005
#: The ramps into and out of the sag (s).
RAMP = 0.005
#: The slow reactive part a model may lack: gain (per unit of P0 per unit of the voltage's
#: fall) and time constant (s).
SLOW = (0.10, 0.25)


def steady(u0: float) -> tuple[complex, float]:
    """The motor's steady state at the terminal voltage u0 (real): E' and the speed."""
    m = MOTOR
    zs = m["rs"] + 1j * m["xp"]

    def state(s):
        k = 1 / m["tp"] + 1j * WB * s + 1j * m["dx"] / (m["tp"] * zs)
        e = 1j * m["dx"] * u0 / (m["tp"] * zs) / k
        return e, (u0 - e) / zs

    def balance(s):
        e, i = state(s)
        return (e * np.conj(i)).real - m["t0"] * (1 - s) ** 2

    grid = np.geomspace(1e-7, 0.5, 4000)
    vals = np.array([balance(s) for s in grid])
    k = int(np.flatnonzero((vals[:-1] < 0) & (vals[1:] >= 0))[0])
    s = brentq(balance, grid[k], grid[k + 1], xtol=1e-14)
    return state(s)[0], 1 - s


def sag(*, depth, jump, t_fault, hold, p0, q0, v0=1.0, seed=0, span=0.4, rate=200.0,
        slow=False, window=0.0):  # fmt: skip
    """One sag's sampled ``t, v, angle, p, q`` (noise sd NOISE on P and Q) as a dict.

    ``window`` > 0: each value is the mean over ``[t_k - window/2, t_k + window/2]``;
    ``slow``: the reactive part :data:`SLOW` is added to Q.
    """
    kt = [0, t_fault, t_fault + RAMP, t_fault + hold, t_fault + hold + RAMP, 10]
    kv = [v0, v0, v0 * (1 - depth), v0 * (1 - depth), v0, v0]
    ka = [0, 0, -jump, -jump, 0, 0]

    def u(t):
        return np.interp(t, kt, kv) * np.exp(1j * np.interp(t, kt, ka))

    m = MOTOR
    zs = m["rs"] + 1j * m["xp"]
    e0, w0 = steady(v0)
    gain, tau = SLOW if slow else (0.0, 1.0)

    def rhs(t, y):
        e = y[0] + 1j * y[1]
        i = (u(t) - e) / zs
        de = -(e - 1j * m["dx"] * i) / m["tp"] + 1j * WB * (y[2] - 1) * e
        dw = ((e * np.conj(i)).real - m["t0"] * y[2] ** 2) / (2 * m["h"])
        ds = (gain * (1 - abs(u(t)) / v0) - y[3]) / tau
        return [de.real, de.imag, dw, ds]

    t = np.round(np.arange(0, span + 1e-9, 1 / rate), 12)
    t = t[t <= span]
    # A phasor window's mean centred on each stamp (window > 0): the response on a fine grid.
    fine = np.round(np.arange(-window, span + window + 1e-9, 1e-4), 12) if window else t
    sol = solve_ivp(rhs, (fine[0], fine[-1]), [e0.real, e0.imag, w0, 0.0], t_eval=fine,
                    method="DOP853", rtol=1e-9, atol=1e-11, max_step=5e-4)  # fmt: skip
    assert sol.success
    e = sol.y[0] + 1j * sol.y[1]
    uf = u(fine)
    s_m = uf * np.conj((uf - e) / zs)
    x = np.abs(uf) / v0
    size = F_M * p0 / s_m.real[0]
    a1, a2, a3, a4, a5, a6 = ZIP
    p = p0 * (1 - F_M) * (a1 * x**2 + a2 * x + a3) + size * s_m.real
    q = q0 * (a4 * x**2 + a5 * x + a6) + size * (s_m.imag - s_m.imag[0] * x**2)
    q = q + p0 * sol.y[3]
    series = {"v": np.abs(uf), "angle": np.unwrap(np.angle(uf)), "p": p, "q": q}
    if window:
        mean = [np.abs(fine - tk) <= window / 2 for tk in t]
        series = {k: np.array([a[w].mean() for w in mean]) for k, a in series.items()}
    rng = np.random.default_rng(seed)
    return {"t": t, "v": series["v"], "angle": series["angle"],
            "p": series["p"] + NOISE * rng.standard_normal(t.size),
            "q": series["q"] + NOISE * rng.standard_normal(t.size)}  # fmt: skip


def straddles(t, t_fault, hold, cycle=1 / F_HZ):
    """Whether a one-cycle phasor window ending at each stamp straddles a ramp."""
    edges = np.array([t_fault, t_fault + hold])
    return np.array([np.any((edges > tk - cycle) & (edges < tk + RAMP)) for tk in t])
