"""ANDES as the independent simulator: a ZIP load and a ``Motor3`` on one bus, under a fault.

The case is built in code (ANDES 2.0), four buses in a row::

    bus 1 (Slack, infinite) --Z_src-- bus 2 (Fault) --Z_feed-- bus 3 (PQ -> ZIP, Motor3, BusFreq)

The Slack's voltage is set by Ohm's law so that the power flow puts bus 3 at ``v0`` (the
ZIP's reference voltage in both programs); the motor is sized so that it draws the share
``f_m`` of ``p0`` there. A three-phase fault at bus 2 with reactance ``xf`` (found by a few
short runs so that the deepest load-bus voltage during the fault is ``1 - sag_depth``
times ``v0``) makes the event. ANDES integrates it (implicit trapezoid, fixed step).

The record (:class:`AndesEvent`) has, at ANDES's own time points, the load bus's
``t_s, v, angle_rad, f`` (Hz, from ANDES's ``BusFreq``), the load's ``p, q`` (system p.u.,
load convention, computed from the feeder's current so that they are what a meter at the
bus would see), the motor's own ``p_motor, q_motor`` (ANDES's ``Motor3.p, q``) and states
``slip, e1d, e1q`` (ANDES frame), its torques ``tm, te`` (system base), and
``p_static, q_static = p - p_motor, q - q_motor``.
:attr:`AndesEvent.truth` holds the parameters in loadbayes's naming contract
(``docs/andes.md``). ANDES runs in a temporary output folder with its logging silenced.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize

from loadbayes.cases.andes_motor3 import (
    andes_quiet,
    motor3_fields,
    solve_power_flow,
    zip_fields,
)
from loadbayes.cases.motor_sim import DEFAULT_T0, MOTORS
from loadbayes.models.motor import MotorParams, steady_state

__all__ = ["AndesEvent", "fault_reactance_guess", "simulate"]

VN_KV = 110.0
"""Nominal voltage of every bus and device (kV); equal everywhere so ANDES rescales nothing."""
Z_FEED = complex(0.002, 0.02)
"""Feeder impedance between the fault bus and the load bus (system p.u.)."""


@dataclass(frozen=True)
class AndesEvent:
    """One simulated event: ANDES's record, the truth and the settings.

    Attributes
    ----------
    record : pandas.DataFrame
        Columns ``t_s, v, angle_rad, f, p, q, p_motor, q_motor, p_static, q_static, slip,
        e1d, e1q, tm, te`` at ANDES's time points (module docstring).
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


def _load_side(motor: MotorParams, t0: float, mva_m: float, v0: float, s_static: complex):
    # Norton equivalent of the load bus just after a fault: the static load as its
    # pre-fault admittance, the motor as E' behind (Rs + j X') / mva_m (system base).
    op = steady_state(motor, v_pu=v0, t0=t0)
    z_m = complex(motor.rs, motor.xp) / mva_m
    y_load = s_static.conjugate() / v0**2 + 1.0 / z_m
    return complex(op.ed, op.eq) / z_m, y_load


def fault_reactance_guess(
    depth: float,
    *,
    v_src: complex,
    z_src: complex,
    motor: MotorParams,
    t0: float,
    mva_m: float,
    v0: float,
    s_static: complex,
) -> float:
    """Fault reactance that drops the load bus to ``(1 - depth) v0`` at the fault instant.

    A linear-circuit estimate (Ohm's and Kirchhoff's laws on the four-bus case, static
    load as its pre-fault admittance, motor as its transient EMF behind its transient
    impedance); :func:`simulate` then corrects it on ANDES's own result.

    Returns
    -------
    float
        ``xf`` in system p.u., within ``[1e-4, 1e3]``.
    """
    i_m, y3 = _load_side(motor, t0, mva_m, v0, s_static)

    def v3(xf: float) -> float:
        y2 = 1.0 / z_src + 1.0 / (1j * xf) + 1.0 / Z_FEED
        # Nodal equations of buses 2 and 3 (source and motor as current injections).
        a = np.array([[y2, -1.0 / Z_FEED], [-1.0 / Z_FEED, 1.0 / Z_FEED + y3]])
        rhs = np.array([v_src / z_src, i_m])
        return abs(np.linalg.solve(a, rhs)[1])

    target = (1.0 - depth) * v0

    def gap(log_xf: float) -> float:
        return v3(math.exp(log_xf)) - target

    lo, hi = math.log(1e-4), math.log(1e3)
    if gap(lo) >= 0:
        return 1e-4
    if gap(hi) <= 0:
        return 1e3
    return math.exp(optimize.brentq(gap, lo, hi, xtol=1e-10))


