"""ANDES ``Motor3`` and ``ZIP`` in loadbayes's conventions, and a power flow that converges.

The full convention map, with the test that proves each line, is in ``docs/andes.md``.
In short, for ANDES 2.0's ``Motor3`` (``andes/models/motor/motorbase.py``):

- Same third-order equations in seconds (``T'0 = (xr1 + xm) / (wb rr1)``, slip terms
  ``wb * slip``), same current and power equations, ``slip = 1 - w``.
- Frame: ANDES puts ``vd + j vq = j V e^{j theta}`` (``vd = -V sin theta``,
  ``vq = V cos theta``); loadbayes puts the steady terminal voltage on the d axis. The
  equations are invariant under a constant rotation, so the two differ by the fixed
  factor ``j e^{j theta0}``; a *moving* bus angle is seen by both as a frequency deviation.
- Bases: ``rs, xs, xm, rr1, xr1`` on the motor's rating ``Sn`` (ANDES converts them), ``Hm``
  on ``Sn`` (``M = 2 Hm``), but the torque coefficients ``c1, c2, c3`` are *not* converted:
  they are on the system base. So ``t0 (own base) = (c1 + c2 + c3) * Sb / Sn``.
- Torque: ANDES evaluates ``tm = aa + bb s + c2 s^2`` with ``aa = c1 + c2 + c3`` and
  ``bb = -c2 - 2 c3``. In ``w = 1 - s`` this is
  ``c2 w^2 + (2 c3 - c2) w + (c1 + c2 - c3)`` (Milano's book has ``c3 s^2``; ANDES 2.0's
  code has ``c2 s^2``, and the maps below follow the code, checked by the tests).
- Power flow: ANDES starts ``Motor3`` at ``slip = 1`` (standstill, for start-up studies)
  with ``vd = vq = Iq = 0``; ten Jacobian entries are then exactly zero and absent from
  the pattern ANDES's default KLU factorises once, which segfaults at the next iteration
  (docs/andes.md). With ``linsolve = 1`` (what an exported case carries) ANDES's own
  Newton converges from there; :func:`solve_power_flow` seeds the motor's variables at
  the steady state first and uses SciPy's solver, which raises instead of crashing.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from loadbayes.models.motor import MotorParams, steady_state

__all__ = [
    "andes_quiet",
    "motor3_fields",
    "motor_from_motor3",
    "seed_motor3",
    "solve_power_flow",
    "torque_from_andes",
    "torque_to_andes",
    "zip_fields",
]


@contextmanager
def andes_quiet() -> Iterator[None]:
    """Silence ANDES's logging and warnings inside the block (restored afterwards)."""
    import logging

    logger = logging.getLogger("andes")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            # ANDES's own deprecation and runtime warnings are not ours to act on; the
            # project runs pytest with filterwarnings=error, so they must not escape.
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.setLevel(level)


def torque_to_andes(t0_sys: float, a: float, b: float, c: float) -> tuple[float, float, float]:
    """ANDES ``(c1, c2, c3)`` for the load torque ``t0_sys (a w^2 + b w + c)``.

    Parameters
    ----------
    t0_sys : float
        Load torque at synchronous speed on the **system** base (``t0 * mva_m``).
    a, b, c : float
        loadbayes's torque shares (sum 1).

    Returns
    -------
    tuple of float
        ``c1 = t0 (c + (b - a)/2)``, ``c2 = t0 a``, ``c3 = t0 (a + b)/2``, the inverse of the
        map in the module docstring (so ``c1 + c2 + c3 = t0_sys``).
    """
    return t0_sys * (c + 0.5 * (b - a)), t0_sys * a, 0.5 * t0_sys * (a + b)


def torque_from_andes(c1: float, c2: float, c3: float) -> tuple[float, float, float, float]:
    """``(t0_sys, a, b, c)`` from ANDES's ``c1, c2, c3`` as ANDES 2.0 evaluates them."""
    aa = c1 + c2 + c3
    if not aa > 0:
        raise ValueError(f"Motor3 load torque c1 + c2 + c3 = {aa:g} is not a motoring load")
    return aa, c2 / aa, (2.0 * c3 - c2) / aa, (c1 + c2 - c3) / aa


def motor3_fields(
    motor: MotorParams, *, t0: float, mva_m: float, base_mva: float, vn_kv: float
) -> dict[str, float]:
    """``Motor3`` parameters (ANDES names) for a loadbayes motor.

    Parameters
    ----------
    motor : MotorParams
        Parameters on the motor's own rating (loadbayes convention).
    t0 : float
        Load torque at synchronous speed on the motor's own base.
    mva_m : float
        Motor rating in system p.u. (``Sn = mva_m * base_mva``).
    base_mva : float
        System base (ANDES ``System.config.mva``).
    vn_kv : float
        Rated voltage, equal to the bus's ``Vn`` so ANDES rescales nothing by voltage.

    Returns
    -------
    dict
        ``Sn, Vn, fn, rs, xs, xm, rr1, xr1, Hm, c1, c2, c3`` (``rr2, xr2`` are not used by
        ``Motor3``).
    """
    if not (mva_m > 0 and t0 > 0):
        raise ValueError(f"need mva_m > 0 and t0 > 0, got mva_m={mva_m!r}, t0={t0!r}")
    c1, c2, c3 = torque_to_andes(t0 * mva_m, motor.a, motor.b, motor.c)
    return {
        "Sn": mva_m * base_mva,
        "Vn": vn_kv,
        "fn": motor.f_hz,
        "rs": motor.rs,
        "xs": motor.xs,
        "xm": motor.xm,
        "rr1": motor.rr,
        "xr1": motor.xr,
        "Hm": motor.h_s,
        "c1": c1,
        "c2": c2,
        "c3": c3,
    }


