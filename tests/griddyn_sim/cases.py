"""GridDyn cases of the WECC composite load (CMLDBLU1): the independent simulator of issue 36.

GridDyn (LLNL, BSD; ``griddyn`` 0.13.0) needs Python >= 3.13, so it runs in its own
environment (``make test`` builds ``.venv-griddyn``; ``LOADBAYES_GRIDDYN_PYTHON`` names
another interpreter) and each case in a child process (``run_case.py``). Nothing here
imports loadbayes.

The case: a classical machine (GENCLS, large) behind a line to a fault bus, a second line
to the measured bus (where a recorder would sit), and there one CMLDBLU1 record in
GridDyn's form ``IBUS 'CMLDBLU1' ID <132 CONs> /``: substation transformer (fixed tap),
feeder, motors A and B (three-phase, single-cage: Lpp = Lp, Tppo = 0), motor D (the
single-phase compressor performance model), electronic load and static part. A shunt
fault at the fault bus, its impedance found by the child so that the measured bus sags
by the depth asked for (``1 - median V during the fault / V before``).

The CON order and meanings follow GridDyn's DYR reader (``loadCMLDBLU1`` in
``gridDynReadDyr.cpp``) and the WECC composite load model specification (CMPLDW, WECC
MVWG "Composite Load Model for Dynamic Simulations", 2012; the PSS/E CMLDBLU1 record).
GridDyn restrictions honoured here (see the findings on GridDyn 0.13.0): never all three
motors A, B, C three-phase (motor C's fraction is 0); no dynamic LTC; motor D with
Tf = 0, LFadj = 1 and its run curves at the WECC constants; an electronic load's Frcel
fixed at 0.8 by the reader.

Results: :func:`run_case` returns the measured bus's t_s, v, angle_rad, p, q (system per
unit) resampled to a recorder's phasor rate, and the truth. Runs are cached on disk
(``LOADBAYES_GRIDDYN_CACHE``, default a folder under the system temp dir), keyed by a
hash of everything that defines them, so repeated tests do not rerun GridDyn.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
RUNNER = HERE / "run_case.py"

S_BASE_MVA = 100.0
V_BASE_KV = 230.0
F_HZ = 60.0
# Sags at the measured bus. Deep is 46%: in GridDyn 0.13.0 motor D's stall is not
# monotone in depth (with these defaults 44-45% leave it running with the feeder end at
# 0.46 pu, far below Vstall 0.6; 46% stalls it), so the deep case is where it does stall.
DEPTHS = {"shallow": 0.13, "medium": 0.25, "deep": 0.46}

# Buses and objects as GridDyn names them from the .raw below.
MEASURED_BUS = "LOAD"
FEED_LINK = "FAULT_to_LOAD"
FAULT_LOAD = "FAULT::FAULT_load_1"
LOAD_END_BUS = "cmpldw_2_1_load_end"
CMLD_LOAD = "cmpldw_2_1"


def griddyn_python() -> Path | None:
    """The GridDyn environment's interpreter, or None when there is none."""
    named = os.environ.get("LOADBAYES_GRIDDYN_PYTHON")
    path = Path(named) if named else REPO / ".venv-griddyn" / "bin" / "python"
    return path if path.exists() else None


def skip_reason() -> str | None:
    """One line saying why GridDyn cases cannot run here, or None when they can."""
    python = griddyn_python()
    if python is None:
        return (
            "GridDyn missing: no .venv-griddyn (make test builds it when python3.13 exists)"
            " and LOADBAYES_GRIDDYN_PYTHON unset"
        )
    probe = subprocess.run(
        [str(python), "-c", "import griddyn"], capture_output=True, text=True, timeout=60
    )
    if probe.returncode != 0:
        return f"GridDyn does not import in {python}: {probe.stderr.strip().splitlines()[-1:]}"
    return None


@dataclasses.dataclass(frozen=True)
class Motor3:
    """A WECC three-phase motor (Mtyp 3), single-cage: Lpp = Lp and Tppo = 0 in the record.

    Impedances per unit of the motor's MVA (its base is P / LFm), time constants in s.
    Undervoltage trips are off by default (Ftr = 0): the cases check the load, not relays.
    """

    lfm: float = 0.75
    rs: float = 0.04
    ls: float = 1.8
    lp: float = 0.12
    tpo_s: float = 0.095
    h_s: float = 0.1
    etrq: float = 0.0
    vtr1: float = 0.0
    ttr1_s: float = 9999.0
    ftr1: float = 0.0

    def cons(self) -> list[float]:
        """The 20 CONs of one motor block (MtypX .. TrcX2)."""
        return [
            3.0, self.lfm, self.rs, self.ls, self.lp, self.lp, self.tpo_s, 0.0,
            self.h_s, self.etrq,
            self.vtr1, self.ttr1_s, self.ftr1, 2.0, 9999.0,
            0.0, 9999.0, 0.0, 2.0, 9999.0,
        ]  # fmt: skip


