"""Third-order induction motor: the physics (states, currents, powers, steady state).

The paper's section "IM Model", per unit on the motor's own base, with these choices.

Time base
---------
Time is in **seconds**; reactances and resistances are per unit at the nominal
frequency ``f_hz``, and ``wb = 2 pi f_hz`` rad/s. Then ``T' = (Xr + Xm) / (wb Rr)`` is in
seconds, the slip terms carry a factor ``wb`` and every derivative is per second::

    dEd'/dt = -(Ed' + (X - X') Iq) / T' - wb (w - 1) Eq'
    dEq'/dt = -(Eq' - (X - X') Id) / T' + wb (w - 1) Ed'
    dw/dt   = ((Ed' Id + Eq' Iq) - T0 (A w^2 + B w + C)) / (2 H)
    Id = ( Rs (Ud - Ed') + X' (Uq - Eq')) / (Rs^2 + X'^2)
    Iq = ( Rs (Uq - Eq') - X' (Ud - Ed')) / (Rs^2 + X'^2)

with ``X' = Xs + Xm Xr / (Xm + Xr)``, ``X = Xs + Xm``, ``A + B + C = 1`` and ``w`` the rotor
speed in p.u. of synchronous speed (slip ``s = 1 - w``). In complex form, with
``E' = Ed' + j Eq'``, ``U = Ud + j Uq`` and ``I = Id + j Iq`` (load convention: ``I`` flows
into the motor)::

    U = E' + (Rs + j X') I
    dE'/dt = -(E' - j (X - X') I) / T' + j wb (w - 1) E'

Regression form (what the estimators use), with
``b1 = -1/T'`` [1/s], ``b2 = -(X - X')/T'`` [1/s], ``b3 = -1/(2H)`` [1/s],
``ab = Rs/(Rs^2 + X'^2)``, ``ac = X'/(Rs^2 + X'^2)``::

    dEd'/dt + wb (w - 1) Eq' = b1 Ed' + b2 Iq
    dEq'/dt - wb (w - 1) Ed' = b1 Eq' - b2 Id
    dw/dt = b3 (T0 (A w^2 + B w + C) - (Ed' Id + Eq' Iq))
    Id = ab (Ud - Ed') + ac (Uq - Eq')
    Iq = ab (Uq - Eq') - ac (Ud - Ed')

Departures from the paper (see docs/paper.md, the numbered slips): the mechanical torque is
``A w^2 + B w + C`` (slip 3); the Iq equation has ``- ac (Ud - Ed')`` (slip 5); ``T0`` stays
in the speed regressor (slip 6); the slip terms carry ``wb`` because time is in seconds.

Sign conventions
----------------
Electrical torque ``Te = Ed' Id + Eq' Iq = Re(E' conj(I))`` (air-gap power, p.u.).
Complex power into the motor ``S = U conj(I)``: ``P = Ud Id + Uq Iq`` and
``Q = Uq Id - Ud Iq``; a motoring machine has ``P > 0`` and ``Q > 0`` (it absorbs
reactive power). The steady state puts the terminal voltage on the d axis:
``Ud = V``, ``Uq = 0``.

Its length is one idea: the motor's equations, stated once here with their conventions
(50 lines of docstring), the functions that evaluate them, and the steady state and its
inverse that start every simulation and fit.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize

__all__ = [
    "COEFFICIENT_NAMES",
    "MotorParams",
    "OperatingPoint",
    "currents",
    "derivatives",
    "electrical_torque",
    "inverse",
    "mechanical_torque",
    "power",
    "steady_state",
]

COEFFICIENT_NAMES: tuple[str, ...] = ("b1", "b2", "b3", "ab", "ac")
"""Names of the five regression coefficients, in the order the estimators use."""


@dataclass(frozen=True)
class MotorParams:
    """Induction-motor parameters, per unit on the motor's own base.

    Parameters
    ----------
    rs, xs, xm, rr, xr : float
        Stator resistance, stator leakage, magnetising reactance, rotor resistance and
        rotor leakage reactance (p.u., reactances at the nominal frequency).
    h_s : float
        Inertia constant H in seconds (rotor and load).
    a, b, c : float
        Mechanical-torque coefficients, ``Tm = T0 (a w^2 + b w + c)``; must sum to 1.
    name : str
        Free-text label.
    f_hz : float
        Nominal frequency in Hz; fixes ``wb = 2 pi f_hz`` and hence the time base.
    """

    rs: float
    xs: float
    xm: float
    rr: float
    xr: float
    h_s: float
    a: float = 1.0
    b: float = 0.0
    c: float = 0.0
    name: str = ""
    f_hz: float = 60.0

    def __post_init__(self) -> None:
        for field in ("xm", "rr", "xr", "h_s", "f_hz"):
            value = getattr(self, field)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"MotorParams.{field} must be finite and > 0, got {value!r}")
        for field in ("rs", "xs"):
            value = getattr(self, field)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"MotorParams.{field} must be finite and >= 0, got {value!r}")
        if abs(self.a + self.b + self.c - 1.0) > 1e-9:
            raise ValueError(f"a + b + c must be 1, got {self.a + self.b + self.c!r}")

    @property
    def wb(self) -> float:
        """Base angular frequency ``2 pi f_hz`` in rad/s."""
        return 2.0 * math.pi * self.f_hz

    @property
    def xp(self) -> float:
        """Transient reactance ``X' = Xs + Xm Xr / (Xm + Xr)`` (p.u.)."""
        return self.xs + self.xm * self.xr / (self.xm + self.xr)

    @property
    def x(self) -> float:
        """Open-circuit reactance ``X = Xs + Xm`` (p.u.)."""
        return self.xs + self.xm

    @property
    def tp_s(self) -> float:
        """Open-circuit transient time constant ``T' = (Xr + Xm) / (wb Rr)`` in seconds."""
        return (self.xr + self.xm) / (self.wb * self.rr)

    def coefficients(self) -> dict[str, float]:
        """Return the five regression coefficients.

        Returns
        -------
        dict of str to float
            ``b1 = -1/T'``, ``b2 = -(X - X')/T'``, ``b3 = -1/(2H)`` (all in 1/s) and
            ``ab = Rs/(Rs^2 + X'^2)``, ``ac = X'/(Rs^2 + X'^2)`` (p.u.).
        """
        tp, xp = self.tp_s, self.xp
        den = self.rs**2 + xp**2
        return {
            "b1": -1.0 / tp,
            "b2": -(self.x - xp) / tp,
            "b3": -1.0 / (2.0 * self.h_s),
            "ab": self.rs / den,
            "ac": xp / den,
        }

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a plain, JSON-serialisable dict."""
        return asdict(self)


def currents(
    ud: ArrayLike, uq: ArrayLike, ed: ArrayLike, eq: ArrayLike, params: MotorParams
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Stator currents from terminal voltage and transient EMF.

    Parameters
    ----------
    ud, uq : array_like
        Terminal voltage components (p.u.).
    ed, eq : array_like
        Transient EMF components Ed', Eq' (p.u.).
    params : MotorParams
        Motor parameters.

    Returns
    -------
    id, iq : ndarray
        Current components (p.u., load convention: into the motor).

    Notes
    -----
    ``I = (U - E') / (Rs + j X')``. The paper's Iq line has ``+ X' (Ud - Ed')``; the
    division gives ``- X' (Ud - Ed')`` (docs/paper.md, slip 5).
    """
    dd = np.asarray(ud, dtype=float) - np.asarray(ed, dtype=float)
    dq = np.asarray(uq, dtype=float) - np.asarray(eq, dtype=float)
    rs, xp = params.rs, params.xp
    den = rs**2 + xp**2
    return (rs * dd + xp * dq) / den, (rs * dq - xp * dd) / den


