"""Run an ANDES system with a composite load: power flow, time domain, the load's record.

:func:`run_tds` is shared by the harness (:mod:`loadbayes.cases.andes.sim`), a load in
another case (:mod:`loadbayes.cases.andes.grid`) and the export's round trip.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from loadbayes.export.andes.conventions import andes_quiet, solve_power_flow

__all__ = ["TDS_TOL", "run_tds"]

TDS_TOL = 1e-9
"""ANDES's Newton tolerance in the time domain (its default, 1e-4, lets the load's P, Q
from the feeder current miss the device equations by 2e-4: the feeder's admittance, 50
p.u., multiplies any voltage error)."""


def run_tds(
    system: Any,
    *,
    load_bus: Any,
    net_bus: Any | None,
    t_end_s: float,
    step_s: float,
    zip_idx: Any = None,
    motor_idx: Any = None,
) -> pd.DataFrame:
    """Power flow (``Motor3`` seeded) and time-domain run of a set-up ANDES system.

    Parameters
    ----------
    system : andes.System
        Set up, not yet solved; its load bus is fed by one line from ``net_bus`` (no
        line charging), as in :mod:`loadbayes.export.andes.case` or an exported case.
    load_bus, net_bus : idx
        The load bus and the bus feeding it. With ``net_bus=None`` (a load bus inside a
        meshed network) the static part's P, Q are read from the ``ZIP`` device's own
        equation (``zip_idx``) instead of the feeder current.
    t_end_s, step_s : float
        End time and ANDES's fixed step (s).
    zip_idx, motor_idx : idx, optional
        The load's ``ZIP`` and ``Motor3``; default the first of each.

    Returns
    -------
    pandas.DataFrame
        ``t_s, v, angle_rad, p, q`` (load bus; P, Q from the feeder's current, system
        p.u., load convention), then with a ``Motor3`` ``p_motor, q_motor, p_static,
        q_static, slip, e1d, e1q, tm, te`` and with a ``BusFreq`` ``f`` (Hz). A time that
        ANDES records twice (a switching instant) keeps its later record.

    Raises
    ------
    RuntimeError
        If the power flow or the time-domain run fails.
    """
    from andes.linsolvers.solverbase import Solver

    solve_power_flow(system)
    cfg = system.TDS.config
    cfg.tf, cfg.fixt, cfg.tstep, cfg.no_tqdm, cfg.criteria = t_end_s, 1, step_s, 1, 0
    cfg.tol = TDS_TOL
    system.TDS.solver = Solver(sparselib="spsolve")  # raise, never segfault, on a NaN
    with andes_quiet():
        ok = system.TDS.run()
    ts = system.dae.ts
    if not ok or ts.t[-1] < t_end_s - 1e-9:
        raise RuntimeError("ANDES time-domain simulation failed")
    y, x = np.asarray(ts.y), np.asarray(ts.x)

    def col(var: Any, k: int = 0, states: bool = False) -> np.ndarray:
        return (x if states else y)[:, int(var.a[k])].copy()

    load = system.Bus.idx2uid(load_bus)
    v_load = col(system.Bus.v, load) * np.exp(1j * col(system.Bus.a, load))
    # The load's motor: its Motor3, or (a case with none) its fifth-order Motor5.
    m = system.Motor5 if not system.Motor3.n and "Motor5" in system.models else system.Motor3
    km = 0 if motor_idx is None else m.idx2uid(motor_idx)
    if net_bus is not None:
        lines = system.Line
        pairs = list(zip(lines.bus1.v, lines.bus2.v, strict=True))
        k = pairs.index((net_bus, load_bus))
        if lines.b.v[k] or lines.b1.v[k] or lines.b2.v[k]:
            raise ValueError("the feeder of the load bus must have no line charging")
        z = complex(lines.r.v[k], lines.x.v[k])
        net = system.Bus.idx2uid(net_bus)
        v_net = col(system.Bus.v, net) * np.exp(1j * col(system.Bus.a, net))
        s = v_load * np.conj((v_net - v_load) / z)  # into the load bus
    else:
        zp = system.ZIP
        kz = 0 if zip_idx is None else zp.idx2uid(zip_idx)
        vm = np.abs(v_load)
        s = zp.pp0.v[kz] + zp.pi0.v[kz] * vm + zp.pz0.v[kz] * vm**2
        s = s + 1j * (zp.qp0.v[kz] + zp.qi0.v[kz] * vm + zp.qz0.v[kz] * vm**2)
        if m.n:
            s = s + col(m.p, km) + 1j * col(m.q, km)
    out = {
        "t_s": np.asarray(ts.t, dtype=float).copy(),
        "v": np.abs(v_load),
        "angle_rad": col(system.Bus.a, load),
        "p": s.real,
        "q": s.imag,
    }
    if m.n:
        out.update(p_motor=col(m.p, km), q_motor=col(m.q, km))
        out.update(p_static=s.real - out["p_motor"], q_static=s.imag - out["q_motor"])
        out.update(slip=col(m.slip, km, True), e1d=col(m.e1d, km, True))
        out.update(e1q=col(m.e1q, km, True), tm=col(m.tm, km), te=col(m.te, km))
    at_bus = [k for k, b in enumerate(system.BusFreq.bus.v) if b == load_bus]
    if at_bus:
        out["f"] = col(system.BusFreq.f, at_bus[0]) * float(system.BusFreq.fn.v[at_bus[0]])
    keep = np.append(np.diff(out["t_s"]) > 0, True)
    return pd.DataFrame({key: value[keep] for key, value in out.items()})
