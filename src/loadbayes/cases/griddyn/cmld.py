"""The WECC composite load as a GridDyn case: the CMLDBLU1 record, its network and its truth.

The CON order and meanings follow GridDyn's DYR reader (``loadCMLDBLU1`` in
``gridDynReadDyr.cpp``) and the WECC composite load model specification (CMPLDW, WECC
MVWG "Composite Load Model for Dynamic Simulations", 2012; the PSS/E CMLDBLU1 record).
GridDyn 0.13.0 restrictions honoured here: never all three motors A, B, C three-phase
(motor C's fraction is 0); single-cage three-phase motors (Lpp = Lp, Tppo = 0); a fixed
tap (no LTC); motor D with Tf = 0, LFadj = 1 and its run curves at the WECC constants;
the electronic load's Frcel fixed at 0.8 by the reader; a GENCLS source, not an
infinite bus. Nothing here imports loadbayes or GridDyn.
"""

from __future__ import annotations

import dataclasses

S_BASE_MVA = 100.0
V_BASE_KV = 230.0
F_HZ = 60.0


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