def _run(spec: dict[str, Any], xf: float, t_end_s: float) -> dict[str, np.ndarray]:
    import andes

    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp, andes_quiet():
        ss = andes.System(no_output=True, default_config=True, output_path=tmp)
        ss.config.mva = spec["base_mva"]
        for idx, name in ((1, "source"), (2, "fault"), (3, "load")):
            ss.add("Bus", {"idx": idx, "name": name, "Vn": VN_KV, "v0": spec["v0"]})
        v_src = spec["v_src"]
        ss.add(
            "Slack",
            {"idx": 1, "bus": 1, "Vn": VN_KV, "Sn": spec["base_mva"], "v0": abs(v_src),
             "a0": float(np.angle(v_src))},
        )  # fmt: skip
        for idx, (b1, b2, z) in enumerate(((1, 2, spec["z_src"]), (2, 3, Z_FEED)), start=1):
            ss.add(
                "Line",
                {"idx": idx, "bus1": b1, "bus2": b2, "r": z.real, "x": z.imag, "b": 0.0,
                 "Vn1": VN_KV, "Vn2": VN_KV, "Sn": spec["base_mva"]},
            )  # fmt: skip
        s_pq = spec["s_static"] + 1j * spec["q_c"]  # the ZIP's own part, before the shunt
        ss.add("PQ", {"idx": 1, "bus": 3, "Vn": VN_KV, "p0": s_pq.real, "q0": s_pq.imag})
        ss.add("ZIP", {"idx": 1, "pq": 1, **zip_fields(spec["a_p"], spec["a_q"])})
        if spec["q_c"]:
            b = spec["q_c"] / spec["v0"] ** 2
            ss.add("Shunt", {"idx": 1, "bus": 3, "Vn": VN_KV, "Sn": spec["base_mva"], "b": b})
        ss.add("Motor3", {"idx": 1, "bus": 3, **spec["motor3"]})
        ss.add("BusFreq", {"idx": 1, "bus": 3, "fn": spec["motor"].f_hz})
        t_f = spec["fault_start_s"]
        ss.add("Fault", {"idx": 1, "bus": 2, "tf": t_f, "tc": t_f + spec["fault_s"], "xf": xf})
        ss.setup()
        solve_power_flow(ss)
        ss.TDS.config.tf = t_end_s
        ss.TDS.config.fixt = 1
        ss.TDS.config.tstep = spec["step_s"]
        ss.TDS.config.no_tqdm = 1
        ss.TDS.config.criteria = 0
        ok = ss.TDS.run()
        if not ok or ss.dae.ts.t[-1] < t_end_s - 1e-9:
            raise RuntimeError(f"ANDES time-domain simulation failed (xf={xf:g})")
        ts = ss.dae.ts
        y = np.asarray(ts.y)
        x = np.asarray(ts.x)

        def col(var: Any, k: int = 0, states: bool = False) -> np.ndarray:
            return (x if states else y)[:, int(var.a[k])].copy()

        out = {
            "t": np.asarray(ts.t, dtype=float).copy(),
            "v2": col(ss.Bus.v, 1),
            "a2": col(ss.Bus.a, 1),
            "v3": col(ss.Bus.v, 2),
            "a3": col(ss.Bus.a, 2),
            "f": col(ss.BusFreq.f),
            "p_motor": col(ss.Motor3.p),
            "q_motor": col(ss.Motor3.q),
            "slip": col(ss.Motor3.slip, states=True),
            "e1d": col(ss.Motor3.e1d, states=True),
            "e1q": col(ss.Motor3.e1q, states=True),
            "tm": col(ss.Motor3.tm),
            "te": col(ss.Motor3.te),
        }
    # ANDES records a switch time twice; keep the later record of each time.
    t = out["t"]
    keep = np.append(np.diff(t) > 0, True)
    return {k: v[keep] for k, v in out.items()}


