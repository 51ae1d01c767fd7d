"""Three-phase waveforms of a known load mix under a phase-to-ground fault (SciPy, NumPy).

The yardstick of issue 36's "sequence-domain records written in the tests": a record
whose negative sequence is known, made without the package (no import of ``loadbayes``;
the COMTRADE is written by :func:`waveform_composite.write_comtrade_1999`, the tests' own
writer), so that the reader's V2 and I2, and later a likelihood of the negative sequence,
are checked against physics the package did not compute.

The bus
-------
The recorder's bus voltage is given in sequence components (per unit of the phase
base), piecewise constant: balanced ``V1 = v_pre`` before the fault; during it (from
``t_on_s`` for ``duration_s``) ``V1``, ``V2`` and ``V0`` of a phase-A-to-ground fault
seen from a bus some way off it (:class:`Fault`: by default ``|V1| = 0.87``, ``|V2| =
0.13``, ``|V0| = 0.10``, V2 and V0 opposite V1, so that phase A dips most); balanced
again after. A fault starts and ends with a step (off a cycle boundary), as a real one.

The load (all per unit of the system base ``S_base``; motors on their own rating)
----------------------------------------------------------------------------------
- A static ZIP part, ``P = p_zip (a1 x^2 + a2 x + a3)``, ``Q = q_zip (a4 x^2 + a5 x +
  a6)``, ``x = |V1| / v_pre``, drawing ``I1 = conj(S / V1)``. Its negative-sequence
  admittance is its constant-impedance equivalent at the pre-fault point,
  ``Y2 = (p_zip - j q_zip) / v_pre^2``: a static load's unbalanced current is that of
  its impedance (lamps, heaters); it has no zero-sequence path (delta or ungrounded).
- One or two induction motors (:class:`Motor`), rating ``S_m`` (system p.u.), the
  T-circuit ``Rs + jXs`` then ``jXm`` in parallel with ``Rr / s + jXr``.

  Positive sequence: the third-order model (stator transients neglected) in the frame
  rotating at the nominal frequency, ``wb = 2 pi f``::

      dE'/dt = -j wb s E' - (E' - j (X - X') I1m) / T0'
      I1m    = (V1 - E') / (Rs + j X'),   X = Xs + Xm,   X' = Xs + Xm Xr / (Xm + Xr)
      T0'    = (Xr + Xm) / (wb Rr)
      ds/dt  = (T_load(s) - Te) / (2 H),   Te = Re(E' conj(I1m)) - T2
      T_load = T0 ((1 - s) / (1 - s0))^k   (k = 0 constant torque, k = 2 a fan)

  from its steady state at the pre-fault slip ``s0`` (``T0`` is the torque there, so
  the motor is loaded, not given a torque).

  Negative sequence: from the motor's own equivalent circuit at slip ``2 - s``::

      Z2(s) = Rs + jXs + jXm || (Rr / (2 - s) + jXr),     I2m = V2 / Z2(s)

  (close to ``Rs + Rr / (2 - s) + j (Xs + Xr)``, the form that neglects ``Xm``; both are
  in the truth). Its braking torque ``T2 = |Ir2|^2 Rr / (2 - s)`` (the negative-sequence
  rotor current's power at slip ``2 - s``) enters the slip equation.

  The motor's currents in system p.u. are ``S_m`` times those on its rating.
- A zero-sequence admittance ``y0`` (a grounded neutral somewhere in the bay), so that
  the reader must separate the sequences: ``I0 = y0 V0``.

The waveforms
-------------
Phases ``Xa = X0 + X1 + X2``, ``Xb = X0 + a^2 X1 + a X2``, ``Xc = X0 + a X1 + a^2 X2``,
``a = exp(j 2 pi / 3)``; instantaneous ``x_k(t) = sqrt(2) Re(X_k exp(j wb t))`` (volts
and amperes: ``V_base / sqrt 3`` for a voltage, ``S_base / (sqrt 3 V_base)`` for a
current), ``t`` from the first sample (the frame the reader's ``angle_rad`` uses), with
normal noise (a share of the nominal peak) and the writer's quantisation.

The truth (:attr:`Record.truth`) holds the bases, the fault, the ZIP part, each motor's
parameters, rating and pre-fault slip, and the mix's negative-sequence admittance ``Y2``
(system p.u., at the pre-fault slip and as a series in time), also in units of the mix's
pre-fault ``P0``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from waveform_composite import write_comtrade_1999

__all__ = ["Fault", "Motor", "Record", "generate", "write_record"]

A = np.exp(2j * np.pi / 3)


@dataclass(frozen=True)
class Motor:
    """A three-phase induction motor: T-circuit on its rating, inertia, loading."""

    rating: float  # S_m, per unit of the system base
    rs: float = 0.03
    xs: float = 0.10
    xm: float = 3.0
    rr: float = 0.02
    xr: float = 0.10
    h_s: float = 0.5
    s0: float = 0.015  # pre-fault slip
    torque_exp: int = 0  # 0 constant torque, 2 torque ~ speed^2

    def z1(self, s: float) -> complex:
        """Positive-sequence impedance of the T-circuit at slip ``s`` (motor base)."""
        rotor = self.rr / s + 1j * self.xr
        return self.rs + 1j * self.xs + 1j * self.xm * rotor / (1j * self.xm + rotor)

    def z2(self, s: float | np.ndarray) -> complex | np.ndarray:
        """Negative-sequence impedance at slip ``2 - s`` from the same circuit."""
        rotor = self.rr / (2.0 - s) + 1j * self.xr
        return self.rs + 1j * self.xs + 1j * self.xm * rotor / (1j * self.xm + rotor)

    def z2_approx(self, s: float) -> complex:
        """``Rs + Rr / (2 - s) + j (Xs + Xr)``: the magnetising branch neglected."""
        return self.rs + self.rr / (2.0 - s) + 1j * (self.xs + self.xr)

    @property
    def x(self) -> float:
        return self.xs + self.xm

    @property
    def x1(self) -> float:
        """Transient reactance X'."""
        return self.xs + self.xm * self.xr / (self.xm + self.xr)

    def t0p(self, wb: float) -> float:
        """Open-circuit transient time constant T0' (s)."""
        return (self.xr + self.xm) / (wb * self.rr)

    def rotor_neg_torque(self, v2: complex, s: float) -> float:
        """Braking torque of the negative sequence, ``|Ir2|^2 Rr / (2 - s)`` (motor base)."""
        if v2 == 0:
            return 0.0
        i2 = v2 / self.z2(s)
        e2 = v2 - (self.rs + 1j * self.xs) * i2  # across the magnetising branch
        ir2 = e2 / (self.rr / (2.0 - s) + 1j * self.xr)
        return float(abs(ir2) ** 2 * self.rr / (2.0 - s))


