"""Simulated composite-load events: a library motor plus a ZIP part, with noise.

The motor is integrated by :func:`loadbayes.cases.motor_sim.simulate` (SciPy's
``solve_ivp``, DOP853, tight tolerances), independent of the compiled kernel the fit
uses: this is the "truth" the kernel and the fit are checked against.

The motor is driven by the continuous-time voltage: a step down at ``start_s`` (wherever
that falls between two samples, as a fault does), held, then a linear recovery (or a
step back). The recording is its samples ``V_k`` at ``fs`` per second, right-continuous
at the step (a sample at the step's instant reads the sag). The fit models such a step
at an unknown instant inside its sample interval (models/composite_steps.py); with
``step=False`` the motor is instead driven by the straight line through the samples,
which is the fit's reading with ``steps=False``.

Noise: independent normal on P and Q, sd ``noise * |S0|`` with ``|S0| = sqrt(p0^2 + q0^2)``
(one level for both channels, a fraction of the load's apparent power).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from loadbayes.cases.motor_sim import Disturbance, sag, simulate
from loadbayes.measurements.record import EventRecord
from loadbayes.models.motor import MotorParams
from loadbayes.models.motor_library import MOTORS

__all__ = ["simulate_event", "sag_samples"]


def sag_samples(
    t: np.ndarray,
    *,
    depth: float,
    start_s: float,
    duration_s: float,
    recovery_s: float = 0.0,
    v0: float = 1.0,
) -> np.ndarray:
    """Sampled voltage of a sag, then a linear recovery.

    ``v0 (1 - depth)`` on ``[start_s, start_s + duration_s)``, then back to ``v0`` linearly
    over ``recovery_s`` (a step when 0).
    """
    end = start_s + duration_s
    frac = np.where(t < start_s - 1e-12, 0.0, 1.0)
    if recovery_s > 0:
        frac = np.where(t >= end - 1e-12, np.clip(1.0 - (t - end) / recovery_s, 0.0, 1.0), frac)
    else:
        frac = np.where(t >= end - 1e-12, 0.0, frac)
    return v0 * (1.0 - depth * frac)


def simulate_event(
    motor: MotorParams | str = "small_industrial",
    *,
    depth: float = 0.3,
    start_s: float = 0.5,
    duration_s: float = 0.2,
    recovery_s: float = 0.3,
    t_end_s: float = 3.0,
    fs: float = 60.0,
    v0: float = 1.0,
    t0: float = 0.6,
    f_m: float = 0.5,
    p0: float = 1.0,
    q0: float = 0.3,
    zip_p: tuple[float, float, float] = (0.3, 0.3, 0.4),
    zip_q: tuple[float, float, float] = (0.4, 0.3, 0.3),
    noise: float = 0.01,
    seed: int = 0,
    name: str = "",
    step: bool = True,
) -> tuple[EventRecord, dict[str, Any]]:
    """Simulate one sag at a composite load.

    Parameters
    ----------
    motor : MotorParams or str
        A key of ``MOTORS`` or parameters (torque shares and ``f_hz`` from it).
    depth, start_s, duration_s, recovery_s : float
        The sag: fractional depth, start, length and linear recovery (s). The recovery
        gives the static part a range of voltages, not just two levels (with two, the
        three ZIP shares of a channel are one equation short).
    t_end_s, fs : float
        Record length (s) and samples per second.
    v0 : float
        Pre-event voltage (p.u.).
    t0 : float
        The motor's load torque at synchronous speed (own base).
    f_m : float
        Motor share of the initial active power ``p0``.
    p0, q0 : float
        Total initial active and reactive power (system p.u.).
    zip_p, zip_q : tuple of float
        ZIP shares of the static part (each sums to one; negatives allowed).
    noise : float
        Noise sd as a fraction of ``|S0|``.
    seed : int
        Seed of the noise.
    name : str
        Label of the event.
    step : bool
        Drive the motor with the continuous-time sag (a step at ``start_s``); False:
        with the straight line through the samples.

    Returns
    -------
    (EventRecord, dict)
        The noisy event and the truth, named as the fit reports it (docs/composite.md).
    """
    params = MOTORS[motor] if isinstance(motor, str) else motor
    if abs(sum(zip_p) - 1) > 1e-9 or abs(sum(zip_q) - 1) > 1e-9:
        raise ValueError("ZIP shares must each sum to 1")
    dt = 1.0 / fs
    n = int(math.floor(t_end_s * fs + 1e-9)) + 1
    t = dt * np.arange(n)
    v = sag_samples(
        t, depth=depth, start_s=start_s, duration_s=duration_s, recovery_s=recovery_s, v0=v0
    )
    if step:
        dist = sag(depth, start_s, duration_s, recovery_s, v0_pu=v0)
        v = dist(t)  # the same samples as sag_samples, from the profile itself
    else:
        # The interpolant bends at every sample where the slope changes: restart there.
        slope = np.diff(v)
        kinks = t[1:-1][np.abs(np.diff(slope)) > 1e-12]
        dist = Disturbance(t.copy(), v.copy(), tuple(float(k) for k in kinks if k > 0), {})
        dist = replace(
            dist, info={"kind": "sampled sag", "depth": depth, "fs": fs, "recovery_s": recovery_s}
        )
    rec = simulate(params, disturbance=dist, t_end_s=t[-1], dt_s=dt, t0=t0, noise=0.0, seed=0)
    p_m = rec["p"].to_numpy()
    q_m = rec["q"].to_numpy()
    x = v / v0
    s_m = f_m * p0 / p_m[0]
    p = p0 * (1 - f_m) * (zip_p[0] * x**2 + zip_p[1] * x + zip_p[2]) + s_m * p_m
    q = q0 * (zip_q[0] * x**2 + zip_q[1] * x + zip_q[2]) + s_m * (q_m - q_m[0] * x**2)
    sd = noise * math.hypot(p0, q0)
    rng = np.random.default_rng(seed)
    p_obs = p + sd * rng.standard_normal(n)
    q_obs = q + sd * rng.standard_normal(n)
    xp, x_open = params.xp, params.x
    truth: dict[str, Any] = {
        "p0": p0,
        "q0": q0,
        "v0": v0,
        **dict(zip(("a1", "a2", "a3"), zip_p, strict=True)),
        **dict(zip(("a4", "a5", "a6"), zip_q, strict=True)),
        "f_m": f_m,
        "rs": params.rs,
        "xs": params.xs,
        "xm": params.xm,
        "rr": params.rr,
        "xr": params.xr,
        "h_s": params.h_s,
        "a": params.a,
        "b": params.b,
        "c": params.c,
        "t0": t0,
        "x_prime": xp,
        "x_open": x_open,
        "t_prime_s": params.tp_s,
        "f_hz": params.f_hz,
        "mva_m": s_m,
        "q_c": s_m * q_m[0],
        "tau_p": 1.0 / sd**2 if sd > 0 else math.inf,
        "tau_q": 1.0 / sd**2 if sd > 0 else math.inf,
        "p_clean": p,
        "q_clean": q,
    }
    if step:  # the instants the fit reports as t_step0, t_step1 (an abrupt return)
        truth["t_step0"] = float(start_s)
        if recovery_s == 0:
            truth["t_step1"] = float(start_s + duration_s)
    return EventRecord(t, v, p_obs, q_obs, None, name or f"sag{depth:g}"), truth