# WECC typical: motor A a fast constant-torque compressor, motor B a high-inertia fan
# with torque rising with speed squared (CMPLDW defaults, single-cage here).
MOTOR_A = Motor3()
MOTOR_B = Motor3(lfm=0.75, rs=0.03, ls=1.8, lp=0.19, tpo_s=0.2, h_s=0.5, etrq=2.0)


@dataclasses.dataclass(frozen=True)
class MotorD:
    """WECC motor D (single-phase air conditioners), performance model.

    Stall below ``vstall`` for ``tstall_s`` into ``rstall + j xstall`` (motor base);
    a fraction ``frst`` restarts above ``vrst`` after ``trst_s``; undervoltage trip of
    ``fuvr`` below ``uvtr1`` for ``ttr1_s``. Run curves at GridDyn's fixed WECC constants.
    """

    lfm: float = 1.0
    comp_pf: float = 0.98
    vstall: float = 0.6
    rstall: float = 0.1
    xstall: float = 0.1
    tstall_s: float = 0.033
    trst_s: float = 0.4
    frst: float = 0.2
    vrst: float = 0.95
    tv_s: float = 0.025
    fuvr: float = 0.1
    uvtr1: float = 0.6
    ttr1_s: float = 0.02

    def cons(self) -> list[float]:
        """CONs 98-132 (Tstall .. Ttr2)."""
        return [
            self.tstall_s, self.trst_s, self.tv_s, 0.0, self.lfm, self.comp_pf,
            self.vstall, self.rstall, self.xstall, 1.0,
            0.0, 1.0, 6.0, 2.0, 12.0, 3.2, 11.0, 2.5, 0.86,
            self.frst, self.vrst, 1.0, -3.3,
            0.5, 0.4, 0.6, 0.5,
            15.0, 0.7, 1.9,
            self.fuvr, self.uvtr1, self.ttr1_s, 1.0, 9999.0,
        ]  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Cmld:
    """One CMLDBLU1 load and its network: every number the truth reports.

    Fractions are of the load's P at the feeder's end; the static part takes the rest.
    Feeder and transformer impedances per unit of the distribution base ``load_mw /
    mva_ratio`` MVA (the record's MVA = -mva_ratio); everything else per unit of
    ``S_BASE_MVA``.
    """

    load_mw: float = 100.0
    load_mvar: float = 20.0
    f_a: float = 0.15
    f_b: float = 0.10
    f_d: float = 0.15
    f_el: float = 0.15
    motor_a: Motor3 = MOTOR_A
    motor_b: Motor3 = MOTOR_B
    motor_d: MotorD = MotorD()
    mva_ratio: float = 0.8
    r_fdr: float = 0.04
    x_fdr: float = 0.04
    fb: float = 0.75
    x_xf: float = 0.08
    bss: float = 0.0
    tap_hs: float = 1.0
    tap_ls: float = 1.05
    pf_el: float = 1.0
    vd1: float = 0.7
    vd2: float = 0.5
    pf_s: float = 0.95
    # Static P = P0 (p1c V^p1e + p2c V^p2e + 1 - p1c - p2c); Q likewise.
    p1c: float = 0.3
    p1e: float = 2.0
    p2c: float = 0.3
    p2e: float = 1.0
    q1c: float = 0.5
    q1e: float = 2.0
    q2c: float = 0.3
    q2e: float = 1.0
    # Source: a GENCLS of h_src s and x_src on s_src_mva, lines r + jx (system p.u.).
    v_src: float = 1.02
    h_src_s: float = 50.0
    x_src: float = 0.02
    s_src_mva: float = 2000.0
    line_src_fault: tuple[float, float] = (0.002, 0.02)
    line_fault_load: tuple[float, float] = (0.005, 0.05)

    @property
    def f_static(self) -> float:
        """The static part's share: what the motors and electronics leave."""
        return 1.0 - self.f_a - self.f_b - self.f_d - self.f_el

    def cons(self) -> list[float]:
        """The 132 CONs of the CMLDBLU1 record, in GridDyn's (and PSS/E's) order."""
        if self.f_static < -1e-12:
            raise ValueError("the motor and electronic fractions add up to more than 1")
        motor_c = Motor3(h_s=0.1, etrq=2.0)  # fraction 0: never built (A, B, C crash)
        cons = [
            -self.mva_ratio, self.bss, self.r_fdr, self.x_fdr, self.fb, self.x_xf,
            self.tap_hs, self.tap_ls, 0.0,
            0.9, 1.1, 0.00625, 1.025, 1.04, 30.0, 5.0, 0.0, 0.0,
            self.f_a, self.f_b, 0.0, self.f_d, self.f_el,
            self.pf_el, self.vd1, self.vd2, self.pf_s,
            self.p1c, self.p1e, self.p2c, self.p2e, 0.0,
            self.q1c, self.q1e, self.q2c, self.q2e, 0.0,
            *self.motor_a.cons(), *self.motor_b.cons(), *motor_c.cons(),
            *self.motor_d.cons(),
        ]  # fmt: skip
        assert len(cons) == 132
        return cons

    def raw(self) -> str:
        """The PSS/E v33 power flow: source, fault bus (zero load), load bus."""
        (r1, x1), (r2, x2) = self.line_src_fault, self.line_fault_load
        x_gen = self.x_src
        gen = (
            f"    1,'1 ', {self.load_mw:.3f}, {self.load_mvar:.3f}, 9900.0, -9900.0,"
            f" {self.v_src:.5f}, 0, {self.s_src_mva:.1f}, 0.0, {x_gen:.5f}, 0.0, 0.0,"
            " 1.0, 1, 100.0, 9000.0, -9000.0, 1,1.0, 0,1.0, 0,1.0, 0,1.0, 0, 1.0"
        )
        branch = "{a}, {b},'1 ', {r:.5f}, {x:.5f}, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1,1, 0.0, 1,1.0, 0,1.0, 0,1.0, 0,1.0"  # noqa: E501
        ends = [
            "TRANSFORMER", "AREA", "TWO-TERMINAL DC", "VOLTAGE SOURCE CONVERTER",
            "IMPEDANCE CORRECTION", "MULTI-TERMINAL DC", "MULTI-SECTION LINE", "ZONE",
            "INTER-AREA TRANSFER", "OWNER", "FACTS CONTROL DEVICE", "SWITCHED SHUNT",
            "GNE DEVICE",
        ]  # fmt: skip
        fill = {"AREA": "   1, 0, 0.0, 1.0,'1'", "ZONE": "   1,'1'", "OWNER": "    1,'1'"}
        lines = [
            f" 0, {S_BASE_MVA:.2f}, 33, 0, 0, {F_HZ:.2f}  / loadbayes GridDyn CMLD case",
            "",
            "",
            f"    1,'SRC', {V_BASE_KV:.4f},3, 1, 1, 1,{self.v_src:.5f}, 0.0",
            f"    2,'LOAD', {V_BASE_KV:.4f},1, 1, 1, 1,1.00000, 0.0",
            f"    3,'FAULT', {V_BASE_KV:.4f},1, 1, 1, 1,1.00000, 0.0",
            "0 / END OF BUS DATA, BEGIN LOAD DATA",
            f"    2,'1 ',1, 1, 1, {self.load_mw:.3f}, {self.load_mvar:.3f}, 0.0, 0.0, 0.0, 0.0, 1,1",  # noqa: E501
            "    3,'1 ',1, 1, 1, 0.000, 0.000, 0.0, 0.0, 0.0, 0.0, 1,1",
            "0 / END OF LOAD DATA, BEGIN FIXED SHUNT DATA",
            "0 / END OF FIXED SHUNT DATA, BEGIN GENERATOR DATA",
            gen,
            "0 / END OF GENERATOR DATA, BEGIN BRANCH DATA",
            "    " + branch.format(a=1, b=3, r=r1, x=x1),
            "    " + branch.format(a=3, b=2, r=r2, x=x2),
            "0 / END OF BRANCH DATA, BEGIN TRANSFORMER DATA",
        ]
        for this, following in zip(ends, [*ends[1:], None], strict=True):
            if this in fill:
                lines.append(fill[this])
            tail = f", BEGIN {following} DATA" if following else ""
            lines.append(f"0 / END OF {this} DATA{tail}")
        lines.append("Q")
        return "\n".join(lines) + "\n"

    def dyr(self) -> str:
        """The dynamic data: the GENCLS source and the CMLDBLU1 record."""
        cons = " ".join(repr(float(c)) for c in self.cons())
        return f"1 'GENCLS' 1 {self.h_src_s!r} 0.0 /\n2 'CMLDBLU1' 1 {cons} /\n"

    def truth(self) -> dict:
        """Every number that defines the load, with its base."""
        dist_mva = self.load_mw / self.mva_ratio
        to_system = S_BASE_MVA / dist_mva
        return {
            "s_base_mva": S_BASE_MVA,
            "v_base_kv": V_BASE_KV,
            "f_hz": F_HZ,
            "load_mw_raw": self.load_mw,
            "load_mvar_raw": self.load_mvar,
            "fractions": {
                "motor_a": self.f_a,
                "motor_b": self.f_b,
                "motor_c": 0.0,
                "motor_d": self.f_d,
                "electronic": self.f_el,
                "static": self.f_static,
            },
            "motor_share": self.f_a + self.f_b + self.f_d,
            "three_phase_motor_share": self.f_a + self.f_b,
            "distribution_base_mva": dist_mva,
            "feeder": {
                "r_fdr": self.r_fdr,
                "x_fdr": self.x_fdr,
                "fb": self.fb,
                "x_xf": self.x_xf,
                "bss": self.bss,
                "tap_hs": self.tap_hs,
                "tap_ls": self.tap_ls,
                "base": "distribution (distribution_base_mva)",
            },
            "feeder_system_pu": {
                "r_fdr": self.r_fdr * to_system,
                "x_fdr": self.x_fdr * to_system,
                "x_xf": self.x_xf * to_system * self.tap_hs**2,
                "r_total": self.r_fdr * to_system,
                "x_total": (self.x_fdr + self.x_xf * self.tap_hs**2) * to_system,
            },
            "motor_a": dataclasses.asdict(self.motor_a) | {"lpp": self.motor_a.lp, "tppo_s": 0.0},
            "motor_b": dataclasses.asdict(self.motor_b) | {"lpp": self.motor_b.lp, "tppo_s": 0.0},
            "motor_d": dataclasses.asdict(self.motor_d),
            "electronic": {"pf_el": self.pf_el, "vd1": self.vd1, "vd2": self.vd2, "frcel": 0.8},
            "static": {
                "pf_s": self.pf_s,
                "p1c": self.p1c,
                "p1e": self.p1e,
                "p2c": self.p2c,
                "p2e": self.p2e,
                "q1c": self.q1c,
                "q1e": self.q1e,
                "q2c": self.q2c,
                "q2e": self.q2e,
            },
            "source": {
                "model": "GENCLS",
                "v": self.v_src,
                "h_s": self.h_src_s,
                "x_d_prime": self.x_src,
                "s_mva": self.s_src_mva,
                "line_src_fault": list(self.line_src_fault),
                "line_fault_load": list(self.line_fault_load),
            },
            "cons": self.cons(),
        }