@dataclass(frozen=True)
class Fault:
    """Sequence voltages at the bus during a phase-A-to-ground fault (per unit)."""

    t_on_s: float = 0.2013
    duration_s: float = 0.0617
    v1: complex = 0.87 * np.exp(-0.05j)
    v2: complex = 0.13 * np.exp(1j * (np.pi - 0.05))
    v0: complex = 0.10 * np.exp(1j * (np.pi - 0.05))


@dataclass
class Record:
    """Sample times, per-unit sequence phasors at every sample, waveforms, the truth."""

    t: np.ndarray
    seq_v: np.ndarray  # (3, n): V0, V1, V2 per unit
    seq_i: np.ndarray  # (3, n): I0, I1, I2 per unit of S_base / (3 V_base_phase)
    v: np.ndarray  # (3, n) phase voltages, V
    i: np.ndarray  # (3, n) line currents, A
    truth: dict = field(default_factory=dict)

    def at(self, t: np.ndarray, which: str) -> np.ndarray:
        """A sequence phasor (``"v1"``, ``"v2"``, ``"i1"``, ``"i2"``, ...) at times ``t``.

        Linear interpolation between samples (1/rate apart: far finer than the motor's
        slip moves); on a step, the sample's side.
        """
        k = {"0": 0, "1": 1, "2": 2}[which[1]]
        x = (self.seq_v if which[0] == "v" else self.seq_i)[k]
        return np.interp(t, self.t, x.real) + 1j * np.interp(t, self.t, x.imag)


def _zip_current(v1: complex, p_zip: float, q_zip: float, shares, v_pre: float) -> complex:
    x = abs(v1) / v_pre
    a1, a2, a3, a4, a5, a6 = shares
    s = p_zip * (a1 * x * x + a2 * x + a3) + 1j * q_zip * (a4 * x * x + a5 * x + a6)
    return complex(np.conj(s / v1))


