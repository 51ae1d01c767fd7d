"""The composite load (ZIP + induction motor) of the naming contract, by the package's simulator.

A reference implementation for the checks against ANDES: given one parameter set (names as
in ``docs/andes.md``, "Naming contract") and a measured terminal voltage (magnitude and
angle), it returns the load's P and Q by driving :func:`loadbayes.cases.motor_sim.simulate`
(SciPy DOP853, tight tolerances) with that voltage. It is slow and exact; the composite
fit has its own compiled kernel.

The model (all system p.u., ``x = V / v0``)::

    P(t) = (1 - f_m) p0 (a1 x^2 + a2 x + a3)            + mva_m P_m(t)
    Q(t) = q_s0 (a4 x^2 + a5 x + a6)      - q_c x^2     + mva_m Q_m(t)
    mva_m = f_m p0 / P_m(0),   q_s0 = q0 + q_c - mva_m Q_m(0)

where ``P_m, Q_m`` are the motor's powers on its own rating, its steady state at ``v0``
with load torque ``t0`` (own base), and ``q_c`` a shunt capacitor's supply at ``v0``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from loadbayes.cases.motor_sim import Disturbance
from loadbayes.cases.motor_sim import simulate as simulate_motor
from loadbayes.models.motor import steady_state
from loadbayes.models.motor_library import motor_from_values

__all__ = ["predict", "profile"]


def profile(t: ArrayLike, values: ArrayLike, *, kind: str) -> Disturbance:
    """A piecewise-linear profile through recorded samples, with steps where samples crowd.

    A network simulator records a switching instant as two samples a hair apart (ANDES:
    0.1 ms); those pairs become integrator breakpoints, so the motor simulator restarts
    at the step instead of striding over it.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0) or t.size != y.size:
        raise ValueError("need at least two samples with strictly increasing times")
    dt = np.diff(t)
    close = np.flatnonzero(dt < 0.5 * np.median(dt))
    cuts = sorted({float(t[k]) for k in close} | {float(t[k + 1]) for k in close})
    return Disturbance(t, y, tuple(cuts), {"kind": kind, "n": int(t.size)})


def predict(
    values: Mapping[str, float],
    t_s: ArrayLike,
    v: ArrayLike,
    angle_rad: ArrayLike | None = None,
    *,
    dt_s: float | None = None,
) -> pd.DataFrame:
    """Composite load P, Q for a recorded terminal voltage.

    Parameters
    ----------
    values : mapping
        ``p0, q0, f_m, a1..a6, rs, xs, xm, rr, xr, h_s, t0`` and optionally ``v0`` (default
        the first voltage sample), ``a, b, c``, ``f_hz``, ``q_c`` (default 0).
    t_s, v : array_like
        Recorded time (s, strictly increasing, starting at 0) and voltage magnitude (p.u.).
    angle_rad : array_like, optional
        Recorded voltage angle (rad, in a frame turning at the nominal frequency); without
        it the motor sees a voltage of fixed phase.
    dt_s : float, optional
        Output spacing; default the median sample spacing. Output times are ``k dt_s``.

    Returns
    -------
    pandas.DataFrame
        ``t_s, v, p, q, p_motor, q_motor, p_static, q_static`` (system p.u.); ``attrs`` has
        ``mva_m`` and the motor's steady state.
    """
    t = np.asarray(t_s, dtype=float)
    vm = np.asarray(v, dtype=float)
    motor = motor_from_values(values)
    v0 = float(values.get("v0", vm[0]))
    t0 = float(values["t0"])
    p0, q0, f_m = float(values["p0"]), float(values["q0"]), float(values["f_m"])
    q_c = float(values.get("q_c", 0.0))
    op = steady_state(motor, v_pu=v0, t0=t0)
    mva_m = f_m * p0 / op.p
    step = float(np.median(np.diff(t))) if dt_s is None else float(dt_s)
    # The steady state is solved at v0; the profile starts there even if the first sample
    # differs by rounding (it is the same number when v0 is taken from the record).
    vprof = profile(t, np.concatenate([[v0], vm[1:]]), kind="recorded V")
    aprof = None if angle_rad is None else profile(t, angle_rad, kind="recorded angle")
    sim = simulate_motor(
        motor, disturbance=vprof, angle=aprof, t_end_s=float(t[-1]), dt_s=step, t0=t0, noise=0.0
    )
    x = np.hypot(sim["ud"], sim["uq"]).to_numpy() / v0
    a1, a2, a3 = (float(values[k]) for k in ("a1", "a2", "a3"))
    a4, a5, a6 = (float(values[k]) for k in ("a4", "a5", "a6"))
    p_static = (1.0 - f_m) * p0 * (a1 * x**2 + a2 * x + a3)
    q_s0 = q0 + q_c - mva_m * op.q
    q_static = q_s0 * (a4 * x**2 + a5 * x + a6) - q_c * x**2
    p_motor = mva_m * sim["p"].to_numpy()
    q_motor = mva_m * sim["q"].to_numpy()
    out = pd.DataFrame(
        {
            "t_s": sim["t_s"].to_numpy(),
            "v": x * v0,
            "p": p_static + p_motor,
            "q": q_static + q_motor,
            "p_motor": p_motor,
            "q_motor": q_motor,
            "p_static": p_static,
            "q_static": q_static,
        }
    )
    out.attrs.update({"mva_m": mva_m, "steady_state": op.to_dict(), "v0": v0})
    return out
