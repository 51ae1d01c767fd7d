"""An independent composite-load event generator: SciPy only, none of loadbayes's motor code.

The yardstick of issue 21: events the package did not make, to check ``fit_composite``
against. Written from the equations of docs/composite.md ("The model") and nothing else:
no import of ``loadbayes`` at all, so a shared mistake cannot hide.

The model
---------
Bus quantities per unit on the system base; the motor's impedances and torque per unit on
its own rating ``S_m``; time in seconds, ``wb = 2 pi f_hz``. The motor is the third-order
induction motor with its slip terms::

    dEd'/dt = -(Ed' + (X - X') Iq) / T' - wb (w - 1) Eq'
    dEq'/dt = -(Eq' - (X - X') Id) / T' + wb (w - 1) Ed'
    dw/dt   = ((Ed' Id + Eq' Iq) - T0 (A w^2 + B w + C)) / (2 H)
    I = (U - E') / (Rs + j X'),   p_m + j q_m = U conj(I),   U = V e^{j delta}

with ``X = Xs + Xm``, ``X' = Xs + Xm Xr / (Xm + Xr)``, ``T' = (Xr + Xm) / (wb Rr)``. It is
integrated by ``scipy.integrate.solve_ivp`` (Radau, rtol 1e-8, atol 1e-10), restarted at
every knot of the voltage (so an exact step and the kink of a ramp are integrated
exactly), from its own steady state: for a slip ``s`` the flux equations are linear in
``E'`` and are solved as such, and the slip is the first root (scanning up from ``s = 0``:
the stable branch) of electrical minus load torque, found by ``scipy.optimize.brentq``.

The bus load is::

    P(t) = p0 (1 - f_m) (a1 x^2 + a2 x + a3) + S_m p_m(t)
    Q(t) = q0 (a4 x^2 + a5 x + a6)         + S_m (q_m(t) - q_m(0) x^2)

with ``x = V / v0`` and ``S_m = f_m p0 / p_m(0)``: the motor takes ``f_m`` of the initial
active power, and a constant-impedance capacitor ``q_c = S_m q_m(0)`` cancels its initial
reactive power, so ``q0`` is all the static part's (docs/composite.md, "Shunt
compensation").

The voltage
-----------
A continuous, piecewise-linear ``V(t)`` and ``delta(t)`` (:class:`Sag`): each sag leaves
``v0`` at ``start_s`` (anywhere, not on a sample instant), reaches ``v0 (1 - depth)``
after ``ramp_in_s`` (0: an exact step), holds, and leaves that level at
``start_s + duration_s`` to be back at ``v0`` after ``ramp_out_s``; the angle moves by
``angle_rad`` with the same shape. Several sags follow each other. Optionally
(:func:`simulate`'s ``angle_extra``) the system's own phase against the ``f_hz`` frame is
added to ``delta(t)`` (an off-nominal frequency, a frequency dip): the motor sees it, and
it starts in the steady state of the frequency at the start.

Sampling (the window model)
---------------------------
``sampling="point"``: the instantaneous ``V, P, Q`` (and angle) at ``t_k = k / rate_hz``.
``sampling="phasor"``: what a recorder's phasor estimation gives, modelled as the mean
over the one-cycle window ``[t_k - 1/f_hz, t_k]`` of the instantaneous ``V, P, Q`` (and
angle). The window means are exact integrals: ``int V``, ``int P``, ``int Q``,
``int delta`` are carried as quadrature states of the same ODE. A real recorder's
estimator (a DFT over one cycle of the waveform, then magnitude) is not exactly the mean
of the magnitude, but it is a one-cycle average of the same kind, which is what the fit
must not read as a point.

Noise: independent normal on P and Q, sd ``noise * hypot(p0, q0)`` (the convention of the
package's own simulator, so noise levels compare); ``noise_v`` on V (default 0).

The two motors (:data:`MOTORS`), not in the package's library (whose T' are 0.087,
0.50, 1.17 and 1.6 s): ``small_fast`` (T' 0.060 s, H 0.35 s) and ``large_slow`` (T'
0.70 s, H 1.2 s), both with ``Xs = Xr`` (the closure the package assumes, so any miss is
the fit's and not the closure's).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = [
    "MOTORS",
    "Motor",
    "Sag",
    "knots",
    "simulate",
    "simulate_event",
    "steady_state",
]


@dataclass(frozen=True)
class Motor:
    """An induction motor, per unit on its own rating (60 Hz time base by default)."""

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

    @property
    def x(self) -> float:
        """Open-circuit reactance ``Xs + Xm``."""
        return self.xs + self.xm

    @property
    def xp(self) -> float:
        """Transient reactance ``Xs + Xm Xr / (Xm + Xr)``."""
        return self.xs + self.xm * self.xr / (self.xm + self.xr)

    def tp(self, f_hz: float = 60.0) -> float:
        """Open-circuit transient time constant ``(Xr + Xm) / (wb Rr)`` in seconds."""
        return (self.xr + self.xm) / (2.0 * math.pi * f_hz * self.rr)


def _motor_for_tp(tp_s: float, *, rs: float, xs: float, xm: float, h_s: float, name: str) -> Motor:
    """A motor with ``Xs = Xr`` whose ``Rr`` gives the transient time constant ``tp_s``."""
    rr = (xs + xm) / (2.0 * math.pi * 60.0 * tp_s)
    return Motor(rs=rs, xs=xs, xm=xm, rr=rr, xr=xs, h_s=h_s, name=name)


#: Two motors not in loadbayes's library (60 Hz): a small fast one and a large slow one.
MOTORS: dict[str, Motor] = {
    # A small motor (a few kW): high rotor resistance, T' 0.060 s, light rotor.
    "small_fast": _motor_for_tp(0.060, rs=0.040, xs=0.10, xm=2.2, h_s=0.35, name="small fast"),
    # A large motor (MW class): low rotor resistance, T' 0.70 s, heavy rotor.
    "large_slow": _motor_for_tp(0.70, rs=0.010, xs=0.09, xm=3.5, h_s=1.2, name="large slow"),
}


@dataclass(frozen=True)
class Sag:
    """One voltage sag: leaves ``v0`` at ``start_s``, ramps (0 = step) to and from the level."""

    start_s: float
    depth: float
    duration_s: float
    ramp_in_s: float = 0.0
    ramp_out_s: float = 0.0
    angle_rad: float = 0.0


def knots(v0: float, sags: Sequence[Sag], t_start: float, t_end: float) -> np.ndarray:
    """The knots ``(t, v, delta)`` of the piecewise-linear voltage, shape (n, 3).

    A step is two knots at the same instant (the value before, then after). Between
    knots ``V`` and ``delta`` are linear; before the first and after the last, constant.
    """
    rows = [(t_start, v0, 0.0)]
    last = t_start
    for s in sorted(sags, key=lambda s: s.start_s):
        if (
            not 0.0 < s.depth < 1.0
            or s.duration_s < s.ramp_in_s
            or min(s.ramp_in_s, s.ramp_out_s) < 0
        ):
            raise ValueError(f"sag {s}: need 0 < depth < 1, ramps >= 0, duration >= ramp in")
        t1, t2 = s.start_s, s.start_s + s.ramp_in_s
        t3, t4 = s.start_s + s.duration_s, s.start_s + s.duration_s + s.ramp_out_s
        if t1 <= last or t4 >= t_end:
            raise ValueError(f"sag at {s.start_s} s overlaps another or the record's ends")
        vs = v0 * (1.0 - s.depth)
        rows += [(t1, v0, 0.0), (t2, vs, s.angle_rad), (t3, vs, s.angle_rad), (t4, v0, 0.0)]
        last = t4
    rows.append((t_end, v0, 0.0))
    return np.array(rows, dtype=float)


def _voltage(kn: np.ndarray, i: int, t: float) -> tuple[float, float]:
    """``V, delta`` at ``t`` inside segment ``i`` (from knot ``i`` to knot ``i + 1``)."""
    t0, t1 = kn[i, 0], kn[i + 1, 0]
    w = (t - t0) / (t1 - t0)
    return (
        kn[i, 1] + w * (kn[i + 1, 1] - kn[i, 1]),
        kn[i, 2] + w * (kn[i + 1, 2] - kn[i, 2]),
    )


def _current(m: Motor, u: complex, e: complex) -> complex:
    return (u - e) / complex(m.rs, m.xp)


def _rhs_motor(m: Motor, f_hz: float, t0: float, u: complex, y: np.ndarray) -> np.ndarray:
    """The three motor derivatives at terminal voltage ``u`` and state ``(Ed', Eq', w)``."""
    ed, eq, w = y[0], y[1], y[2]
    wb = 2.0 * math.pi * f_hz
    i = _current(m, u, complex(ed, eq))
    dx, tp = m.x - m.xp, m.tp(f_hz)
    ded = -(ed + dx * i.imag) / tp - wb * (w - 1.0) * eq
    deq = -(eq - dx * i.real) / tp + wb * (w - 1.0) * ed
    te = ed * i.real + eq * i.imag
    tm = t0 * (m.a * w * w + m.b * w + m.c)
    return np.array([ded, deq, (te - tm) / (2.0 * m.h_s)])


def _flux_at_slip(m: Motor, f_hz: float, v: float, s: float) -> complex:
    """The steady flux ``E'`` at slip ``s``: the flux equations are affine in ``E'``."""

    def f(e: np.ndarray) -> np.ndarray:
        return _rhs_motor(m, f_hz, 0.0, complex(v, 0.0), np.array([e[0], e[1], 1.0 - s]))[:2]

    b = f(np.zeros(2))
    a = np.column_stack([f(np.array([1.0, 0.0])) - b, f(np.array([0.0, 1.0])) - b])
    e = np.linalg.solve(a, -b)
    return complex(e[0], e[1])


def _torque_gap(m: Motor, f_hz: float, v: float, t0: float, s: float, w_sync: float = 1.0) -> float:
    e = _flux_at_slip(m, f_hz, v, s)
    i = _current(m, complex(v, 0.0), e)
    w = w_sync - s
    return (e.real * i.real + e.imag * i.imag) - t0 * (m.a * w * w + m.b * w + m.c)


def steady_state(
    m: Motor, t0: float, *, v: float = 1.0, f_hz: float = 60.0, w_sync: float = 1.0
) -> np.ndarray:
    """The steady state ``(Ed', Eq', w)`` at terminal voltage ``v`` (angle 0), stable branch.

    The slip is the first zero of electrical minus load torque scanning up from
    ``s = 0`` (where the electrical torque is zero and the load's is ``T0 (A + B + C)``);
    a root past the breakdown slip (the peak of the electrical torque) is a stall.

    ``w_sync``: the voltage's speed in units of ``wb`` (1: nominal). Off nominal, the
    flux is that of the slip ``s = w_sync - w`` in a frame turning with the voltage (the
    slip terms see ``w - w_sync``), and the load torque that of the rotor's ``w``; the
    flux returned is in that frame, the voltage on its d axis.
    """
    grid = np.concatenate([np.geomspace(1e-6, 0.05, 400), np.linspace(0.05, 1.0, 400)[1:]])
    g = np.array([_torque_gap(m, f_hz, v, t0, s, w_sync) for s in grid])
    up = np.nonzero((g[:-1] < 0.0) & (g[1:] >= 0.0))[0]
    k = up[0] if up.size else 0

    te = g + np.array([t0 * (m.a * w * w + m.b * w + m.c) for w in w_sync - grid])
    if up.size == 0 or grid[k] > grid[np.argmax(te)]:
        raise ValueError(f"motor {m.name!r} stalls at V={v} with T0={t0}: no steady state")
    s = brentq(
        lambda s: _torque_gap(m, f_hz, v, t0, s, w_sync),
        grid[k], grid[k + 1], xtol=1e-15, rtol=1e-14,
    )  # fmt: skip
    e = _flux_at_slip(m, f_hz, v, s)
    return np.array([e.real, e.imag, w_sync - s])


@dataclass
class Trajectory:
    """A noise-free simulation: the motor's solution and the bus load, as functions of time."""

    motor: Motor
    f_hz: float
    t0: float
    kn: np.ndarray
    sols: list  # one OdeSolution per segment (None for a zero-length step segment)
    s_m: float
    pm0: float
    qm0: float
    v0: float
    p0: float
    q0: float
    f_m: float
    shares: tuple[float, float, float, float, float, float]
    #: The system's phase on top of the knots' angle (rad, a function of t), or None.
    angle_extra: Callable[[float], float] | None = None

    def voltage(self, i: int, t: float) -> tuple[float, float]:
        """``V, delta`` at ``t`` inside segment ``i``: the knots' plus ``angle_extra``."""
        v, d = _voltage(self.kn, i, t)
        if self.angle_extra is not None:
            d += self.angle_extra(t)
        return v, d

    def _segment(self, t: float) -> int:
        # Right-continuous: at a step instant, the segment after the step.
        i = int(np.searchsorted(self.kn[:, 0], t, side="right")) - 1
        i = min(max(i, 0), len(self.kn) - 2)
        while self.sols[i] is None:
            i += 1
        return i

    def state(self, t: float) -> np.ndarray:
        """``(Ed', Eq', w, int V, int P, int Q, int delta)`` at ``t``."""
        i = self._segment(t)
        return self.sols[i](t)

    def point(self, t: float) -> tuple[float, float, float, float]:
        """Instantaneous ``V, delta, P, Q`` at ``t``."""
        i = self._segment(t)
        v, d = self.voltage(i, t)
        y = self.sols[i](t)
        return (v, d, *self._pq(v, d, y))

    def _pq(self, v: float, d: float, y: np.ndarray) -> tuple[float, float]:
        u = v * complex(math.cos(d), math.sin(d))
        i = _current(self.motor, u, complex(y[0], y[1]))
        s = u * i.conjugate()
        x = v / self.v0
        a1, a2, a3, a4, a5, a6 = self.shares
        p = self.p0 * (1.0 - self.f_m) * (a1 * x * x + a2 * x + a3) + self.s_m * s.real
        q = self.q0 * (a4 * x * x + a5 * x + a6) + self.s_m * (s.imag - self.qm0 * x * x)
        return p, q

    def motor_power(self, t: float) -> tuple[float, float, float, float]:
        """Motor's ``p_m, q_m`` (own rating), electrical torque and load torque at ``t``."""
        i_seg = self._segment(t)
        v, d = self.voltage(i_seg, t)
        y = self.sols[i_seg](t)
        u = v * complex(math.cos(d), math.sin(d))
        e = complex(y[0], y[1])
        i = _current(self.motor, u, e)
        s = u * i.conjugate()
        m, w = self.motor, y[2]
        te = e.real * i.real + e.imag * i.imag
        return s.real, s.imag, te, self.t0 * (m.a * w * w + m.b * w + m.c)


def simulate(
    *,
    motor: Motor | str = "small_fast",
    t0: float = 0.7,
    f_m: float = 0.4,
    p0: float = 1.0,
    q0: float = 0.3,
    shares: Sequence[float] = (0.3, 0.3, 0.4, 0.4, 0.3, 0.3),
    v0: float = 1.0,
    sags: Sequence[Sag] = (Sag(1.0123, 0.3, 0.2, 0.02, 0.02),),
    t_start_s: float = -0.1,
    t_end_s: float = 3.0,
    f_hz: float = 60.0,
    angle_extra: Callable[[float], float] | None = None,
) -> Trajectory:
    """Integrate the motor through the sags (noise-free); see the module's docstring.

    ``angle_extra``: the system's phase relative to the ``f_hz`` frame (rad, a function
    of t), added to the knots' angle wherever the voltage is used (the motor's terminal
    voltage, the point and window outputs, :meth:`Trajectory.motor_power`): an
    off-nominal frequency ``f_sys`` is ``2 pi (f_sys - f_hz) t``, a frequency dip its
    integral. Its slope at ``t_start_s`` (where it must be linear: a steady frequency)
    sets the initial steady state (:func:`steady_state`'s ``w_sync``), so the record
    starts without a transient. None (default): the nominal frequency, as before.
    """
    m = MOTORS[motor] if isinstance(motor, str) else motor
    if not 0.0 < f_m < 1.0:
        raise ValueError("f_m must lie in (0, 1)")
    if len(shares) != 6 or abs(sum(shares[:3]) - 1) > 1e-12 or abs(sum(shares[3:]) - 1) > 1e-12:
        raise ValueError("shares a1..a6 with a1 + a2 + a3 = 1 and a4 + a5 + a6 = 1")
    kn = knots(v0, sags, t_start_s, t_end_s)
    if angle_extra is None:
        y0m = steady_state(m, t0, v=v0, f_hz=f_hz)
    else:
        h = 1e-3  # the slope of a linear phase, to rounding
        rate = (angle_extra(t_start_s + h) - angle_extra(t_start_s - h)) / (2.0 * h)
        y0m = steady_state(m, t0, v=v0, f_hz=f_hz, w_sync=1.0 + rate / (2.0 * math.pi * f_hz))
    i0 = _current(m, complex(v0, 0.0), complex(y0m[0], y0m[1]))
    s0 = v0 * i0.conjugate()
    pm0, qm0 = s0.real, s0.imag
    traj = Trajectory(m, f_hz, t0, kn, [], f_m * p0 / pm0, pm0, qm0, v0, p0, q0, f_m, tuple(shares),
                      angle_extra)  # fmt: skip
    if angle_extra is not None:  # the steady flux turned to the voltage's angle at the start
        d0 = angle_extra(t_start_s)
        e0 = complex(y0m[0], y0m[1]) * complex(math.cos(d0), math.sin(d0))
        y0m = np.array([e0.real, e0.imag, y0m[2]])

    y = np.concatenate([y0m, np.zeros(4)])
    for i in range(len(kn) - 1):
        ta, tb = kn[i, 0], kn[i + 1, 0]
        if tb <= ta:  # a step: the state carries over, only the voltage jumps
            traj.sols.append(None)
            continue

        def rhs(t: float, z: np.ndarray, i: int = i) -> np.ndarray:
            v, d = traj.voltage(i, t)
            u = v * complex(math.cos(d), math.sin(d))
            p, q = traj._pq(v, d, z)
            return np.concatenate([_rhs_motor(m, f_hz, t0, u, z), [v, p, q, d]])

        sol = solve_ivp(rhs, (ta, tb), y, method="Radau", rtol=1e-8, atol=1e-10, dense_output=True)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed on [{ta}, {tb}]: {sol.message}")
        traj.sols.append(sol.sol)
        y = sol.y[:, -1]
    return traj


def simulate_event(
    *,
    rate_hz: float = 60.0,
    sampling: str = "point",
    noise: float = 0.005,
    noise_v: float = 0.0,
    seed: int = 0,
    angle: bool = False,
    t_end_s: float = 3.0,
    **kwargs,
) -> tuple[pd.DataFrame, dict]:
    """One recorded event: the samples (``t_s, v, p, q[, angle_rad]``) and the truth.

    Parameters
    ----------
    rate_hz : float
        Samples per second; samples at ``t_k = k / rate_hz`` from 0 to ``t_end_s``.
    sampling : {"point", "phasor"}
        Instantaneous values, or one-cycle window means (the module's window model).
    noise, noise_v : float
        Sd of the normal noise on P, Q (times ``hypot(p0, q0)``) and on V.
    seed : int
        Seed of the noise.
    angle : bool
        Add the ``angle_rad`` column.
    **kwargs
        Passed to :func:`simulate` (motor, t0, f_m, p0, q0, shares, v0, sags, f_hz).

    Returns
    -------
    (DataFrame, dict)
        The samples, and the truth: ``f_m, p0, q0, a1..a6, t_prime_s, x_prime, x_open,
        dx, rs, h_s, t0`` (the motor on its own rating ``mva_m``), the base-free
        ``rs_t0, x_prime_t0, dx_t0, h_over_t0``, ``q_c``, ``slip0`` and ``t_fault_s``
        (the instants each sag starts and ends: the ramps' first knots).
    """
    if sampling not in ("point", "phasor"):
        raise ValueError("sampling is 'point' or 'phasor'")
    f_hz = kwargs.get("f_hz", 60.0)
    window = 1.0 / f_hz
    traj = simulate(t_start_s=-2.0 * window, t_end_s=t_end_s + 1e-9, **kwargs)
    n = int(math.floor(t_end_s * rate_hz + 1e-9)) + 1
    t = np.arange(n) / rate_hz
    out = np.empty((n, 4))
    for k, tk in enumerate(t):
        if sampling == "point":
            v, d, p, q = traj.point(tk)
        else:
            hi, lo = traj.state(tk), traj.state(tk - window)
            v, p, q, d = (hi[3:7] - lo[3:7]) / window
        out[k] = (v, d, p, q)
    rng = np.random.default_rng(seed)
    sd = noise * math.hypot(traj.p0, traj.q0)
    df = pd.DataFrame(
        {
            "t_s": t,
            "v": out[:, 0] + noise_v * rng.standard_normal(n),
            "p": out[:, 2] + sd * rng.standard_normal(n),
            "q": out[:, 3] + sd * rng.standard_normal(n),
        }
    )
    if angle:
        df["angle_rad"] = out[:, 1]
    return df, truth(traj)


def truth(traj: Trajectory) -> dict:
    """The true parameters of a trajectory, under the package's names."""
    m, f_hz = traj.motor, traj.f_hz
    a = dict(zip(("a1", "a2", "a3", "a4", "a5", "a6"), traj.shares, strict=True))
    dx = m.x - m.xp
    sags = traj.kn[1:-1:4, 0].tolist() + traj.kn[3:-1:4, 0].tolist()
    return {
        "f_m": traj.f_m,
        "p0": traj.p0,
        "q0": traj.q0,
        "v0": traj.v0,
        **a,
        "t_prime_s": m.tp(f_hz),
        "x_prime": m.xp,
        "x_open": m.x,
        "dx": dx,
        "rs": m.rs,
        "h_s": m.h_s,
        "t0": traj.t0,
        "mva_m": traj.s_m,
        "rs_t0": m.rs * traj.t0,
        "x_prime_t0": m.xp * traj.t0,
        "dx_t0": dx * traj.t0,
        "h_over_t0": m.h_s / traj.t0,
        "q_c": traj.s_m * traj.qm0,
        "slip0": float(1.0 - traj.state(traj.kn[0, 0])[2]),
        "t_fault_s": sorted(sags),
        "motor": m.name,
    }