def _cache_dir() -> Path:
    named = os.environ.get("LOADBAYES_GRIDDYN_CACHE")
    path = Path(named) if named else Path(tempfile.gettempdir()) / "loadbayes-griddyn-cache"
    path.mkdir(parents=True, exist_ok=True)
    return path


def _resample(rows: np.ndarray, rate_hz: float, window_s: float) -> np.ndarray:
    """Rows at ``k / rate_hz``: the mean over ``window_s`` centred on the stamp (0: points)."""
    t = rows[:, 0]
    half = window_s / 2.0
    stamps = np.arange(np.ceil(half * rate_hz), np.floor((t[-1] - half) * rate_hz) + 1) / rate_hz
    if window_s <= 0.0:
        values = [np.interp(stamps, t, column) for column in rows[:, 1:].T]
    else:
        # Exact means of the piecewise-linear output over each window (trapezoid sums).
        steps = (rows[1:, 1:] + rows[:-1, 1:]) / 2 * np.diff(t)[:, None]
        cum = np.concatenate([np.zeros((1, rows.shape[1] - 1)), np.cumsum(steps, axis=0)])
        values = [
            (np.interp(stamps + half, t, column) - np.interp(stamps - half, t, column)) / window_s
            for column in cum.T
        ]
    return np.column_stack([stamps, *values])


