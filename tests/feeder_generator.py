"""An independent generator of fault records: a ZIP load and one motor behind a feeder.

Written with SciPy only, from the textbook equations, sharing no code with the package:
the recorded bus's voltage follows a sag (linear ramps in and out); behind the series
impedance ``z_fd`` the load bus's voltage is solved at every instant from the network
equation ``V = V_L + z_fd I(V_L)`` (``scipy.optimize.fsolve``), where the load draws a
static ZIP part (its shares of its own P and Q at the pre-fault load-bus voltage) and a
third-order induction motor (the paper's equations with the slip terms: ``E'`` behind
``Rs + jX'``, rotor speed with torque ``T0 (A w^2 + B w + C)``), integrated by
``scipy.integrate.solve_ivp`` (Radau). The initial state (load-bus voltage, slip, static
Q) is solved jointly so that the recorded bus sits at ``v_src0`` and the load draws
``q_load`` at the load bus. The record holds, at ``fs`` samples per second, the
recorded bus's V, angle, P and Q, as a recorder sees them.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve


def simulate(*, f_hz=50.0, rs=0.04, xs=0.1, xm=3.0, rr=0.03, h=0.4, t0=0.7, torque=(0, 0, 1),
             mva=0.6, zip_p=(0.4, 0.3, 0.3), zip_q=(0.5, 0.3, 0.2), p_static=0.6, q_load=0.3,
             z_fd=complex(0.01, 0.03), sag=0.15, t_on=0.1, dur=0.12, fs=50, t_end=0.5,
             ramp=0.02, v_src0=1.0):  # fmt: skip
    """``(t, v, angle, p, q, truth)`` of one sag (system p.u.; see the module docstring)."""
    wb = 2 * np.pi * f_hz
    x = xs + xm
    xp = xs + xm * xs / (xm + xs)  # Xr = Xs
    tp = (xs + xm) / (wb * rr)
    a_t, b_t, c_t = torque
    zm = complex(rs, xp)

    def src(t):
        a = np.clip((t - t_on) / ramp, 0, 1) - np.clip((t - t_on - dur) / ramp, 0, 1)
        return v_src0 * (1 - sag * a)

    def e_ss(vl, s):
        return 1j * (x - xp) * vl / (zm * (1 + 1j * wb * tp * s) + 1j * (x - xp))

    def static_s(vl, vl0, qs):
        r = abs(vl) / abs(vl0)
        return p_static * (zip_p[0] * r * r + zip_p[1] * r + zip_p[2]) + 1j * qs * (
            zip_q[0] * r * r + zip_q[1] * r + zip_q[2]
        )

    def init(z):
        vr, vi, s, qs = z
        vl = complex(vr, vi)
        e = e_ss(vl, s)
        i_m = (vl - e) / zm
        te = (e * np.conj(i_m)).real
        ss = static_s(vl, vl, qs) + mva * vl * np.conj(i_m)
        v = vl + z_fd * np.conj(ss / vl)
        w = 1 - s
        return [v.real - v_src0, v.imag, te - t0 * (a_t * w * w + b_t * w + c_t), ss.imag - q_load]

    vr, vi, s0, qs = fsolve(init, [0.97, -0.02, 0.01, 0.0], xtol=1e-13)
    vl0 = complex(vr, vi)
    e0 = e_ss(vl0, s0)
    guess = [vl0]

    def load_bus(t, e):
        v = src(t)

        def f(z):
            vl = complex(*z)
            ss = static_s(vl, vl0, qs) + mva * vl * np.conj((vl - e) / zm)
            r = vl + z_fd * np.conj(ss / vl) - v
            return [r.real, r.imag]

        # full_output: fsolve then warns of nothing, and the residual is checked here.
        # Started at the last instant's solution, it can find no relative progress at
        # xtol 1e-12 and said so as a RuntimeWarning (on an AVX-512 machine, whose NumPy
        # rounds its elementary functions differently), though already at the root.
        z, info, _, _ = fsolve(f, [guess[0].real, guess[0].imag], xtol=1e-12, full_output=True)
        if np.max(np.abs(info["fvec"])) > 1e-10:
            raise RuntimeError(f"the load bus's voltage at t = {t}: no solution")
        vl = complex(*z)
        guess[0] = vl
        return vl

    def rhs(t, y):
        e, w = complex(y[0], y[1]), y[2]
        vl = load_bus(t, e)
        i_m = (vl - e) / zm
        de = -1j * wb * (1 - w) * e - (e - 1j * (x - xp) * i_m) / tp
        te = (e * np.conj(i_m)).real
        return [de.real, de.imag, (te - t0 * (a_t * w * w + b_t * w + c_t)) / (2 * h)]

    ts = np.arange(0, t_end, 1 / fs)
    sol = solve_ivp(rhs, (0, t_end), [e0.real, e0.imag, 1 - s0], t_eval=ts, method="Radau",
                    rtol=1e-8, atol=1e-10, max_step=ramp / 4)  # fmt: skip
    out = np.empty((4, ts.size))
    for k, t in enumerate(ts):
        e = complex(sol.y[0, k], sol.y[1, k])
        vl = load_bus(t, e)
        ss = static_s(vl, vl0, qs) + mva * vl * np.conj((vl - e) / zm)
        i = np.conj(ss / vl)
        v = vl + z_fd * i
        s_in = v * np.conj(i)
        out[:, k] = abs(v), np.angle(v), s_in.real, s_in.imag
    pm0 = (mva * vl0 * np.conj((vl0 - e0) / zm)).real
    s_load0 = abs(static_s(vl0, vl0, qs) + mva * vl0 * np.conj((vl0 - e0) / zm))
    truth = {
        "rs": rs, "xs": xs, "xm": xm, "rr": rr, "h_s": h, "t0": t0, "mva": mva,
        "x_prime": xp, "t_prime_s": tp, "x_open": x, "p_static": p_static,
        "f_m": pm0 / (pm0 + p_static),
        # The feeder's X on the load's base (|S| at the first sample, as the model's).
        "x_fd": z_fd.imag * abs(out[2, 0] + 1j * out[3, 0]),
        "a1": zip_p[0], "a2": zip_p[1], "a3": zip_p[2], "s_load0": s_load0,
        "v_load0": abs(vl0),
        "qm0": (mva * vl0 * np.conj((vl0 - e0) / zm)).imag,
        "q_static": qs,
    }  # fmt: skip
    return ts, out[0], out[1], out[2], out[3], truth


def write_sags(root, sags=(0.15, 0.25), seed=2, noise=0.005):
    """Two (or more) sags of the default load as CSVs in ``root`` (``t_s, v, p, q,
    angle_rad``, 0.5% noise on P and Q, one generator of ``seed`` for all): their paths.

    The CLI tests that fit a small pair of events (``--model auto``, ``--noise ar1``)
    read these.
    """
    import pandas as pd

    rng = np.random.default_rng(seed)
    paths = []
    for k, sag in enumerate(sags):
        t, v, d, p, q, _ = simulate(sag=sag)
        frame = pd.DataFrame({"t_s": t, "v": v, "p": p + rng.normal(0, noise, t.size),
                              "q": q + rng.normal(0, noise, t.size), "angle_rad": d})  # fmt: skip
        paths.append(root / f"sag{k}.csv")
        frame.to_csv(paths[-1], index=False)
    return paths
