"""An independent generator of sags that stall air conditioners: motor D behind a feeder.

Written with NumPy and SciPy only, from the published model, sharing no code with the
package. The recorded bus's voltage follows a sag (``depth`` below ``v_src0`` for
``dur`` seconds, linear ramps ``ramp_in`` and ``ramp_out``); behind a series feeder
impedance ``z_fd`` the load bus draws:

- a static ZIP part (its shares of its own P and Q at the pre-fault load-bus voltage);
- motor D, the single-phase compressors' performance model of PNNL-17796 as the WECC
  composite load model specification (2015) writes it, with its typical values: on its
  own base (P = 1 running at 1 p.u.), running

  - above ``vbrk``: ``P = P0 + kp1 (V - vbrk)^np1``, ``Q = Q0 + kq1 (V - vbrk)^nq1``,
  - below it: ``P = P0 + kp2 (vbrk - V)^np2``, ``Q = Q0 + kq2 (vbrk - V)^nq2``,

  with ``P0 = 1 - kp1 (1 - vbrk)^np1`` and ``Q0 = tan(acos(comp_pf)) - kq1 (1 -
  vbrk)^nq1`` (so P = 1 and Q = tan(acos(comp_pf)) at 1 p.u.); it stalls when the
  load-bus voltage has stayed below ``vstall`` for ``tstall`` (decided on the internal
  step, not on the output's samples), then draws the stalled impedance ``rstall +
  j xstall``, taken here on the motor's MVA base (``P / comp_pf``); after the voltage
  has stayed above ``vrst`` for ``trst`` the fraction ``frst`` restarts and runs again;
- optionally a third-order induction motor (``im``: the textbook equations of
  ``feeder_generator.py``, ``E'`` behind ``Rs + jX'``, speed with torque ``T0 (A w^2 +
  B w + C)``).

At every internal step (``dt``, about 0.5 ms) the feeder's loop ``V = V_L + z_fd
I(V_L)`` is solved for the load-bus voltage (``scipy.optimize.fsolve``), the motor's
state advanced by the classical fourth-order Runge-Kutta step (the load bus solved at
each stage) and motor D's timers by ``dt``. The record holds point samples at ``fs`` per
second of the recorded bus's V, angle, P and Q, and the truth: the load-bus voltage at
the samples, whether and when motor D stalled, its thresholds and shares.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.optimize import brentq, fsolve

#: Motor D's typical values (WECC composite load model specification; the run curves are
#: PNNL-17796's), restated here so the generator stays apart from the package.
MOTOR_D = {
    "vbrk": 0.86, "kp1": 0.0, "np1": 1.0, "kq1": 6.0, "nq1": 2.0, "kp2": 12.0, "np2": 3.2,
    "kq2": 11.0, "nq2": 2.5, "vstall": 0.60, "tstall": 0.033, "rstall": 0.10,
    "xstall": 0.10, "frst": 0.20, "vrst": 0.95, "trst": 0.30, "comp_pf": 0.98,
}  # fmt: skip


def run_curve(v, d):
    """A running motor D's P, Q on its own base at load-bus voltage ``v`` (array)."""
    v = np.asarray(v, dtype=float)
    p0 = 1.0 - d["kp1"] * (1.0 - d["vbrk"]) ** d["np1"]
    q0 = math.tan(math.acos(d["comp_pf"])) - d["kq1"] * (1.0 - d["vbrk"]) ** d["nq1"]
    hi = np.maximum(v - d["vbrk"], 0.0)
    lo = np.maximum(d["vbrk"] - v, 0.0)
    above = v >= d["vbrk"]
    p = np.where(above, p0 + d["kp1"] * hi ** d["np1"], p0 + d["kp2"] * lo ** d["np2"])
    q = np.where(above, q0 + d["kq1"] * hi ** d["nq1"], q0 + d["kq2"] * lo ** d["nq2"])
    return p, q


def stalled_power(v, d):
    """A stalled motor D's P, Q on its own base (P = 1 running at 1 p.u.)."""
    zz = d["rstall"] ** 2 + d["xstall"] ** 2
    scale = np.asarray(v, dtype=float) ** 2 / (zz * d["comp_pf"])
    return scale * d["rstall"], scale * d["xstall"]


