"""The library of documented induction motors (``MOTORS``), per unit on each motor's rating.

These are physics data (and :func:`motor_from_values`, a motor from a named parameter
set), used by the composite fit's multi-start and by the simulators.

Motors (``MOTORS``), per unit on each motor's own rating, 60 Hz
-----------------------------------------------------------------
``small_industrial`` and ``large_industrial``
    IEEE Task Force on Load Representation for Dynamic Performance, "Standard load
    models for power flow and dynamic performance simulation", IEEE Trans. Power
    Systems 10(3):1302-1313, 1995: the table of typical induction-motor data, motor
    types "small industrial motor" (Rs 0.031, Xs 0.10, Xm 3.2, Rr 0.018, Xr 0.18,
    H 0.7 s) and "large industrial motor" (Rs 0.013, Xs 0.067, Xm 3.8, Rr 0.009,
    Xr 0.17, H 1.5 s). The same values are widely reproduced (e.g. in Kundur's
    "Power System Stability and Control", ch. 7, and in PowerWorld's user-defined
    load-model example, against which they were cross-checked).
``krause_3hp`` and ``krause_2250hp``
    P. C. Krause, O. Wasynczuk, S. D. Sudhoff, "Analysis of Electric Machinery and
    Drive Systems", table of induction-machine parameters (section 6.10 in the 2nd
    ed.): 3 hp, 220 V, 4 pole, rs 0.435, Xls 0.754, XM 26.13, X'lr 0.754, r'r 0.816 ohm,
    J 0.089 kg m^2; 2250 hp, 2300 V, 4 pole, rs 0.029, Xls 0.226, XM 13.04,
    X'lr 0.226, r'r 0.022 ohm, J 63.87 kg m^2. Converted here with the book's base
    (VA base = rated hp x 746 W, Zb = V_LL^2 / VA base, H = J wbm^2 / (2 VA base),
    wbm = 2 wb / poles). Both have Xs = Xr, so the ``inverse`` closure recovers them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from loadbayes.models.motor import MotorParams

__all__ = ["MOTORS", "MOTOR_FIELDS", "motor_from_values"]


def _krause(
    name: str,
    hp: float,
    v_ll: float,
    rs: float,
    xls: float,
    xm: float,
    xlr: float,
    rr: float,
    j: float,
    poles: int = 4,
) -> MotorParams:
    s_base = hp * 746.0
    zb = v_ll**2 / s_base
    wbm = 2.0 * (2.0 * math.pi * 60.0) / poles
    return MotorParams(
        rs=rs / zb,
        xs=xls / zb,
        xm=xm / zb,
        rr=rr / zb,
        xr=xlr / zb,
        h_s=j * wbm**2 / (2.0 * s_base),
        name=name,
        f_hz=60.0,
    )


MOTORS: dict[str, MotorParams] = {
    "small_industrial": MotorParams(
        rs=0.031,
        xs=0.10,
        xm=3.2,
        rr=0.018,
        xr=0.18,
        h_s=0.7,
        name="IEEE TF 1995 small industrial motor",
        f_hz=60.0,
    ),
    "large_industrial": MotorParams(
        rs=0.013,
        xs=0.067,
        xm=3.8,
        rr=0.009,
        xr=0.17,
        h_s=1.5,
        name="IEEE TF 1995 large industrial motor",
        f_hz=60.0,
    ),
    "krause_3hp": _krause(
        "Krause 3 hp, 220 V", 3.0, 220.0, 0.435, 0.754, 26.13, 0.754, 0.816, 0.089
    ),
    "krause_2250hp": _krause(
        "Krause 2250 hp, 2300 V", 2250.0, 2300.0, 0.029, 0.226, 13.04, 0.226, 0.022, 63.87
    ),
}


#: The motor fields of a parameter set (the composite naming contract).
MOTOR_FIELDS = ("rs", "xs", "xm", "rr", "xr", "h_s")


def motor_from_values(values: Mapping[str, float]) -> MotorParams:
    """``MotorParams`` from a parameter set (``a, b, c`` default to 1, 0, 0; ``f_hz`` 60)."""
    return MotorParams(
        **{k: float(values[k]) for k in MOTOR_FIELDS},
        a=float(values.get("a", 1.0)),
        b=float(values.get("b", 0.0)),
        c=float(values.get("c", 0.0)),
        f_hz=float(values.get("f_hz", 60.0)),
        name="composite",
    )
