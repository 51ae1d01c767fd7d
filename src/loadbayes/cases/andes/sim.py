"""ANDES as the independent simulator: a ZIP load and a ``Motor3`` on one bus, under a fault.

The case is :mod:`loadbayes.export.andes.case` (infinite bus, network bus, load bus; the
power flow puts the load bus at ``v0`` with the motor drawing the share ``f_m`` of
``p0``), plus a ``BusFreq`` at the load bus and a three-phase ``Fault`` at the network bus
whose reactance ``xf`` is found by a few short runs so that the deepest load-bus voltage
during the fault is ``(1 - sag_depth) v0``. ANDES integrates the event (implicit
trapezoid, fixed step).

The record (:class:`AndesEvent`) has, at ANDES's own time points, the load bus's
``t_s, v, angle_rad, f`` (Hz, from ANDES's ``BusFreq``), the load's ``p, q`` (system p.u.,
load convention, computed from the feeder's current so that they are what a meter at the
bus would see), the motor's own ``p_motor, q_motor`` (ANDES's ``Motor3.p, q``), states
``slip, e1d, e1q`` (ANDES frame) and ``ed, eq, w`` (loadbayes's frame), torques
``tm, te`` (system base), and
``p_static, q_static = p - p_motor, q - q_motor``. :attr:`AndesEvent.truth` holds the
parameters in loadbayes's naming contract (``docs/andes.md``). ANDES runs in a temporary
output folder with its logging and warnings silenced.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize

from loadbayes.cases.motor_sim import DEFAULT_T0
from loadbayes.export.andes.case import Z_FEED, CompositeCase, add_composite
from loadbayes.export.andes.conventions import andes_quiet
from loadbayes.export.andes.run import run_tds
from loadbayes.models.motor import MotorParams, steady_state
from loadbayes.models.motor_library import MOTORS

__all__ = [
    "AndesEvent",
    "achieved_depth",
    "default_step",
    "event_from_run",
    "fault_reactance_guess",
    "second_cage",
    "simulate",
]


@dataclass(frozen=True)
class AndesEvent:
    """One simulated event: ANDES's record, the truth and the settings.

    Attributes
    ----------
    record : pandas.DataFrame
        Columns ``t_s, v, angle_rad, f, p, q, p_motor, q_motor, p_static, q_static, slip,
        e1d, e1q, tm, te, ed, eq, w`` at ANDES's time points (module docstring).
    truth : dict
        Parameters in the naming contract: ``p0, q0, v0, a1..a6, f_m, rs, xs, xm, rr, xr,
        h_s, a, b, c, t0, mva_m, q_c, x_prime, x_open, t_prime_s, f_hz``.
    settings : dict
        Network, fault and solver settings, the achieved sag depth and the ANDES version.
    motor : MotorParams
        The motor (own base).
    """

    record: pd.DataFrame
    truth: dict[str, float]
    settings: dict[str, Any]
    motor: MotorParams = field(repr=False)

    def resample(self, rate_hz: float) -> pd.DataFrame:
        """The record on a uniform grid ``k / rate_hz`` (linear interpolation).

        Parameters
        ----------
        rate_hz : float
            Samples per second; ANDES's step should be no coarser than ``1 / rate_hz``.

        Returns
        -------
        pandas.DataFrame
            Same columns; the grid covers ``[0, t_end]``.
        """
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz!r}")
        t = self.record["t_s"].to_numpy()
        grid = np.arange(int(math.floor(t[-1] * rate_hz + 1e-9)) + 1) / rate_hz
        cols = {c: np.interp(grid, t, self.record[c].to_numpy()) for c in self.record.columns}
        return pd.DataFrame(cols, columns=list(self.record.columns))


def default_step(motor: MotorParams) -> float:
    """ANDES's step for a motor: ``1/(600 k)`` s, at most a sixteenth of its fastest mode.

    The fastest mode of the third-order motor under a fault is the short-circuit transient
    ``T' X' / X`` (40-70 ms for the IEEE motors and Krause's 2250 hp, 5 ms for Krause's
    3 hp). ANDES's implicit trapezoid missed Krause's 3 hp in a 10% sag by 1.4e-3 of its
    rating at a third of that mode, and in a 60% sag by 1e-3 at a ninth; at a sixteenth
    the worst seen is 5.4e-4, inside the 1e-3 the tests allow (docs/andes.md). ``k`` is
    an integer so that 60, 120 and 600 samples/s fall on ANDES's points.
    """
    fastest = motor.tp_s * motor.xp / motor.x
    return 1.0 / (600.0 * math.ceil((1.0 / 600.0) / (fastest / 16.0)))


def second_cage(motor: MotorParams, cage2: tuple[float, float]) -> dict[str, float]:
    """ANDES ``Motor5``'s second cage on ``motor``: X'', T''0 (s) and a step for it.

    ANDES 2.0 (``motor5.py``): ``x'' = xs + xr1 xr2 xm / (xr1 xr2 + xr1 xm + xr2 xm)`` and
    ``T''0 = (xr2 + xr1 xm / (xr1 + xm)) / (wb rr2)``. Its first cage keeps Motor3's
    ``x' `` and ``T'0 = (xr1 + xm) / (wb rr1)``; as ``T''0`` goes to 0 the second cage's
    EMF follows ``E' - j (x' - x'') I`` and the model is Motor3's. The step: ``1/(600 k)``
    s, at most a sixth of the short-circuit mode ``T''0 x'' / x'`` (a mode shorter than
    the samples' interval, whose error no sample at 60/s resolves).
    """
    rr2, xr2 = cage2
    xs, xm, xr1 = motor.xs, motor.xm, motor.xr
    wb = 2.0 * math.pi * motor.f_hz
    x2 = xs + xr1 * xr2 * xm / (xr1 * xr2 + xr1 * xm + xr2 * xm)
    t20 = (xr2 + xr1 * xm / (xr1 + xm)) / (wb * rr2)
    fastest = t20 * x2 / motor.xp
    step = 1.0 / (600.0 * math.ceil((1.0 / 600.0) / (fastest / 6.0)))
    return {"x_second": x2, "t_second_s": t20, "step_s": step}


def fault_reactance_guess(depth: float, case: CompositeCase, fault_s: float) -> float:
    """Fault reactance at bus 2 that drops the load bus to ``(1 - depth) v0`` by the fault's end.

    A linear-circuit estimate (nodal equations of buses 2 and 3; the static load as its
    pre-fault admittance, the motor as its transient EMF behind its transient impedance
    ``(Rs + j X') / mva_m``, its EMF moving from ``E'0`` towards ``(1 - depth) E'0`` with
    the short-circuit time constant ``T' X' / X`` over the fault); :func:`simulate` then
    corrects it on ANDES's own result.

    Returns
    -------
    float
        ``xf`` in system p.u., within ``[1e-4, 1e3]``.
    """
    y3 = (case.static_pq - 1j * case.q_c).conjugate() / case.v0**2
    i_m = 0j
    if case.motor is not None:
        op = steady_state(case.motor, v_pu=case.v0, t0=case.t0)
        z_m = complex(case.motor.rs, case.motor.xp) / case.mva_m
        decay = math.exp(-fault_s / (case.motor.tp_s * case.motor.xp / case.motor.x))
        emf = complex(op.ed, op.eq) * ((1.0 - depth) + depth * decay)
        y3, i_m = y3 + 1.0 / z_m, emf / z_m
    y_feed, y_src = 1.0 / Z_FEED, 1.0 / case.z_src

    def gap(log_xf: float) -> float:
        y2 = y_src + y_feed + 1.0 / (1j * math.exp(log_xf))
        nodal = np.array([[y2, -y_feed], [-y_feed, y_feed + y3]])
        v3 = np.linalg.solve(nodal, np.array([case.v_src * y_src, i_m]))[1]
        return abs(v3) - (1.0 - depth) * case.v0

    lo, hi = math.log(1e-4), math.log(1e3)
    if gap(lo) >= 0:
        return 1e-4
    if gap(hi) <= 0:
        return 1e3
    return math.exp(optimize.brentq(gap, lo, hi, xtol=1e-10))


def _run(spec: dict[str, Any], xf: float, t_end_s: float) -> pd.DataFrame:
    import andes

    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp, andes_quiet():
        ss = andes.System(no_output=True, default_config=True, output_path=tmp)
        ids = add_composite(ss, spec["case"])
        ss.add("BusFreq", {"idx": 1, "bus": ids["load_bus"], "fn": spec["f_hz"]})
        t_f = spec["fault_start_s"]
        ss.add(
            "Fault",
            {"idx": 1, "bus": ids["net_bus"], "tf": t_f, "tc": t_f + spec["fault_s"], "xf": xf},
        )
        ss.setup()
        return run_tds(
            ss,
            load_bus=ids["load_bus"],
            net_bus=ids["net_bus"],
            t_end_s=t_end_s,
            step_s=spec["step_s"],
        )


def achieved_depth(raw: pd.DataFrame, spec: dict[str, Any]) -> float:
    """``1 - min V / V(0)`` at the load bus over the fault (``spec``: its start and length)."""
    t0, t1 = spec["fault_start_s"], spec["fault_start_s"] + spec["fault_s"]
    t, v = raw["t_s"].to_numpy(), raw["v"].to_numpy()
    return float(1.0 - v[(t > t0) & (t < t1)].min() / v[0])


def simulate(
    motor: MotorParams | str = "small_industrial",
    *,
    f_m: float = 0.4,
    p0: float = 1.0,
    q0: float = 0.3,
    zip_p: tuple[float, float, float] = (0.4, 0.3, 0.3),
    zip_q: tuple[float, float, float] = (0.5, 0.3, 0.2),
    t0: float = DEFAULT_T0,
    q_c: float = 0.0,
    v0: float = 1.0,
    sag_depth: float = 0.3,
    fault_start_s: float = 0.5,
    fault_s: float = 0.1,
    t_end_s: float = 2.0,
    step_s: float | None = None,
    z_src: complex = complex(0.01, 0.1),
    base_mva: float = 100.0,
    depth_tol: float = 0.01,
    max_runs: int = 4,
    cage2: tuple[float, float] | None = None,
) -> AndesEvent:
    """Simulate a composite load (ZIP + ``Motor3``) through a fault in ANDES.

    Parameters
    ----------
    motor : MotorParams or str
        The motor (own base) or a key of :data:`loadbayes.models.motor_library.MOTORS`.
    f_m : float
        Motor's share of the initial active power, in (0, 1].
    p0, q0 : float
        Total load P, Q at ``v0`` (system p.u.; ``q0`` includes the motor and the shunt).
    zip_p, zip_q : tuple of float
        Static shares ``(a1, a2, a3)`` and ``(a4, a5, a6)`` (Z, I, P; each sums to 1).
    t0 : float
        Motor's load torque at synchronous speed, own base (its loading).
    q_c : float
        Shunt capacitor's reactive supply at ``v0`` (system p.u.); 0 for none.
    v0 : float
        Pre-fault load-bus voltage (p.u.).
    sag_depth : float
        Target depth of the sag: the lowest load-bus voltage during the fault is
        ``(1 - sag_depth) v0`` to within ``depth_tol`` (achieved value in ``settings``).
    fault_start_s, fault_s, t_end_s : float
        Fault time, its duration and the record's end (s).
    step_s : float, optional
        ANDES's fixed integration step (s); default :func:`default_step`.
    z_src : complex
        Source impedance from the infinite bus to the fault bus (system p.u.).
    base_mva : float
        System base.
    depth_tol : float
        Tolerance on the achieved sag depth.
    max_runs : int
        Most ANDES runs to reach the depth (secant steps on ``log xf``).
    cage2 : tuple of float, optional
        ``(rr2, xr2)`` (motor base): the motor is ANDES's fifth-order ``Motor5``, whose
        first cage is ``motor``'s rotor (:func:`second_cage`); the default step then
        resolves the second cage's short-circuit mode.

    Returns
    -------
    AndesEvent
        Record, truth, settings and motor.

    Raises
    ------
    ValueError
        For parameters out of range, or a loading beyond the motor's breakdown torque.
    RuntimeError
        If ANDES fails (power flow or time-domain simulation).
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
        "f_hz": params.f_hz,
        "p0": p0,
        "q0": q0,
        "v0": v0,
        "f_m": f_m,
        "t0": t0,
        "q_c": q_c,
    }
    case = CompositeCase.from_values(values, with_motor=True, base_mva=base_mva, z_src=z_src)
    if cage2 is not None:
        case = replace(case, cage2=(float(cage2[0]), float(cage2[1])))
        if step_s is None:
            step_s = min(default_step(params), second_cage(params, cage2)["step_s"])
    spec = {
        "case": case,
        "name": params.name,
        "f_hz": params.f_hz,
        "fault_start_s": fault_start_s,
        "fault_s": fault_s,
        "step_s": default_step(params) if step_s is None else float(step_s),
    }
    xf = fault_reactance_guess(sag_depth, case, fault_s)
    # First the whole event; if its sag misses the target, secant steps on log xf with
    # runs that stop at the fault's end, then the whole event again.
    raw = _run(spec, xf, t_end_s)
    tried = [(math.log(xf), achieved_depth(raw, spec))]
    runs = 1
    while abs(tried[-1][1] - sag_depth) > depth_tol and runs < max_runs:
        if len(tried) == 1:
            # Depth falls with xf roughly as 1 / (1 + xf / x_th): a step in log xf.
            d = tried[0][1]
            xf *= math.exp((d - sag_depth) / max(d * (1 - d), 0.05))
        else:
            (x1, d1), (x2, d2) = tried[-2], tried[-1]
            slope = (d2 - d1) / (x2 - x1) if x2 != x1 else -0.2
            xf = math.exp(x2 + (sag_depth - d2) / (slope if slope < 0 else -0.2))
        xf = min(max(xf, 1e-4, math.exp(tried[-1][0]) / 10), 1e3, math.exp(tried[-1][0]) * 10)
        last = runs == max_runs - 1
        raw = _run(spec, xf, t_end_s if last else fault_start_s + fault_s + 2 * spec["step_s"])
        tried.append((math.log(xf), achieved_depth(raw, spec)))
        runs += 1
    if raw["t_s"].iloc[-1] < t_end_s - 1e-9:
        raw = _run(spec, xf, t_end_s)
    return event_from_run(raw, spec, xf, sag_depth, t_end_s)


