"""The package's composite load against an ANDES event, at ANDES's own time points.

:func:`reproduce` drives :func:`loadbayes.cases.composite_reference.predict` (the package's
motor simulator, SciPy DOP853) with the event's load-bus voltage, magnitude and angle,
on a grid ``refine`` times finer than ANDES's step, and reads it at ANDES's time points:
ANDES's points after a switching instant are offset by its 0.1 ms switching step, and
interpolating ANDES's coarser record instead would add an error of order
``(h / tau)^2 / 8`` on a fast mode ``tau`` that is neither program's.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from loadbayes.cases.andes.sim import AndesEvent
from loadbayes.cases.composite_reference import predict

__all__ = ["COMPARED", "max_errors", "reproduce"]

COMPARED = ("p", "q", "p_motor", "q_motor", "p_static", "q_static")
"""Columns compared (system p.u.)."""
SWITCH_EPS = 1e-4
"""ANDES's step just after a switching instant (``System.store_switch_times``)."""


def reproduce(
    event: AndesEvent,
    overrides: Mapping[str, float] | None = None,
    *,
    use_angle: bool = True,
    refine: int = 4,
) -> pd.DataFrame:
    """The package's prediction next to ANDES's record, at ANDES's time points.

    Parameters
    ----------
    event : AndesEvent
        From :func:`loadbayes.cases.andes.sim.simulate`.
    overrides : mapping, optional
        Parameter values replacing the truth's (for negative controls).
    use_angle : bool
        Drive the motor with the bus angle too (default), or with the magnitude only.
    refine : int
        The package's output grid is ANDES's step over ``refine``.

    Returns
    -------
    pandas.DataFrame
        ``t_s`` and, for each of :data:`COMPARED`, ``<col>_andes`` and ``<col>_lb``. The
        points in ``(t_switch, t_switch + max(step / refine, 0.1 ms)]`` after each switching
        instant are left out: there a linear reading of either grid straddles the step.
    """
    rec = event.record
    values = {**event.truth, **(overrides or {})}
    dt = float(event.settings["step_s"]) / refine
    angle = rec["angle_rad"] if use_angle else None
    pred = predict(values, rec["t_s"], rec["v"], angle, dt_s=dt)
    t = rec["t_s"].to_numpy()
    start = float(event.settings["fault_start_s"])
    switches = np.array([start, start + float(event.settings["fault_s"])])
    after = (t[:, None] > switches) & (t[:, None] <= switches + max(dt, SWITCH_EPS) + 1e-12)
    keep = ~after.any(axis=1)
    out = {"t_s": t[keep]}
    for col in COMPARED:
        out[f"{col}_andes"] = rec[col].to_numpy()[keep]
        out[f"{col}_lb"] = np.interp(t[keep], pred["t_s"], pred[col])
    return pd.DataFrame(out)


def max_errors(frame: pd.DataFrame, mva_m: float) -> dict[str, float]:
    """Largest absolute differences; ``p_motor, q_motor`` on the motor's rating.

    Parameters
    ----------
    frame : pandas.DataFrame
        From :func:`reproduce`.
    mva_m : float
        The motor's rating in system p.u.

    Returns
    -------
    dict
        One entry per column of :data:`COMPARED`.
    """
    errors = {}
    for col in COMPARED:
        diff = np.max(np.abs(frame[f"{col}_lb"] - frame[f"{col}_andes"]))
        errors[col] = float(diff / mva_m if col in ("p_motor", "q_motor") else diff)
    return errors