def source(t, *, depth, t_on, dur, ramp_in, ramp_out, v_src0):
    """The recorded bus's voltage: down ``depth`` over ``ramp_in``, held ``dur``, back."""
    down = np.clip((t - t_on) / ramp_in, 0, 1) if ramp_in > 0 else float(t >= t_on)
    t_up = t_on + ramp_in + dur
    up = np.clip((t - t_up) / ramp_out, 0, 1) if ramp_out > 0 else float(t >= t_up)
    return v_src0 * (1.0 - depth * (down - up))


def simulate(*, depth=0.3, dur=0.15, t_on=0.1, ramp_in=0.0, ramp_out=0.0, t_end=0.8,
             fs=60.0, dt=5e-4, v_src0=1.0, z_fd=complex(0.021, 0.06), p_load=0.8,
             f_d=0.3, zip_p=(0.4, 0.3, 0.3), zip_q=(0.5, 0.3, 0.2), q_static=0.15,
             motor_d=None, im=None, f_hz=60.0):  # fmt: skip
    """``(t, v, angle, p, q, truth)`` of one sag (system p.u.; the module docstring).

    ``p_load`` is the load bus's pre-fault P, of which ``f_d`` is motor D's; ``q_static``
    the static part's Q; ``motor_d`` overrides :data:`MOTOR_D` by name; ``im`` (a dict:
    ``mva, rs, xs, xm, rr, h, t0, torque``) adds an induction motor whose P is on top.
    """
    d = {**MOTOR_D, **(motor_d or {})}
    wb = 2 * np.pi * f_hz
    pd_rate = f_d * p_load
    p_static = p_load - pd_rate
    zip_p, zip_q = np.asarray(zip_p, float), np.asarray(zip_q, float)
    m = None
    if im is not None:
        m = dict(im)
        m["x"] = m["xs"] + m["xm"]
        m["xp"] = m["xs"] + m["xm"] * m["xs"] / (m["xm"] + m["xs"])
        m["tp"] = m["x"] / (wb * m["rr"])
        m["zm"] = complex(m["rs"], m["xp"])

    def static_s(vl_abs, vl0_abs):
        r = vl_abs / vl0_abs
        zp = zip_p[0] * r * r + zip_p[1] * r + zip_p[2]
        zq = zip_q[0] * r * r + zip_q[1] * r + zip_q[2]
        return p_static * zp + 1j * q_static * zq

    def d_s(vl_abs, running):
        pr, qr = run_curve(vl_abs, d)
        ps, qs = stalled_power(vl_abs, d)
        return pd_rate * complex(running * pr + (1 - running) * ps,
                                 running * qr + (1 - running) * qs)  # fmt: skip

    def im_current(vl, e):
        return 0j if m is None else m["mva"] * (vl - e) / m["zm"]

    def e_ss(vl, s):
        return 1j * (m["x"] - m["xp"]) * vl / (m["zm"] * (1 + 1j * wb * m["tp"] * s)
                                                + 1j * (m["x"] - m["xp"]))  # fmt: skip

    def torque_load(w):
        a, b, c = m["torque"]
        return m["t0"] * (a * w * w + b * w + c)

    # The pre-fault state: the recorded bus at v_src0, the static part at its own
    # voltage (it draws p_static, q_static there), motor D running, the motor in balance.
    def init(z):
        vl = complex(z[0], z[1])
        s_l = static_s(abs(vl), abs(vl)) + d_s(abs(vl), 1.0)
        out = []
        if m is not None:
            e = e_ss(vl, z[2])
            i_m = im_current(vl, e)
            s_l += vl * np.conj(i_m)
            te = (e * np.conj((vl - e) / m["zm"])).real
            out = [te - torque_load(1 - z[2])]
        v = vl + z_fd * np.conj(s_l / vl)
        return [v.real - v_src0, v.imag, *out]

    z0 = fsolve(init, [0.97, -0.03] + ([0.01] if m is not None else []), xtol=1e-13)
    vl0 = complex(z0[0], z0[1])
    v0_abs = abs(vl0)
    e = e_ss(vl0, z0[2]) if m is not None else 0j
    w = 1 - z0[2] if m is not None else 1.0

    def loop(v_src, e, running, guess):
        def f(z):
            vl = complex(*z)
            s_l = static_s(abs(vl), v0_abs) + d_s(abs(vl), running)
            i = np.conj(s_l / vl) + im_current(vl, e)
            r = vl + z_fd * i - v_src
            return [r.real, r.imag]

        # full_output: a converged solve that cannot reach xtol is judged by its residual.
        z = fsolve(f, [guess.real, guess.imag], xtol=1e-12, full_output=True)[0]
        if np.hypot(*f(z)) > 1e-9:
            raise RuntimeError("the feeder's loop has no solution (voltage collapse)")
        return complex(*z)

    def rhs(y, vl):
        e, w = complex(y[0], y[1]), y[2]
        i_m = (vl - e) / m["zm"]
        de = -1j * wb * (1 - w) * e - (e - 1j * (m["x"] - m["xp"]) * i_m) / m["tp"]
        te = (e * np.conj(i_m)).real
        return np.array([de.real, de.imag, (te - torque_load(w)) / (2 * m["h"])])

    sub = max(1, math.ceil(1.0 / (fs * dt)))
    h = 1.0 / (fs * sub)  # the internal step: the samples fall on it
    n_out = int(math.floor(t_end * fs + 1e-9)) + 1
    src_kw = {"depth": depth, "t_on": t_on, "dur": dur, "ramp_in": ramp_in,
              "ramp_out": ramp_out, "v_src0": v_src0}  # fmt: skip
    running, below, above, restarted = 1.0, 0.0, 0.0, False
    t_stall = None
    vl = vl0
    rows, fine_v = [], []
    y = np.array([e.real, e.imag, w])
    n_steps = (n_out - 1) * sub
    for k in range(n_steps + 1):
        t = k * h
        vsrc = source(t, **src_kw)
        vl = loop(vsrc, complex(y[0], y[1]), running, vl)
        fine_v.append(abs(vl))
        if k % sub == 0:
            ey = complex(y[0], y[1])
            s_l = static_s(abs(vl), v0_abs) + d_s(abs(vl), running)
            i = np.conj(s_l / vl) + im_current(vl, ey)
            s_l = vl * np.conj(i)
            v = vl + z_fd * i
            s_in = v * np.conj(i)
            rows.append([t, abs(v), np.angle(v), s_in.real, s_in.imag, abs(vl), s_l.real,
                         s_l.imag, abs(i), running])  # fmt: skip
        if k == n_steps:
            break
        # Motor D's timers over [t, t + h): the voltage at the step's start holds.
        if t_stall is None:
            below = below + h if abs(vl) < d["vstall"] else 0.0
            if below >= d["tstall"] - 1e-12:
                t_stall, running = t + h, 0.0
        elif not restarted:
            above = above + h if abs(vl) > d["vrst"] else 0.0
            if above >= d["trst"] - 1e-12:
                restarted, running = True, d["frst"]
        if m is not None:

            def at(tt, yy, guess, running=running):
                g = loop(source(tt, **src_kw), complex(yy[0], yy[1]), running, guess)
                return rhs(yy, g), g

            k1, g1 = rhs(y, vl), vl
            k2, g2 = at(t + h / 2, y + h / 2 * k1, g1)
            k3, g3 = at(t + h / 2, y + h / 2 * k2, g2)
            k4, _ = at(t + h, y + h * k3, g3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    arr = np.array(rows)
    truth = {
        "vstall": d["vstall"], "tstall": d["tstall"], "stalled": t_stall is not None,
        "t_stall": t_stall, "restarted": restarted, "motor_d": d,
        "v_load": arr[:, 5], "p_load": arr[:, 6], "q_load": arr[:, 7], "i": arr[:, 8],
        "running": arr[:, 9], "v_load_fine": np.array(fine_v), "dt": h,
        "v_load0": v0_abs, "f_d": f_d, "p_static": p_static, "q_static": q_static,
        "a1": zip_p[0], "a2": zip_p[1], "a3": zip_p[2], "z_fd": z_fd,
        # The feeder's X on the load's base (|S| at the first sample, as the model's).
        "x_fd": z_fd.imag * abs(arr[0, 3] + 1j * arr[0, 4]),
    }  # fmt: skip
    return arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4], truth


def stall_depth(*, dur, lo=0.05, hi=0.45, tol=1e-4, **kw):
    """The least sag depth (at the recorded bus) that stalls motor D, by bisection.

    ``kw`` as :func:`simulate` (the same load); ``t_end`` is cut to the fault's end.
    """
    kw = {**kw, "t_end": kw.get("t_on", 0.1) + dur + 0.1, "dur": dur}

    @functools.cache  # brentq asks the two ends again: the same runs
    def stalls(x):
        return simulate(depth=x, **kw)[5]["stalled"]

    if stalls(lo) or not stalls(hi):
        raise ValueError("the stall depth lies outside [lo, hi]")
    return brentq(lambda x: 0.5 - float(stalls(x)), lo, hi, xtol=tol)