def event_from_run(raw, spec, xf, target, t_end_s) -> AndesEvent:
    """Build the :class:`AndesEvent` (record, truth, settings) from a run's record."""
    import andes

    case: CompositeCase = spec["case"]
    params = case.motor
    cols = ["t_s", "v", "angle_rad", "f", "p", "q", "p_motor", "q_motor", "p_static"]
    cols += ["q_static", "slip", "e1d", "e1q", "tm", "te"]
    record = raw[cols].copy()
    # The states in loadbayes's frame: ANDES's vd + j vq is j V e^{j theta}; loadbayes
    # puts the initial terminal voltage on the d axis (docs/andes.md, "axes").
    e = (raw["e1d"] + 1j * raw["e1q"]).to_numpy() * np.exp(-1j * (np.pi / 2 + raw["angle_rad"][0]))
    record["ed"], record["eq"], record["w"] = e.real, e.imag, 1.0 - raw["slip"].to_numpy()
    p0, q0 = float(record["p"].iloc[0]), float(record["q"].iloc[0])
    (a1, a2, a3), (a4, a5, a6) = case.a_p, case.a_q
    truth = {
        "p0": p0,
        "q0": q0,
        "v0": float(record["v"].iloc[0]),
        "a1": a1,
        "a2": a2,
        "a3": a3,
        "a4": a4,
        "a5": a5,
        "a6": a6,
        "f_m": float(record["p_motor"].iloc[0]) / p0,
        "rs": params.rs,
        "xs": params.xs,
        "xm": params.xm,
        "rr": params.rr,
        "xr": params.xr,
        "h_s": params.h_s,
        "a": params.a,
        "b": params.b,
        "c": params.c,
        "t0": case.t0,
        "mva_m": case.mva_m,
        "q_c": case.q_c,
        "x_prime": params.xp,
        "x_open": params.x,
        "t_prime_s": params.tp_s,
        "f_hz": params.f_hz,
    }
    if case.cage2 is not None:
        cage = second_cage(params, case.cage2)
        truth.update(x_second=cage["x_second"], t_second_s=cage["t_second_s"])
    depth = achieved_depth(raw, spec)
    settings = {
        "simulator": f"ANDES {andes.__version__}",
        "motor_name": spec["name"],
        "base_mva": case.base_mva,
        "z_src": [case.z_src.real, case.z_src.imag],
        "z_feed": [Z_FEED.real, Z_FEED.imag],
        "v_src": [abs(case.v_src), float(np.angle(case.v_src))],
        "fault_bus": 2,
        "load_bus": 3,
        "fault_start_s": spec["fault_start_s"],
        "fault_s": spec["fault_s"],
        "xf": xf,
        "sag_depth_target": target,
        "sag_depth": depth,
        "step_s": spec["step_s"],
        "t_end_s": t_end_s,
        "integrator": "ANDES TDS, implicit trapezoid, fixed step",
        "motor3": case.motor3(),
        "motor_model": "Motor3" if case.cage2 is None else "Motor5",
        "cage2": None if case.cage2 is None else list(case.cage2),
    }
    record.attrs.update({"truth": truth, "settings": settings})
    return AndesEvent(record=record, truth=truth, settings=settings, motor=params)