def electrical_torque(
    ed: ArrayLike, eq: ArrayLike, id: ArrayLike, iq: ArrayLike
) -> NDArray[np.float64]:
    """Air-gap torque ``Te = Ed' Id + Eq' Iq`` (p.u.)."""
    return np.asarray(ed, float) * np.asarray(id, float) + np.asarray(eq, float) * np.asarray(
        iq, float
    )


def mechanical_torque(w: ArrayLike, t0: float, params: MotorParams) -> NDArray[np.float64]:
    """Load torque ``Tm = T0 (A w^2 + B w + C)`` (p.u.; the paper writes ``A^2 w``, slip 3)."""
    w = np.asarray(w, dtype=float)
    return t0 * (params.a * w**2 + params.b * w + params.c)


def power(
    ud: ArrayLike, uq: ArrayLike, id: ArrayLike, iq: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Active and reactive power into the motor, ``S = U conj(I)``.

    Parameters
    ----------
    ud, uq, id, iq : array_like
        Voltage and current components (p.u.).

    Returns
    -------
    p, q : ndarray
        ``P = Ud Id + Uq Iq`` and ``Q = Uq Id - Ud Iq``; positive ``Q`` is absorbed, as
        for any motor (magnetising current lags the voltage).
    """
    ud, uq = np.asarray(ud, float), np.asarray(uq, float)
    id, iq = np.asarray(id, float), np.asarray(iq, float)
    return ud * id + uq * iq, uq * id - ud * iq


def derivatives(
    state: ArrayLike, ud: ArrayLike, uq: ArrayLike, params: MotorParams, *, t0: float
) -> NDArray[np.float64]:
    """Right-hand side of the state equations, vectorised over samples.

    Parameters
    ----------
    state : array_like, shape (3, ...)
        ``(Ed', Eq', w)``; trailing axes broadcast with ``ud`` and ``uq``.
    ud, uq : array_like
        Terminal voltage components (p.u.).
    params : MotorParams
        Motor parameters (fix ``wb`` through ``f_hz``).
    t0 : float
        Load-torque coefficient T0 (p.u.).

    Returns
    -------
    ndarray, shape (3, ...)
        ``(dEd'/dt, dEq'/dt, dw/dt)`` in 1/s (module docstring, "Time base").
    """
    if np.ndim(ud) == np.ndim(uq) == 0 and np.shape(state) == (3,):
        return _derivatives_one(state, float(ud), float(uq), params, t0)
    ed, eq, w = (np.asarray(s, dtype=float) for s in state)
    id_, iq = currents(ud, uq, ed, eq, params)
    tp, dx, wb = params.tp_s, params.x - params.xp, params.wb
    ded = -(ed + dx * iq) / tp - wb * (w - 1.0) * eq
    deq = -(eq - dx * id_) / tp + wb * (w - 1.0) * ed
    dw = (electrical_torque(ed, eq, id_, iq) - mechanical_torque(w, t0, params)) / (
        2.0 * params.h_s
    )
    if np.ndim(ded) == np.ndim(deq) == np.ndim(dw) == 0:
        # One sample (an ODE solver's call): nothing to broadcast, and the stack of
        # broadcast views costs more than the model's arithmetic.
        return np.array([ded, deq, dw], dtype=float)
    return np.stack(np.broadcast_arrays(ded, deq, dw))


def _derivatives_one(
    state: ArrayLike, ud: float, uq: float, params: MotorParams, t0: float
) -> NDArray[np.float64]:
    """:func:`derivatives` at one sample (an ODE solver's call), in Python floats.

    The same operations in the same order as the array path (``w**2`` is ``w * w``, as
    NumPy computes a square), so the same bits; NumPy's per-call cost on 0-d arrays was
    most of a reference simulation's time.
    """
    ed, eq, w = (float(s) for s in state)
    rs, xp = params.rs, params.xp
    den = rs**2 + xp**2
    dd, dq = ud - ed, uq - eq
    id_, iq = (rs * dd + xp * dq) / den, (rs * dq - xp * dd) / den
    tp, dx, wb = params.tp_s, params.x - params.xp, params.wb
    ded = -(ed + dx * iq) / tp - wb * (w - 1.0) * eq
    deq = -(eq - dx * id_) / tp + wb * (w - 1.0) * ed
    tm = t0 * (params.a * (w * w) + params.b * w + params.c)
    dw = (ed * id_ + eq * iq - tm) / (2.0 * params.h_s)
    return np.array([ded, deq, dw], dtype=float)


@dataclass(frozen=True)
class OperatingPoint:
    """Steady operating point of a motor (all p.u.; ``slip = 1 - w``)."""

    ud: float
    uq: float
    ed: float
    eq: float
    w: float
    id: float
    iq: float
    t0: float
    te: float
    p: float
    q: float
    slip: float
    breakdown_slip: float

    @property
    def state(self) -> NDArray[np.float64]:
        """The state vector ``(Ed', Eq', w)``."""
        return np.array([self.ed, self.eq, self.w])

    def to_dict(self) -> dict[str, float]:
        """Return the fields as a plain dict of floats."""
        return {k: float(v) for k, v in asdict(self).items()}


def _flux(params: MotorParams, v: float, s: NDArray[np.float64]) -> NDArray[np.complex128]:
    # dE'/dt = 0 with w = 1 - s and I = (V - E')/Z solves to
    # E' = j D V / (Z (1 + j wb T' s) + j D), D = X - X', Z = Rs + j X'.
    z = params.rs + 1j * params.xp
    dx = params.x - params.xp
    return 1j * dx * v / (z * (1.0 + 1j * params.wb * params.tp_s * s) + 1j * dx)


def _te_p_q(params: MotorParams, v: float, s: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
    s = np.asarray(s, dtype=float)
    e = _flux(params, v, s)
    i = (v - e) / (params.rs + 1j * params.xp)
    sv = v * np.conj(i)
    return (e * np.conj(i)).real, sv.real, sv.imag


def _first_root(f: Any, grid: NDArray[np.float64]) -> float | None:
    vals = f(grid)
    idx = np.flatnonzero(np.sign(vals[1:]) != np.sign(vals[:-1]))
    if idx.size == 0:
        return None
    k = int(idx[0])
    return float(optimize.brentq(lambda s: float(f(s)), grid[k], grid[k + 1], xtol=1e-16))


def steady_state(
    params: MotorParams,
    *,
    v_pu: float = 1.0,
    t0: float | None = None,
    slip: float | None = None,
    p_pu: float | None = None,
) -> OperatingPoint:
    """Solve the initial operating point (all three derivatives zero).

    Parameters
    ----------
    params : MotorParams
        Motor parameters.
    v_pu : float
        Terminal voltage magnitude; the reference puts it on the d axis (``Ud = V``,
        ``Uq = 0``).
    t0, slip, p_pu : float, optional
        The loading, exactly one of: the load-torque coefficient T0 (mechanical torque
        at synchronous speed), a target slip, or a target active power drawn.

    Returns
    -------
    OperatingPoint
        States, currents, T0, electrical torque, P, Q, slip and breakdown slip.

    Raises
    ------
    ValueError
        If the loading is not exactly one option, is not a motoring load, or lies
        beyond the breakdown (pull-out) torque; or if P or Q is not positive.

    Notes
    -----
    The slip is found on the stable branch (below the breakdown slip) by bracketing the
    torque balance ``Te(s) = Tm(1 - s)`` (or ``P(s) = p_pu``) on the closed-form
    electrical steady state, then the full three-state system is polished with
    ``scipy.optimize.root``.
    """
    given = {k: v for k, v in {"t0": t0, "slip": slip, "p_pu": p_pu}.items() if v is not None}
    if len(given) != 1:
        raise ValueError(f"give exactly one of t0, slip, p_pu; got {sorted(given) or 'none'}")
    if not v_pu > 0:
        raise ValueError(f"v_pu must be > 0, got {v_pu!r}")

    def te(s: ArrayLike) -> NDArray:
        return _te_p_q(params, v_pu, s)[0]

    grid = np.geomspace(1e-8, 1.0, 4001)
    k = int(np.argmax(te(grid)))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    s_bd = float(
        optimize.minimize_scalar(
            lambda s: -te(s), bounds=(lo, hi), method="bounded", options={"xatol": 1e-14}
        ).x
    )
    te_max = float(te(s_bd))
    branch = np.geomspace(1e-10, s_bd, 4001)

    if t0 is not None:
        if not t0 > 0:
            raise ValueError(f"t0 must be > 0 for a motoring load, got {t0!r}")
        s0 = _first_root(lambda s: te(s) - mechanical_torque(1.0 - s, t0, params), branch)
        if s0 is None:
            raise ValueError(
                f"load torque T0={t0:g} is beyond the breakdown torque {te_max:.4g} p.u. "
                f"(slip {s_bd:.4g}) at V={v_pu:g} p.u.: no stable operating point"
            )
    elif slip is not None:
        if not 0 < slip <= s_bd:
            raise ValueError(f"slip must be in (0, breakdown slip {s_bd:.4g}], got {slip!r}")
        s0 = float(slip)
    else:
        s0 = _first_root(lambda s: _te_p_q(params, v_pu, s)[1] - p_pu, branch)
        if s0 is None:
            raise ValueError(f"no stable operating point draws P={p_pu:g} p.u. at V={v_pu:g}")
    w_mech = mechanical_torque(1.0 - s0, 1.0, params)
    t0_val = float(te(s0) / w_mech) if t0 is None else float(t0)
    if not t0_val > 0:
        raise ValueError("the requested loading is not a motoring load (T0 <= 0)")

    e0 = _flux(params, v_pu, np.asarray(s0))
    x0 = np.array([e0.real, e0.imag, 1.0 - s0])
    sol = optimize.root(
        lambda x: derivatives(x, v_pu, 0.0, params, t0=t0_val),
        x0,
        method="hybr",
        options={"xtol": 1e-15},
    )
    res0 = np.max(np.abs(derivatives(x0, v_pu, 0.0, params, t0=t0_val)))
    ed, eq, w = sol.x if sol.success and np.max(np.abs(sol.fun)) <= res0 else x0
    id_, iq = currents(v_pu, 0.0, ed, eq, params)
    p, q = power(v_pu, 0.0, id_, iq)
    op = OperatingPoint(
        ud=float(v_pu),
        uq=0.0,
        ed=float(ed),
        eq=float(eq),
        w=float(w),
        id=float(id_),
        iq=float(iq),
        t0=t0_val,
        te=float(electrical_torque(ed, eq, id_, iq)),
        p=float(p),
        q=float(q),
        slip=float(1.0 - w),
        breakdown_slip=s_bd,
    )
    if not (0 < op.slip < 1 and op.p > 0 and op.q > 0):
        raise ValueError(f"operating point is not a motoring one: {op.to_dict()}")
    return op


def inverse(
    coefs: dict[str, ArrayLike], closure: str | None = "xs=xr", *, f_hz: float = 60.0
) -> dict[str, NDArray[np.float64]]:
    """Map regression coefficients back to physical parameters, vectorised over draws.

    Parameters
    ----------
    coefs : dict
        ``b1, b2, b3, ab, ac`` (scalars or arrays of draws, broadcastable).
    closure : {"xs=xr", None}
        The extra equation that splits ``X`` and ``X'`` into ``Xs, Xm, Xr``; ``None``
        returns only the five identifiable quantities.
    f_hz : float
        Nominal frequency; only ``rr`` depends on it (through ``wb``).

    Returns
    -------
    dict of str to ndarray
        ``rs, xp, x, tp_s, h_s`` and, with the closure, ``xs, xm, xr, rr``.

    Notes
    -----
    ``T' = -1/b1``, ``X - X' = b2/b1``, ``H = -1/(2 b3)``,
    ``Rs = ab/(ab^2 + ac^2)``, ``X' = ac/(ab^2 + ac^2)``, ``X = X' + (X - X')``.

    Closure ``Xs = Xr = y``: ``X = y + Xm`` gives ``Xm = X - y``; substituting in
    ``X' = y + Xm y/(Xm + y)`` gives ``X' = 2y - y^2/X``, i.e. ``y^2 - 2 X y + X X' = 0``,
    so ``y = X -+ sqrt(X (X - X'))``. The root with ``Xm = sqrt(X (X - X')) >= 0`` is
    kept: ``Xs = Xr = X - sqrt(X (X - X'))``, ``Xm = sqrt(X (X - X'))`` and
    ``Rr = (Xr + Xm)/(wb T') = X/(wb T')``. Where ``X (X - X') < 0`` there is no real
    solution and the four closure outputs are NaN. Other non-physical values (negative
    ``H``, ``T'`` or ``Rs`` from a draw with the wrong sign) are returned as computed.
    """
    b1, b2, b3, ab, ac = (np.asarray(coefs[k], dtype=float) for k in COEFFICIENT_NAMES)
    with np.errstate(divide="ignore", invalid="ignore"):
        tp = -1.0 / b1
        dx = b2 / b1
        den = ab**2 + ac**2
        xp = ac / den
        x = xp + dx
        out = {"rs": ab / den, "xp": xp, "x": x, "tp_s": tp, "h_s": -1.0 / (2.0 * b3)}
        if closure is None:
            return {k: v[()] for k, v in out.items()}
        if closure != "xs=xr":
            raise ValueError(f"unknown closure {closure!r}; use 'xs=xr' or None")
        disc = x * dx
        real = disc >= 0
        xm = np.where(real, np.sqrt(np.where(real, disc, 0.0)), np.nan)
        xs = x - xm
        rr = np.where(real, x / (2.0 * math.pi * f_hz * tp), np.nan)
        out.update(xs=xs, xm=xm, xr=xs, rr=rr)
    return {k: np.asarray(v)[()] for k, v in out.items()}
