"""A composite load added to a bus of any ANDES case (``kundur/kundur_full.xlsx``, ...).

The same event as :func:`loadbayes.cases.andes.sim.simulate` (a ``PQ`` replaced by a
``ZIP``, a ``Motor3``, a ``BusFreq``, a three-phase ``Fault``), but on a bus of a case
file with its own generators, controls and loads, so the bus's frequency and angle move
as the machines swing. The load's P, Q are the ``ZIP``'s own equation plus the motor's
(the bus is meshed, there is no single feeder to meter); the fault is at the load bus.

Differences from the built-in case: the motor is sized at the case's ``Bus.v0`` (the
power-flow voltage is not known before), so ``f_m`` in the truth is the solved share, a
little off the one asked; ``v0`` is the solved voltage; no shunt.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

from loadbayes.cases.andes.sim import AndesEvent, achieved_depth, default_step, event_from_run
from loadbayes.cases.motor_sim import DEFAULT_T0
from loadbayes.export.andes.case import CompositeCase
from loadbayes.export.andes.conventions import andes_quiet, zip_fields
from loadbayes.export.andes.run import run_tds
from loadbayes.models.motor import MotorParams
from loadbayes.models.motor_library import MOTORS

__all__ = ["simulate_in_case"]

_IDS = {"pq": "lb_pq", "zip": "lb_zip", "motor": "lb_motor", "freq": "lb_freq"}


def _run(spec: dict[str, Any], xf: float, t_end_s: float) -> tuple[Any, Any]:
    import andes

    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp, andes_quiet():
        ss = andes.load(
            str(spec["path"]), setup=False, no_output=True, default_config=True, output_path=tmp
        )
        bus = spec["bus"]
        uid = ss.Bus.idx2uid(bus)
        vn, v_guess = float(ss.Bus.Vn.v[uid]), float(ss.Bus.v0.v[uid])
        case = CompositeCase.from_values(
            {**spec["values"], "v0": v_guess}, with_motor=True, base_mva=float(ss.config.mva)
        )
        s_pq = case.static_pq
        ss.add("PQ", {"idx": _IDS["pq"], "bus": bus, "Vn": vn, "p0": s_pq.real, "q0": s_pq.imag})
        ss.add("ZIP", {"idx": _IDS["zip"], "pq": _IDS["pq"], **zip_fields(case.a_p, case.a_q)})
        motor3 = {**case.motor3(), "Vn": vn}
        ss.add("Motor3", {"idx": _IDS["motor"], "bus": bus, **motor3})
        ss.add("BusFreq", {"idx": _IDS["freq"], "bus": bus, "fn": spec["f_hz"]})
        t_f = spec["fault_start_s"]
        ss.add(
            "Fault",
            {"idx": "lb_fault", "bus": bus, "tf": t_f, "tc": t_f + spec["fault_s"], "xf": xf},
        )
        ss.setup()
        raw = run_tds(
            ss,
            load_bus=bus,
            net_bus=None,
            t_end_s=t_end_s,
            step_s=spec["step_s"],
            zip_idx=_IDS["zip"],
            motor_idx=_IDS["motor"],
        )
    return raw, case


def simulate_in_case(
    case: str | Path,
    bus: Any,
    motor: MotorParams | str = "small_industrial",
    *,
    f_m: float = 0.4,
    p0: float = 1.0,
    q0: float = 0.3,
    zip_p: tuple[float, float, float] = (0.4, 0.3, 0.3),
    zip_q: tuple[float, float, float] = (0.5, 0.3, 0.2),
    t0: float = DEFAULT_T0,
    sag_depth: float = 0.3,
    fault_start_s: float = 0.5,
    fault_s: float = 0.1,
    t_end_s: float = 2.0,
    step_s: float | None = None,
    xf: float | None = None,
    depth_tol: float = 0.01,
    max_runs: int = 5,
) -> AndesEvent:
    """Simulate a composite load on bus ``bus`` of an ANDES case through a fault there.

    Parameters
    ----------
    case : str or Path
        An ANDES case file (``andes.get_case("kundur/kundur_full.xlsx")``, ...).
    bus : idx
        The bus that gets the load (its ANDES idx).
    motor, f_m, p0, q0, zip_p, zip_q, t0, sag_depth, fault_start_s, fault_s, t_end_s, step_s
        As in :func:`loadbayes.cases.andes.sim.simulate` (``p0, q0`` at the bus's
        ``v0`` in the case data).
    xf : float, optional
        First fault reactance tried (system p.u.); default from an assumed source
        reactance of 0.05 p.u. Then voltage-divider and secant steps on ``log xf``.
    depth_tol, max_runs : float, int
        Tolerance on the achieved sag depth and the most ANDES runs.

    Returns
    -------
    AndesEvent
        As :func:`~loadbayes.cases.andes.sim.simulate`; ``settings`` names the case and bus.
    """
    params = MOTORS[motor] if isinstance(motor, str) else motor
    if not (0 < sag_depth < 1 and 0 < fault_start_s and fault_s > 0):
        raise ValueError("need 0 < sag_depth < 1, fault_start_s > 0 and fault_s > 0")
    if not t_end_s > fault_start_s + fault_s:
        raise ValueError("the fault must end before t_end_s")
    values = {
        **{k: getattr(params, k) for k in ("rs", "xs", "xm", "rr", "xr", "h_s", "a", "b", "c")},
        **dict(zip(("a1", "a2", "a3"), zip_p, strict=True)),
        **dict(zip(("a4", "a5", "a6"), zip_q, strict=True)),
        **{"f_hz": params.f_hz, "p0": p0, "q0": q0, "f_m": f_m, "t0": t0},
    }
    spec = {
        "path": Path(case),
        "bus": bus,
        "values": values,
        "name": params.name,
        "f_hz": params.f_hz,
        "fault_start_s": fault_start_s,
        "fault_s": fault_s,
        "step_s": default_step(params) if step_s is None else float(step_s),
    }
    xf = 0.05 * (1 - sag_depth) / sag_depth if xf is None else float(xf)
    short = fault_start_s + fault_s + 2 * spec["step_s"]
    tried: list[tuple[float, float]] = []
    for run in range(max_runs):
        last = run == max_runs - 1
        raw, comp = _run(spec, xf, t_end_s if last else short)
        depth = achieved_depth(raw, spec)
        tried.append((math.log(xf), depth))
        if abs(depth - sag_depth) <= depth_tol or last:
            break
        if len(tried) == 1:
            # A voltage divider, depth = x_th / (x_th + xf), read off the first run.
            x_th = xf * depth / max(1 - depth, 1e-6)
            xf = x_th * (1 - sag_depth) / sag_depth
        else:
            (x1, d1), (x2, d2) = tried[-2], tried[-1]
            slope = (d2 - d1) / (x2 - x1) if x2 != x1 else -0.2
            xf = math.exp(x2 + (sag_depth - d2) / (slope if slope < 0 else -0.2))
        xf = min(max(xf, 1e-5, math.exp(tried[-1][0]) / 20), 1e3, math.exp(tried[-1][0]) * 20)
    if raw["t_s"].iloc[-1] < t_end_s - 1e-9:
        raw, comp = _run(spec, xf, t_end_s)
    event = event_from_run(raw, {**spec, "case": comp}, xf, sag_depth, t_end_s)
    for key in ("z_src", "z_feed", "v_src"):
        event.settings.pop(key)
    event.settings.update(
        case=str(spec["path"].name), fault_bus=bus, load_bus=bus, f_m_asked=f_m, runs=len(tried)
    )
    return event