def motor_from_motor3(fields: dict[str, Any], base_mva: float) -> tuple[MotorParams, float, float]:
    """Return loadbayes's ``(MotorParams, t0 own base, mva_m)`` for ``Motor3`` parameters."""
    t0_sys, a, b, c = torque_from_andes(fields["c1"], fields["c2"], fields["c3"])
    mva_m = float(fields["Sn"]) / base_mva
    params = MotorParams(
        rs=float(fields["rs"]),
        xs=float(fields["xs"]),
        xm=float(fields["xm"]),
        rr=float(fields["rr1"]),
        xr=float(fields["xr1"]),
        h_s=float(fields["Hm"]),
        a=a,
        b=b,
        c=c,
        f_hz=float(fields["fn"]),
        name="from ANDES Motor3",
    )
    return params, t0_sys / mva_m, mva_m


def zip_fields(a_p: tuple[float, float, float], a_q: tuple[float, float, float]) -> dict:
    """ANDES ``ZIP`` percentages from loadbayes shares ``(a1, a2, a3)``, ``(a4, a5, a6)``.

    loadbayes's ``a1, a2, a3`` are the Z, I, P shares of P referred to ``V/v0``; ANDES's
    ``ZIP`` refers ``kpz, kpi, kpp`` (percent) to the power-flow voltage of its ``PQ``. The
    two agree when the power flow puts the bus at ``v0`` (the export and the harness see
    to that).
    """
    for name, shares in (("P", a_p), ("Q", a_q)):
        if abs(sum(shares) - 1.0) > 1e-6:
            raise ValueError(f"ZIP shares of {name} must sum to 1, got {sum(shares)!r}")
    return {
        "kpz": 100.0 * a_p[0],
        "kpi": 100.0 * a_p[1],
        "kpp": 100.0 * a_p[2],
        "kqz": 100.0 * a_q[0],
        "kqi": 100.0 * a_q[1],
        "kqp": 100.0 * a_q[2],
    }


def seed_motor3(system: Any, kind: str = "Motor3") -> None:
    """Put every online ``Motor3`` at loadbayes's steady state before ANDES's Newton steps.

    Call after ``PFlow.init()`` (which sets ANDES's start-up guess ``slip = 1``). The guess
    uses each motor's bus ``v0``/``a0`` parameters; Newton then polishes it to the solved
    bus voltage in a few iterations. ``kind="Motor5"`` seeds the fifth-order motors from
    their first cage's third-order steady state, the second cage's EMF at the first's.
    """
    m = getattr(system, kind)
    base = float(system.config.mva)
    bus_uid = system.Bus.idx2uid(list(m.bus.v))
    for k in range(m.n):
        if m.u.v[k] != 1:
            continue
        # ANDES has converted the impedances to the system base in place (``z=True``);
        # ``.vin`` keeps the values as input, on the motor's own base.
        names = ("Sn", "fn", "rs", "xs", "xm", "rr1", "xr1", "c1", "c2", "c3")
        fields = {name: float(getattr(m, name).vin[k]) for name in names}
        fields["Hm"] = 1.0  # inertia does not enter the steady state
        params, t0, mva_m = motor_from_motor3(fields, base)
        v = float(system.Bus.v0.v[bus_uid[k]])
        theta = float(system.Bus.a0.v[bus_uid[k]])
        op = steady_state(params, v_pu=v, t0=t0)
        rot = 1j * complex(math.cos(theta), math.sin(theta))
        e, i, u = (rot * complex(op.ed, op.eq), rot * complex(op.id, op.iq) * mva_m, rot * v)
        values = {
            "slip": op.slip,
            "e1d": e.real,
            "e1q": e.imag,
            "Id": i.real,
            "Iq": i.imag,
            "vd": u.real,
            "vq": u.imag,
            "p": op.p * mva_m,
            "q": op.q * mva_m,
            "te": op.te * mva_m,
            "tm": op.te * mva_m,
        }
        if kind == "Motor5":
            values.update(e2d=e.real, e2q=e.imag)
        for name, value in values.items():
            getattr(m, name).v[k] = value


def solve_power_flow(system: Any) -> None:
    """Run ANDES's power flow with every ``Motor3`` seeded at its steady state.

    Parameters
    ----------
    system : andes.System
        A set-up system (``andes.load(..., setup=True)`` or ``System.setup()``).

    Raises
    ------
    RuntimeError
        If the power flow does not converge.

    Notes
    -----
    The SciPy sparse solver replaces KLU for the power flow, so that a diverging
    iteration raises instead of crashing the interpreter.
    """
    from andes.linsolvers.solverbase import Solver

    pflow = system.PFlow
    pflow.solver = Solver(sparselib="spsolve")
    original = pflow.init

    def init() -> Any:
        out = original()
        for kind in ("Motor3", "Motor5"):
            if kind in system.models and getattr(system, kind).n:
                seed_motor3(system, kind)
        return out

    pflow.init = init
    try:
        with andes_quiet():
            ok = pflow.run()
    finally:
        del pflow.init  # back to the class's method
    if not ok:
        raise RuntimeError("ANDES power flow did not converge (with Motor3 seeded)")