def _sag_depth(raw: dict[str, np.ndarray], spec: dict[str, Any]) -> float:
    t0, t1 = spec["fault_start_s"], spec["fault_start_s"] + spec["fault_s"]
    during = (raw["t"] > t0) & (raw["t"] < t1)
    return float(1.0 - raw["v3"][during].min() / raw["v3"][0])


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
    step_s: float = 1.0 / 600.0,
    z_src: complex = complex(0.01, 0.1),
    base_mva: float = 100.0,
    depth_tol: float = 0.01,
    max_runs: int = 4,
) -> AndesEvent:
    """Simulate a composite load (ZIP + ``Motor3``) through a fault in ANDES.

    Parameters
    ----------
    motor : MotorParams or str
        The motor (own base) or a key of :data:`loadbayes.cases.motor_sim.MOTORS`.
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
    step_s : float
        ANDES's fixed integration step (s).
    z_src : complex
        Source impedance from the infinite bus to the fault bus (system p.u.).
    base_mva : float
        System base.
    depth_tol : float
        Tolerance on the achieved sag depth.
    max_runs : int
        Most ANDES runs to reach the depth (secant steps on ``log xf``).

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
    if not (0 < f_m <= 1 and p0 > 0 and v0 > 0 and 0 < sag_depth < 1):
        raise ValueError("need 0 < f_m <= 1, p0 > 0, v0 > 0 and 0 < sag_depth < 1")
    if not (0 < fault_start_s and fault_s > 0 and t_end_s > fault_start_s + fault_s):
        raise ValueError("need 0 < fault_start_s and the fault to end before t_end_s")
    op = steady_state(params, v_pu=v0, t0=t0)
    mva_m = f_m * p0 / op.p
    s_total = complex(p0, q0)
    s_static = s_total - mva_m * complex(op.p, op.q)  # ZIP and shunt together
    z_total = z_src + Z_FEED
    v_src = v0 + z_total * (s_total / v0).conjugate()  # bus 3 at v0, angle 0 (Ohm's law)
    spec = {
        "motor": params,
        "motor3": motor3_fields(params, t0=t0, mva_m=mva_m, base_mva=base_mva, vn_kv=VN_KV),
        "a_p": tuple(zip_p),
        "a_q": tuple(zip_q),
        "s_static": s_static,
        "q_c": float(q_c),
        "v0": v0,
        "v_src": v_src,
        "z_src": z_src,
        "base_mva": base_mva,
        "fault_start_s": fault_start_s,
        "fault_s": fault_s,
        "step_s": step_s,
    }
    xf = fault_reactance_guess(
        sag_depth, v_src=v_src, z_src=z_src, motor=params, t0=t0, mva_m=mva_m, v0=v0,
        s_static=s_static,
    )  # fmt: skip
    t_fault_end = fault_start_s + fault_s + 2 * step_s
    tried: list[tuple[float, float]] = []
    for _ in range(max_runs - 1):
        depth = _sag_depth(_run(spec, xf, t_fault_end), spec)
        tried.append((math.log(xf), depth))
        if abs(depth - sag_depth) <= depth_tol:
            break
        if len(tried) == 1:
            # Depth falls with xf roughly as 1 / (1 + xf / x_th): step in log xf.
            xf *= math.exp((depth - sag_depth) / max(depth * (1 - depth), 0.05))
        else:
            (x1, d1), (x2, d2) = tried[-2], tried[-1]
            slope = (d2 - d1) / (x2 - x1) if x2 != x1 else -0.2
            xf = math.exp(x2 + (sag_depth - d2) / (slope if slope < 0 else -0.2))
        xf = min(max(xf, 1e-4), 1e3)
    raw = _run(spec, xf, t_end_s)
    return _event(raw, spec, xf, t0, mva_m, sag_depth, t_end_s)


def _event(raw, spec, xf, t0, mva_m, target, t_end_s) -> AndesEvent:
    import andes

    params: MotorParams = spec["motor"]
    v2 = raw["v2"] * np.exp(1j * raw["a2"])
    v3 = raw["v3"] * np.exp(1j * raw["a3"])
    s = v3 * np.conj((v2 - v3) / Z_FEED)  # power into the load bus, load convention
    record = pd.DataFrame(
        {
            "t_s": raw["t"],
            "v": raw["v3"],
            "angle_rad": raw["a3"],
            "f": raw["f"] * params.f_hz,
            "p": s.real,
            "q": s.imag,
            "p_motor": raw["p_motor"],
            "q_motor": raw["q_motor"],
            "p_static": s.real - raw["p_motor"],
            "q_static": s.imag - raw["q_motor"],
            "slip": raw["slip"],
            "e1d": raw["e1d"],
            "e1q": raw["e1q"],
            "tm": raw["tm"],
            "te": raw["te"],
        }
    )
    p0, q0 = float(s[0].real), float(s[0].imag)
    (a1, a2, a3), (a4, a5, a6) = spec["a_p"], spec["a_q"]
    truth = {
        "p0": p0,
        "q0": q0,
        "v0": float(raw["v3"][0]),
        "a1": a1,
        "a2": a2,
        "a3": a3,
        "a4": a4,
        "a5": a5,
        "a6": a6,
        "f_m": float(raw["p_motor"][0]) / p0,
        "rs": params.rs,
        "xs": params.xs,
        "xm": params.xm,
        "rr": params.rr,
        "xr": params.xr,
        "h_s": params.h_s,
        "a": params.a,
        "b": params.b,
        "c": params.c,
        "t0": t0,
        "mva_m": mva_m,
        "q_c": spec["q_c"],
        "x_prime": params.xp,
        "x_open": params.x,
        "t_prime_s": params.tp_s,
        "f_hz": params.f_hz,
    }
    depth = _sag_depth(raw, spec)
    settings = {
        "simulator": f"ANDES {andes.__version__}",
        "motor_name": params.name,
        "base_mva": spec["base_mva"],
        "z_src": [spec["z_src"].real, spec["z_src"].imag],
        "z_feed": [Z_FEED.real, Z_FEED.imag],
        "v_src": [abs(spec["v_src"]), float(np.angle(spec["v_src"]))],
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
        "motor3": spec["motor3"],
    }
    record.attrs.update({"truth": truth, "settings": settings})
    return AndesEvent(record=record, truth=truth, settings=settings, motor=params)
