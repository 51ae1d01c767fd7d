"""Composite load: a static ZIP part and a third-order induction motor at one bus.

Physics only (docs/composite.md has the equations, units and choices). For one event
recorded at the bus (times ``t_k`` in s, voltage magnitude ``V_k`` and optionally angle
``delta_k``, total ``P_k``, ``Q_k`` in system p.u.), with ``x = V / v0`` and ``v0 = V_0``::

    P(t) = cp2 x^2 + cp1 x + cp0 + S_m p_m(t)
    Q(t) = cq2 x^2 + cq1 x + cq0 + S_m (q_m(t) - q_m(0) x^2)

``p_m, q_m`` are the motor's own-base powers (``models.motor_kernel.integrate`` from the
steady state at ``V_0``), ``S_m`` its rating in system p.u. (``mva_m``). The last term
holds the shunt capacitor that compensates the motor's initial reactive power,
``q_c = S_m q_m(0)`` at ``v0`` (a constant-impedance ``-q_c x^2``), so the motor and its
capacitor draw no net Q before the event and the ZIP part carries all of ``q0``, the usual
composite-load choice (WECC CMPLDW, PSS/E CLOD compensate the motor's magnetising Q).

Given the motor's dynamic parameters, ``P`` and ``Q`` are **linear** in the seven
coefficients ``beta = (cp2, cp1, cp0, cq2, cq1, cq0, P_m0)`` with ``P_m0 = S_m p_m(0)``
(the motor's columns divided by ``p_m(0)``); :func:`design` returns the
two design matrices, :func:`composition` maps ``beta`` to the named quantities
(``p0, q0, a1..a6, f_m, mva_m, q_c``).

Motor parametrisation: the dynamics depend on ``Rs, X', X - X', T', H`` and the loading
``T0`` only (``models/motor.py``); :data:`THETA_NAMES` are their logs. Physical reactances
follow from the closure ``Xs = Xr`` (docs/paper.md): ``Xm = sqrt(X (X - X'))``,
``Xs = Xr = X - Xm``, ``Rr = X / (wb T')``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from loadbayes.measurements.record import EventRecord
from loadbayes.models.motor_kernel import H_MAX_S, integrate, step_size

__all__ = [
    "BETA_NAMES",
    "SCALE_FREE_MATRIX",
    "SCALE_FREE_NAMES",
    "THETA_NAMES",
    "composition",
    "design",
    "motor_physical",
    "motor_response",
    "predict",
]

#: The sampled motor parameters: logs of Rs, X', X - X' (p.u.), T', H (s) and T0 (p.u.).
THETA_NAMES: tuple[str, ...] = ("log_rs", "log_x_prime", "log_dx", "log_t_prime", "log_h", "log_t0")
#: The linear coefficients, in the order of :func:`design`'s columns.
BETA_NAMES: tuple[str, ...] = ("cp2", "cp1", "cp0", "cq2", "cq1", "cq0", "p_m0")
#: Scale-free motor coordinates: ``log(Rs T0), log(X' T0), log((X - X') T0), log T',
#: log(H / T0)``. The model is exactly invariant under a change of the motor's base
#: (impedances times k, T0 and H divided by k, rating times k: same trajectory, same
#: P and Q), so the data inform these five and never ``log T0`` itself.
SCALE_FREE_NAMES: tuple[str, ...] = (
    "log_rs_t0",
    "log_x_prime_t0",
    "log_dx_t0",
    "log_t_prime",
    "log_h_over_t0",
)
#: ``u = SCALE_FREE_MATRIX @ theta`` (first five rows) and ``log T0`` (last row).
SCALE_FREE_MATRIX = np.array(
    [
        [1.0, 0, 0, 0, 0, 1],
        [0, 1, 0, 0, 0, 1],
        [0, 0, 1, 0, 0, 1],
        [0, 0, 0, 1, 0, 0],
        [0, 0, 0, 0, 1, -1],
        [0, 0, 0, 0, 0, 1],
    ]
)


def motor_response(
    event: EventRecord,
    theta: NDArray[np.float64],
    *,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0),
    h_max: float = H_MAX_S,
    window_s: float = 0.0,
    real: NDArray[np.int64] | None = None,
    v2: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The motor's own-base P, Q at the samples for log-parameters ``theta``.

    Parameters
    ----------
    event : EventRecord
        The recording (its V and angle drive the motor).
    theta : ndarray, shape (6,)
        Values of :data:`THETA_NAMES`.
    f_hz, torque, h_max
        Nominal frequency, ``(A, B, C)`` and the RK4 sub-step (see ``motor_kernel``).
    window_s : float
        0: the values at the sample instants. Above 0: each sample's mean over the
        ``window_s`` window centred on it (a phasor sample).
    real : ndarray of int, optional
        Only the samples ``real`` (the others knots of the input); default all
        (``motor_kernel.integrate``).
    v2 : ndarray, optional
        ``|V2|`` at the samples: the negative sequence's braking torque
        (``motor_kernel.brake_torque``); None: none.

    Returns
    -------
    (p_m, q_m) or None
        None when the loading has no stable steady state at ``v0`` or the trajectory
        is not finite.
    """
    rs, xp, dx, tp, h, t0 = np.exp(np.asarray(theta, dtype=float))
    # RK4's error grows as (h / T')^4: a fast motor proposed by a sampler gets a finer step.
    h_max = step_size(tp, h_max)
    out = integrate(
        event.t,
        event.v,
        event.delta,
        rs=rs,
        xp=xp,
        dx=dx,
        tp_s=tp,
        h_s=h,
        t0=t0,
        f_hz=f_hz,
        torque=torque,
        h_max=h_max,
        window_s=window_s,
        real=real,
        v2=v2,
    )
    return None if out is None else (out[0], out[1])