def _steady_eprime(m: Motor, v: complex, s: float, wb: float) -> complex:
    # 0 = -j wb s E' - (E' - j (X - X') (V - E') / Z') / T0'  is linear in E'.
    zp = m.rs + 1j * m.x1
    k = 1j * (m.x - m.x1) / zp
    return complex(k * v / (1.0 + 1j * wb * s * m.t0p(wb) + k))


def generate(
    *,
    f_hz: float = 50.0,
    rate_hz: float = 3200.0,
    t_end_s: float = 0.5,
    v_pre: float = 1.0,
    fault: Fault | None = None,
    p_zip: float = 0.35,
    q_zip: float = 0.05,
    zip_shares=(0.4, 0.3, 0.3, 0.5, 0.2, 0.3),
    motors: tuple[Motor, ...] | None = None,
    y0: complex = 0.3 - 0.1j,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """Sequence phasors (per unit) at every sample of a fault record, and the truth.

    Returns ``t``, ``seq_v`` (3, n: V0, V1, V2), ``seq_i`` (3, n: I0, I1, I2) and the
    truth dict (see the module docstring); no waveforms (:func:`write_record`).
    """
    fault = fault or Fault()
    if motors is None:
        motors = (
            Motor(rating=0.5),
            Motor(rating=0.3, rs=0.04, xs=0.12, xm=2.5, rr=0.035, xr=0.12, h_s=0.15,
                  s0=0.03, torque_exp=2),
        )  # fmt: skip
    wb = 2.0 * math.pi * f_hz
    n = int(math.floor(t_end_s * rate_hz + 1e-9))
    t = np.arange(n) / rate_hz
    on, off = fault.t_on_s, fault.t_on_s + fault.duration_s
    during = (t >= on) & (t < off)
    v1 = np.where(during, fault.v1, v_pre + 0j)
    v2 = np.where(during, fault.v2, 0j)
    v0 = np.where(during, fault.v0, 0j)
    # Each motor from its steady state: E' at s0, and the torque it then carries.
    state0, t_load = [], []
    for m in motors:
        e = _steady_eprime(m, v_pre + 0j, m.s0, wb)
        i = (v_pre - e) / (m.rs + 1j * m.x1)
        t_load.append(float((e * np.conj(i)).real))
        state0 += [e.real, e.imag, m.s0]

    def rhs(_t, y, v1k, v2k):
        out = np.empty_like(y)
        for j, m in enumerate(motors):
            e = y[3 * j] + 1j * y[3 * j + 1]
            s = y[3 * j + 2]
            i = (v1k - e) / (m.rs + 1j * m.x1)
            de = -1j * wb * s * e - (e - 1j * (m.x - m.x1) * i) / m.t0p(wb)
            tl = t_load[j] * ((1.0 - s) / (1.0 - m.s0)) ** m.torque_exp
            te = float((e * np.conj(i)).real) - m.rotor_neg_torque(v2k, s)
            out[3 * j], out[3 * j + 1] = de.real, de.imag
            out[3 * j + 2] = (tl - te) / (2.0 * m.h_s)
        return out

    y = np.empty((3 * len(motors), n))
    start = np.asarray(state0, dtype=float)
    edges = [0.0, on, off, t[-1] + 1.0 / rate_hz]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        idx = np.flatnonzero((t >= a) & (t < b))
        if idx.size == 0:
            continue
        args = (complex(v1[idx[0]]), complex(v2[idx[0]]))
        grid = np.concatenate([[a], t[idx]]) if t[idx[0]] > a else t[idx]
        sol = solve_ivp(rhs, (grid[0], b), start, t_eval=grid, args=args, method="Radau",
                        rtol=1e-10, atol=1e-12)  # fmt: skip
        if not sol.success:
            raise RuntimeError(sol.message)
        y[:, idx] = sol.y[:, -idx.size :]
        end = solve_ivp(rhs, (grid[-1], b), sol.y[:, -1], args=args, method="Radau",
                        rtol=1e-10, atol=1e-12)  # fmt: skip
        start = end.y[:, -1]
    i1 = np.array([_zip_current(complex(x), p_zip, q_zip, zip_shares, v_pre) for x in v1])
    y2_zip = (p_zip - 1j * q_zip) / v_pre**2
    y2 = np.full(n, y2_zip, dtype=complex)
    p0 = p_zip
    q0 = q_zip
    motor_truth = []
    for j, m in enumerate(motors):
        e = y[3 * j] + 1j * y[3 * j + 1]
        s = y[3 * j + 2]
        i1 = i1 + m.rating * (v1 - e) / (m.rs + 1j * m.x1)
        y2 = y2 + m.rating / m.z2(s)
        s_m0 = v_pre * np.conj(v_pre / m.z1(m.s0))
        p0 += m.rating * s_m0.real
        q0 += m.rating * s_m0.imag
        motor_truth.append(
            asdict(m)
            | {
                "x_prime": m.x1,
                "t0_prime_s": m.t0p(wb),
                "p_pre_motor_base": float(s_m0.real),
                "q_pre_motor_base": float(s_m0.imag),
                "load_torque": t_load[j],
                "slip_min": float(s.min()),
                "slip_max": float(s.max()),
                "y2_motor_base": complex(1.0 / m.z2(m.s0)),
                "y2_approx_motor_base": complex(1.0 / m.z2_approx(m.s0)),
            }
        )
    seq_v = np.vstack([v0, v1, v2])
    seq_i = np.vstack([y0 * v0, i1, y2 * v2])
    y2_pre = complex(y2_zip + sum(m.rating / m.z2(m.s0) for m in motors))
    truth = {
        "f_hz": f_hz,
        "rate_hz": rate_hz,
        "v_pre": v_pre,
        "fault": {"t_on_s": on, "t_off_s": off, "v1": fault.v1, "v2": fault.v2, "v0": fault.v0},
        "zip": {"p": p_zip, "q": q_zip, "shares": tuple(zip_shares), "y2": complex(y2_zip)},
        "motors": motor_truth,
        "motor_rating_total": float(sum(m.rating for m in motors)),
        "y0": y0,
        "p0": float(p0),
        "q0": float(q0),
        "y2_prefault": y2_pre,
        "y2_over_p0": y2_pre / p0,
        "y2_series": y2,
    }
    return t, seq_v, seq_i, y2, truth


def _phases(seq: np.ndarray) -> np.ndarray:
    x0, x1, x2 = seq
    return np.vstack([x0 + x1 + x2, x0 + A**2 * x1 + A * x2, x0 + A * x1 + A**2 * x2])


def write_record(
    stem: str | Path,
    *,
    v_base_kv: float = 110.0,
    s_base_mva: float = 40.0,
    noise_v: float = 0.0005,
    noise_i: float = 0.001,
    seed: int = 0,
    **settings,
) -> tuple[Path, Record]:
    """Generate (:func:`generate`'s ``settings``) and write ``stem.cfg``/``.dat``.

    ``noise_v``, ``noise_i``: sd of the normal noise on each sample as a share of the
    nominal peak (``sqrt 2`` times the phase base voltage, the base current). Returns the
    ``.cfg`` and the :class:`Record` (the truth with the bases added).
    """
    t, seq_v, seq_i, _, truth = generate(**settings)
    wb = 2.0 * math.pi * truth["f_hz"]
    v_ph = v_base_kv * 1e3 / math.sqrt(3.0)
    i_b = s_base_mva * 1e6 / (3.0 * v_ph)
    rot = np.exp(1j * wb * t)
    rng = np.random.default_rng(seed)
    v = math.sqrt(2.0) * (_phases(seq_v) * rot).real * v_ph
    i = math.sqrt(2.0) * (_phases(seq_i) * rot).real * i_b
    v += rng.normal(0.0, noise_v * math.sqrt(2.0) * v_ph, v.shape)
    i += rng.normal(0.0, noise_i * math.sqrt(2.0) * i_b, i.shape)
    cfg = write_comtrade_1999(
        stem, t, v, i, rate_hz=truth["rate_hz"], f_hz=truth["f_hz"],
        v_full_scale=1.3 * float(np.abs(v).max()), i_full_scale=1.3 * float(np.abs(i).max()),
    )  # fmt: skip
    truth |= {"v_base_kv": v_base_kv, "s_base_mva": s_base_mva, "noise_v": noise_v,
              "noise_i": noise_i, "seed": seed}  # fmt: skip
    return cfg, Record(t, seq_v, seq_i, v, i, truth)
