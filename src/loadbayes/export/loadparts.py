"""A fitted load as the parts simulators hold: a static V-polynomial and a motor.

Every simulator format here writes a load as

    P(V) = pz V^2 + pi V + pp       (MW),    Q(V) = qz V^2 + qi V + qp   (Mvar)

with V in per unit of the bus's base voltage, plus, for the composite load, an induction
motor drawing ``p_mw, q_mvar`` at the initial voltage. :func:`load_parts` builds these
from one parameter set named as in the naming contract.

- ZIP: ``P = p0 (a1 (V/v0)^2 + a2 V/v0 + a3)``, so ``pz = p0 a1 / v0^2``,
  ``pi = p0 a2 / v0``, ``pp = p0 a3`` (and the same for Q with a4, a5, a6 and q0).
- Exponential ``P = p0 (V/v0)^np``: no simulator here takes it as such in its power flow,
  so it is replaced by the ZIP that fits ``x^np`` best in least squares on
  ``V/v0`` in [0.7, 1.1] with shares summing to 1; the largest relative deviation on
  that band is reported in the notes (it is zero for np = 0, 1, 2).
- Composite: the motor draws ``f_m p0`` at ``v0``, always (the best-determined number of
  the fit is not moved by the conversion): its rating is ``mva = f_m p0 / P_m(v0)`` with
  ``P_m(v0)`` the motor's own-base P at its steady state at ``v0`` (from
  :func:`loadbayes.models.motor.steady_state`, load torque ``t0`` on the motor's base),
  and its Q is ``mva Q_m(v0)``. The posterior's ``mva_m`` is *not* used: the mean (or a
  quantile) of ``mva_m`` times the own-base P of the mean motor is not ``f_m p0``, which
  moved the motor's MW by 9 % between exports (issue 23). The static ZIP carries
  ``(1 - f_m) p0`` of the active power and ``q0 - q_m + q_c`` of the reactive, where
  ``q_c`` is the shunt compensation (reactive power supplied at v0, positive for
  capacitors; the posterior's ``q_c``, else the motor's Q at v0 as the composite model
  defines it). It is a constant-impedance ``-q_c (V/v0)^2``: ``LoadParts.q_c`` for the
  writers that hold a shunt, folded into the polynomial's ``qz`` for the others.

Every export (pandapower, PSS/E, ANDES) takes its numbers from :func:`load_parts`, so the
same draw gives the same motor MW in each.

Powers in the posterior are in per unit of ``s_base_mva`` (``options["s_base_mva"]``,
default 1: the posterior's units are then MW and Mvar); ``options["p_mw"]`` and
``options["q_mvar"]`` give the load's P and Q at v0 directly when the posterior has
no ``p0``/``q0`` (a ZIP fitted with fixed nominal values).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["LoadParts", "MotorPart", "load_parts", "zip_of_exponent"]

_MOTOR_FIELDS = ("rs", "xs", "xm", "rr", "xr", "h_s")


@dataclass
class MotorPart:
    """The motor of a composite load, at its initial operating point.

    Parameters
    ----------
    params : loadbayes.models.motor.MotorParams
        Its parameters on its own base (impedances in p.u. of ``mva``, ``h_s`` in s on
        ``mva``).
    t0 : float
        Load torque at synchronous speed (own base).
    mva : float
        Rating (MVA): ``p_mw / p_pu``.
    p_mw, q_mvar : float
        Power drawn at ``v0``; ``p_mw = f_m P0`` exactly.
    slip : float
        Initial slip.
    p_pu, q_pu : float
        The same power on the motor's own base (``p_pu`` is the WECC loading factor).
    """

    params: Any
    t0: float
    mva: float
    p_mw: float
    q_mvar: float
    slip: float
    p_pu: float = float("nan")
    q_pu: float = float("nan")

    @property
    def x_sync(self) -> float:
        """Synchronous (open-circuit) reactance ``xs + xm`` (own base)."""
        return self.params.xs + self.params.xm

    @property
    def x_transient(self) -> float:
        """Transient reactance ``xs + xm xr / (xm + xr)`` (own base)."""
        pr = self.params
        return pr.xs + pr.xm * pr.xr / (pr.xm + pr.xr)

    @property
    def t_open_s(self) -> float:
        """Transient open-circuit time constant ``(xr + xm) / (wb rr)`` in seconds."""
        pr = self.params
        return (pr.xr + pr.xm) / (2.0 * math.pi * pr.f_hz * pr.rr)


@dataclass
class LoadParts:
    """Static polynomial (MW, Mvar at V in p.u.), optional motor, and notes for the header.

    ``pz .. qp`` hold the static load *and* the shunt compensation (``-q_c / v0^2`` in
    ``qz``), as a simulator with one load record takes them; ``q_c`` (Mvar at v0),
    ``p_static``, ``q_static`` (the static load's MW, Mvar at v0, without the shunt) and
    its shares ``shares_p``, ``shares_q`` (Z, I, P of ``V/v0``) are there for the
    writers that hold the parts apart (pandapower's shunt, the WECC composite record).
    """

    pz: float
    pi: float
    pp: float
    qz: float
    qi: float
    qp: float
    v0: float
    motor: MotorPart | None = None
    notes: list[str] = field(default_factory=list)
    q_c: float = 0.0
    p_static: float = float("nan")
    q_static: float = float("nan")
    shares_p: tuple[float, float, float] = (float("nan"),) * 3
    shares_q: tuple[float, float, float] = (float("nan"),) * 3

    @property
    def p_total(self) -> float:
        """The whole load's MW at v0 (static and motor)."""
        return self.p_static + (self.motor.p_mw if self.motor else 0.0)

    def without_shunt(self) -> tuple[float, float, float]:
        """``(qz, qi, qp)`` of the static load alone (the shunt taken out of ``qz``)."""
        return self.qz + self.q_c / self.v0**2, self.qi, self.qp

    def p(self, v: np.ndarray | float) -> np.ndarray:
        """Static P (MW) at V (p.u.)."""
        v = np.asarray(v, dtype=float)
        return self.pz * v**2 + self.pi * v + self.pp

    def q(self, v: np.ndarray | float) -> np.ndarray:
        """Static Q (Mvar) at V (p.u.)."""
        v = np.asarray(v, dtype=float)
        return self.qz * v**2 + self.qi * v + self.qp


def zip_of_exponent(n: float, lo: float = 0.7, hi: float = 1.1) -> tuple[np.ndarray, float]:
    """ZIP shares (summing to 1) closest to ``x^n`` on ``[lo, hi]``, and the worst error.

    Parameters
    ----------
    n : float
        The exponent.
    lo, hi : float
        The band of ``x = V / v0``.

    Returns
    -------
    shares : numpy.ndarray
        ``(z, i, p)``.
    max_error : float
        Largest ``|ZIP(x) - x^n|`` on the band.
    """
    x = np.linspace(lo, hi, 201)
    # y - 1 = z (x^2 - 1) + i (x - 1): the sum-to-one constraint eliminated.
    a = np.column_stack([x**2 - 1, x - 1])
    z, i = np.linalg.lstsq(a, x**n - 1, rcond=None)[0]
    shares = np.array([z, i, 1 - z - i])
    fit = shares[0] * x**2 + shares[1] * x + shares[2]
    return shares, float(np.max(np.abs(fit - x**n)))


def _nominal(values: Mapping[str, float], options: Mapping[str, Any], ch: str) -> float:
    unit = "p_mw" if ch == "p" else "q_mvar"
    if options.get(unit) is not None:
        return float(options[unit])
    if f"{ch}0" not in values:
        what = "P in MW" if ch == "p" else "Q in Mvar"
        raise ValueError(
            f"the parameter set has no {ch}0: give the load's {what} at v0 "
            f"(--{unit.replace('_', '-')})"
        )
    return float(values[f"{ch}0"]) * float(options.get("s_base_mva") or 1.0)


def _shares(values: Mapping[str, float], names: tuple[str, str, str]) -> np.ndarray:
    a, b, c = names
    if a not in values or b not in values:
        raise ValueError(f"the parameter set lacks {a} or {b}")
    third = values.get(c, 1.0 - values[a] - values[b])
    shares = np.array([values[a], values[b], third], dtype=float)
    # A parameter set whose shares do not sum to 1 is not one fit's (the mean, a draw and
    # the quantiles exported all keep the sum): an edited or mixed file. Normalising it
    # would invent a load no fit found, and the static record and the load flow would
    # disagree; so it is refused, as ANDES refuses it (issue 40, M6).
    if not np.isfinite(shares).all() or abs(shares.sum() - 1.0) > 1e-6:
        got = ", ".join(f"{x:.6g}" for x in shares)
        raise ValueError(
            f"{a}, {b}, {c} must be finite and sum to 1, got {got} (an edited file, or "
            "shares from different fits)"
        )
    return shares


def load_parts(values: Mapping[str, float], *, model: str, options: Mapping[str, Any]) -> LoadParts:
    """Turn one parameter set into a static polynomial and a motor.

    Parameters
    ----------
    values : mapping of str to float
        Parameters named as in the naming contract.
    model : {"zip", "exponential", "composite"}
        The model.
    options : mapping
        ``s_base_mva``, ``p_mw``, ``q_mvar``, ``v0``, ``f_hz`` (see module docstring).

    Returns
    -------
    LoadParts
        The parts.

    Raises
    ------
    ValueError
        For another model, missing parameters, or a motor with no steady state.
    """
    from loadbayes.export import check_model

    check_model(model)
    v0 = float(values.get("v0", options.get("v0") or 1.0))
    if not (math.isfinite(v0) and v0 > 0):
        raise ValueError(f"v0 must be a positive number, got {v0}")
    notes: list[str] = []
    p_tot, q_tot = _nominal(values, options, "p"), _nominal(values, options, "q")
    if model == "exponential":
        sp, errp = zip_of_exponent(float(values["np"]))
        sq, errq = zip_of_exponent(float(values.get("nq", 2.0)))
        notes.append(
            f"exponential load (np = {values['np']:.4g}, nq = {values.get('nq', 2.0):.4g}) "
            f"written as the closest ZIP on V/v0 in [0.7, 1.1]: largest error "
            f"{errp:.2g} (P) and {errq:.2g} (Q) of P0, Q0"
        )
        if "kpf" in values or "kqf" in values:
            notes.append("frequency dependence (kpf, kqf) is not exported")
    else:
        sp = _shares(values, ("a1", "a2", "a3"))
        if "a4" in values or "a5" in values:
            sq = _shares(values, ("a4", "a5", "a6"))
        else:
            sq = np.array([0.0, 0.0, 1.0])
            notes.append("the posterior has no Q model (a4, a5): Q written as constant power")
    motor = None
    p_static, q_static, qz_extra = p_tot, q_tot, 0.0
    if model == "composite":
        motor = _motor(values, options, p_tot, v0)
        p_static = p_tot - motor.p_mw
        if "q_c" in values:
            q_c = float(values["q_c"]) * float(options.get("s_base_mva") or 1.0)
        else:  # the composite model's shunt: the motor's Q compensated at v0
            q_c = motor.q_mvar
        q_static = q_tot - motor.q_mvar + q_c
        qz_extra = -q_c / v0**2
        notes.append(
            f"composite: motor {motor.p_mw:.6g} MW (f_m {float(values['f_m']):.6g} of P0 "
            f"{p_tot:.6g} MW), {motor.q_mvar:.6g} Mvar at v0 (slip {motor.slip:.4g}, "
            f"rating {motor.mva:.6g} MVA); static part {p_static:.6g} MW, {q_static:.6g} "
            f"Mvar; shunt compensation {q_c:.6g} Mvar"
        )
    return LoadParts(
        pz=p_static * sp[0] / v0**2,
        pi=p_static * sp[1] / v0,
        pp=p_static * sp[2],
        qz=q_static * sq[0] / v0**2 + qz_extra,
        qi=q_static * sq[1] / v0,
        qp=q_static * sq[2],
        v0=v0,
        motor=motor,
        notes=notes,
        q_c=q_c if model == "composite" else 0.0,
        p_static=p_static,
        q_static=q_static,
        shares_p=tuple(float(x) for x in sp),
        shares_q=tuple(float(x) for x in sq),
    )


def _motor(values: Mapping[str, float], options: Mapping[str, Any], p_tot: float, v0: float):
    from loadbayes.models.motor import MotorParams, steady_state

    missing = [k for k in (*_MOTOR_FIELDS, "f_m", "t0") if k not in values]
    if missing:
        raise ValueError(f"composite parameter set lacks {', '.join(missing)}")
    params = MotorParams(
        **{k: float(values[k]) for k in _MOTOR_FIELDS},
        a=float(values.get("a", 1.0)),
        b=float(values.get("b", 0.0)),
        c=float(values.get("c", 0.0)),
        f_hz=float(values.get("f_hz", options.get("f_hz") or 60.0)),
    )
    f_m = float(values["f_m"])
    if not (0.0 < f_m <= 1.0):
        raise ValueError(
            f"the motor's share f_m is {f_m:.6g}: a load's motor takes a share in (0, 1] of "
            "its power, so this parameter set is not a load a simulator can hold (refit "
            "with the shares kept in [0, 1]: fit composite --shares bounded)"
        )
    if not p_tot > 0:
        raise ValueError(f"the load draws P0 = {p_tot:.6g} MW: a composite load needs P0 > 0")
    p_m = f_m * p_tot
    try:
        op = steady_state(params, v_pu=v0, t0=float(values["t0"]))
    except ValueError as exc:
        raise ValueError(f"the motor has no steady state at v0 = {v0:.4g}: {exc}") from None
    # The rating follows from f_m p0 (never from the posterior's mva_m): see the module
    # docstring; so the motor draws f_m p0 at v0 in every export.
    mva = p_m / op.p
    return MotorPart(params, op.t0, mva, p_m, op.q * mva, op.slip, op.p, op.q)