def run_case(
    cmld: Cmld | None = None,
    depth: float = DEPTHS["shallow"],
    *,
    rate_hz: float = F_HZ,
    window_s: float | None = None,
    t_fault_s: float = 0.2075,
    duration_s: float = 0.1,
    t_end_s: float = 2.0,
    dt_s: float = 0.0005,
    fault_x_over_r: float = 10.0,
    refresh_s: float = 0.01,
) -> tuple[pd.DataFrame, dict]:
    """One GridDyn event at the measured bus, and its truth.

    ``depth``: the sag at the measured bus (``1 - median V during the fault / V before``)
    within 0.5 percentage points. ``window_s``: the recorder's phasor window (default one
    cycle at 60 Hz; 0 gives point samples). Returns the frame (t_s, v, angle_rad, p, q; V
    per unit of ``V_BASE_KV``, P and Q per unit of ``S_BASE_MVA``, positive into the load)
    and the truth: :meth:`Cmld.truth` plus ``event`` (the fault and what the run read back:
    ``p0``, ``q0``, ``v0`` at the measured bus after GridDyn's initialisation, and the
    initial state of every bus, link and load).
    """
    cmld = cmld or Cmld()
    window_s = 1.0 / F_HZ if window_s is None else window_s
    spec = {
        "raw": cmld.raw(),
        "dyr": cmld.dyr(),
        "measured_bus": MEASURED_BUS,
        "feed_link": FEED_LINK,
        "fault_load": FAULT_LOAD,
        "load_end_bus": LOAD_END_BUS,
        "cmld_load": CMLD_LOAD,
        "depth": depth,
        "depth_tol": 0.005,
        "y_guess": 2.0 + 100.0 * depth,
        "fault_x_over_r": fault_x_over_r,
        "t_fault_s": t_fault_s,
        "t_clear_s": t_fault_s + duration_s,
        "t_end_s": t_end_s,
        "dt_s": dt_s,
        "refresh_s": refresh_s,
    }
    key = hashlib.sha256(
        (json.dumps(spec, sort_keys=True) + RUNNER.read_text()).encode()
    ).hexdigest()[:24]
    out = _cache_dir() / f"cmld-{key}.npz"
    if not out.exists():
        python = griddyn_python()
        if python is None:
            raise RuntimeError(skip_reason())
        with tempfile.TemporaryDirectory(prefix="griddyn-spec-") as tmp:
            spec_path = Path(tmp) / "spec.json"
            spec_path.write_text(json.dumps(spec))
            done = subprocess.run(
                [str(python), str(RUNNER), str(spec_path), str(out)],
                capture_output=True,
                text=True,
                timeout=300,
            )
        if not out.exists():
            raise RuntimeError(
                f"GridDyn case (depth {depth}) failed, exit {done.returncode}: "
                + (done.stderr.strip().splitlines() or ["no message"])[-1]
            )
    with np.load(out) as saved:
        rows = saved["rows"]
        meta = json.loads(str(saved["meta"]))
    feed = meta["start"]["links"][FEED_LINK]
    truth = cmld.truth()
    truth["event"] = {
        "depth_requested": depth,
        "depth_measured": meta["depth_measured"],
        "fault_y": meta["fault_y"],
        "fault_x_over_r": fault_x_over_r,
        "t_fault_s": t_fault_s,
        "t_clear_s": t_fault_s + duration_s,
        "rate_hz": rate_hz,
        "window_s": window_s,
        "p0": -feed[2],
        "q0": -feed[3],
        "v0": meta["start"]["buses"][MEASURED_BUS][0],
        "initial_state": meta["start"],
        "griddyn_version": meta["griddyn_version"],
        "cache_file": str(out),
    }
    sampled = _resample(rows, rate_hz, window_s)
    truth["event"]["feeder_end"] = {
        name: sampled[:, j].tolist() for name, j in (("t_s", 0), ("v", 5), ("p", 6), ("q", 7))
    }
    frame = pd.DataFrame(sampled[:, :5], columns=["t_s", "v", "angle_rad", "p", "q"])
    return frame, truth


if __name__ == "__main__":  # a quick look: python cases.py [depth]
    frame, info = run_case(depth=float(sys.argv[1]) if len(sys.argv) > 1 else 0.13)
    print(frame.iloc[::6].to_string())
    print({k: v for k, v in info["event"].items() if k not in ("initial_state", "feeder_end")})
    end = info["event"]["feeder_end"]
    print("feeder end v:", np.round(end["v"][::6], 3).tolist())