def design(
    event: EventRecord, p_m: NDArray[np.float64], q_m: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Design matrices of P and Q on ``beta`` (:data:`BETA_NAMES`), each shaped (n, 7)."""
    x = event.x
    n = event.n
    zp = np.zeros((n, 7))
    zq = np.zeros((n, 7))
    # The motor's columns are divided by p_m(0): the coefficient is then the motor's
    # initial active power P_m0 = f_m p0 (system p.u.), which does not depend on the
    # unknown rating (see SCALE_FREE_NAMES).
    zp[:, 0], zp[:, 1], zp[:, 2], zp[:, 6] = x * x, x, 1.0, p_m / p_m[0]
    zq[:, 3], zq[:, 4], zq[:, 5], zq[:, 6] = x * x, x, 1.0, (q_m - q_m[0] * x * x) / p_m[0]
    return zp, zq


def composition(
    beta: NDArray[np.float64], p_m0: NDArray[np.float64], q_m0: NDArray[np.float64]
) -> dict[str, NDArray[np.float64]]:
    """Named quantities from the linear coefficients, vectorised over draws.

    Parameters
    ----------
    beta : ndarray, shape (..., 7)
        Coefficients in the order of :data:`BETA_NAMES`.
    p_m0, q_m0 : ndarray, shape (...)
        The motor's own-base P and Q at the first sample.

    Returns
    -------
    dict
        ``p0, q0`` (total at ``v0``), ``a1, a2, a3`` (P shares of the ZIP part,
        ``P_zip0 = p0 (1 - f_m)``), ``a4, a5, a6`` (Q shares, ``Q_zip0 = q0``: the shunt
        cancels the motor's Q at ``v0``), ``f_m`` (motor share of ``p0``), ``mva_m``
        (``P_m0 / p_m0``) and ``q_c = mva_m q_m0``.
    """
    b = np.asarray(beta, dtype=float)
    pm = b[..., 6]
    pz = b[..., 0] + b[..., 1] + b[..., 2]
    qz = b[..., 3] + b[..., 4] + b[..., 5]
    p0 = pz + pm
    mva = pm / p_m0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = {
            "p0": p0,
            "q0": qz,
            "a1": b[..., 0] / pz,
            "a2": b[..., 1] / pz,
            "a3": b[..., 2] / pz,
            "a4": b[..., 3] / qz,
            "a5": b[..., 4] / qz,
            "a6": b[..., 5] / qz,
            "f_m": pm / p0,
            "mva_m": mva,
            "q_c": mva * q_m0,
        }
    return out


def motor_physical(theta: NDArray[np.float64], *, f_hz: float = 60.0) -> dict[str, NDArray]:
    """Physical motor parameters from log-parameters, vectorised (closure ``Xs = Xr``).

    Parameters
    ----------
    theta : ndarray, shape (..., 6)
        Values of :data:`THETA_NAMES`.
    f_hz : float
        Nominal frequency (``Rr = X / (wb T')``).

    Returns
    -------
    dict
        ``rs, xs, xm, rr, xr, h_s, t0, x_prime, x_open, t_prime_s``.
    """
    e = np.exp(np.asarray(theta, dtype=float))
    rs, xp, dx, tp, h, t0 = (e[..., i] for i in range(6))
    x = xp + dx
    xm = np.sqrt(x * dx)
    xs = x - xm
    return {
        "rs": rs,
        "xs": xs,
        "xm": xm,
        "rr": x / (2.0 * math.pi * f_hz * tp),
        "xr": xs,
        "h_s": h,
        "t0": t0,
        "x_prime": xp,
        "x_open": x,
        "t_prime_s": tp,
    }


def predict(
    event: EventRecord,
    theta: NDArray[np.float64],
    beta: NDArray[np.float64],
    *,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0),
    h_max: float = H_MAX_S,
    window_s: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Total P(t), Q(t) of the composite load for one parameter set (None: no steady state).

    ``window_s > 0``: the motor's part as window means centred on the samples
    (:func:`motor_response`).
    """
    resp = motor_response(event, theta, f_hz=f_hz, torque=torque, h_max=h_max, window_s=window_s)
    if resp is None:
        return None
    zp, zq = design(event, *resp)
    b = np.asarray(beta, dtype=float)
    return zp @ b, zq @ b
