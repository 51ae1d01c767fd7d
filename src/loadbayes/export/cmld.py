"""The WECC composite load record: CMLDBLU2 (PSS/E 35) and CMPLDW (PSLF), one mapping.

A fitted composite load (ZIP + one third-order induction motor) fills the composite load
model as *motor A* plus its *static load*; motors B, C, D and the power-electronic load
get fraction 0; there is no feeder, no substation transformer and no shunt at the
substation (the power flow's load bus is the load's own terminal, as in the fit).

Sources of the field order (docs/formats.md has the table with every field):

- CMLDBLU2 header ``IBUS 'USRLOD' 'ID' 'CMLDBLU2' 12 IT 2 133 27 146 48 ICON(2) CON(133)``
  and the CON order up to motor A's trip settings (CON J to J+56): GridPACK's PSS/E
  dyr parser ``src/parser/parser_classes/cmldblu1.hpp`` (GridOPTICS/GridPACK; the token
  index of each CON, MVA at token 11 = CON J), which agrees position by position with a
  public CMLDBLU2 writer (an RTS-96 study script writing ``'USRLOD' '1' 'CMLDBLU2' 12 1 2
  133 27 146 48 0 0`` then the CONs, commented ``J .. J+132``) and with InterPSS's
  CMLDBLU2 parser test (ODM, ``10020 'USRLOD' 1 'CMLDBLU2' 12 1 2 133 27 146 48 0 0``).
- Motors B and C (CON J+57 .. J+96) repeat motor A's 20 fields (both sources).
- CON J+97 .. J+132 (motor D, the single-phase motor, and the rest): named one by one
  by TDcoSim's CMLDBLU2 table (NREL, ``config/composite_load_model_rating.json``, written
  with the header ``'USRLOD' 1 'CMLDBLU2' 12 1 2 133 27 146 48 0 0``): motor D's 35 CONs
  in CMLDBLU1's order (``Tstall, Trst, Tv, Tf, CompLF, CompPF, Vstall ... UVtr2, Ttr2``,
  the order the tests' GridDyn harness writes for CMLDBLU1) and then, the one CON
  CMLDBLU2 adds, ``Frcel`` (the electronic load's fraction that recovers) at J+132.
  So CMLDBLU2's CONs are CMLDBLU1's 132 followed by ``Frcel``. A composite fit
  (``zip+motor``) writes them as 0 (``Fmd`` and ``Fel`` are 0); a model of parts
  (:func:`parts_cmld_values`) fills them.
- CMPLDW (PSLF ``.dyd``): ``cmpldw IBUS "NAME" BASEKV "ID" : #9 mva=MVA`` then the other
  parameters by position, in the order of InterPSS's PSLF reader
  (``org.ieee.odm.adapter.ge.parser.dynamic.load.PSLFDynLoadCMPLDWDataParser``, InterPSS
  ODM): unlike CMLDBLU2 it has ``frcel`` after ``Vd2``, the four motor types together
  (``MtypA .. MtypD``) before motor A's fields, motors B and C without a type field, and
  motor D's 24 named fields (``LfmD, CompPF, Vstall ... Tv``), written as 0 here (its
  fraction is 0). Not checked against a PSLF installation, which was not reachable.

ANDES's PSS/E dyr reader (``andes.io.psse``) splits the record into numbers but does not
support the model (it logs "Models not yet supported: USRLOD"); the tests read the record
back with it all the same.
"""

from __future__ import annotations

import math

from loadbayes.export.loadparts import LoadParts

__all__ = [
    "CMPLDW_NAMES",
    "CON_NAMES",
    "cmld_values",
    "cmpldw_extra",
    "parts_note",
    "parts_cmld_values",
    "cmldblu2_text",
    "cmpldw_text",
    "read_cmldblu2",
]

_MOTOR = ("Mtp{m}", "LFm{m}", "Rs{m}", "Ls{m}", "Lp{m}", "Lpp{m}", "Tpo{m}", "Tppo{m}",
          "H{m}", "Etrq{m}", "Vtr1{m}", "Ttr1{m}", "Ftr1{m}", "Vrc1{m}", "Trc1{m}",
          "Vtr2{m}", "Ttr2{m}", "Ftr2{m}", "Vrc2{m}", "Trc2{m}")  # fmt: skip
#: Motor D's CONs (J+97 .. J+131), CMLDBLU1's order (TDcoSim; the tests' GridDyn harness).
_MOTOR_D = ("Tstall", "Trst", "Tv", "Tf", "CompLF", "CompPF", "Vstall", "Rstall", "Xstall",
            "LFadj", "Kp1", "Np1", "Kq1", "Nq1", "Kp2", "Np2", "Kq2", "Nq2", "Vbrk", "Frst",
            "Vrst", "CmpKpf", "CmpKqf", "Vc1off", "Vc2off", "Vc1on", "Vc2on", "Tth", "Th1t",
            "Th2t", "Fuvr", "UVtr1", "Ttr1", "UVtr2", "Ttr2")  # fmt: skip
#: CON J .. J+132 of CMLDBLU2, by name.
CON_NAMES: tuple[str, ...] = (
    "MVA", "Bss", "Rfdr", "Xfdr", "Fb", "Xxf", "Tfixhs", "Tfixls", "LTC", "Tmin", "Tmax",
    "Step", "Vmin", "Vmax", "Tdel", "Ttap", "Rcomp", "Xcomp", "Fma", "Fmb", "Fmc", "Fmd",
    "Fel", "PFel", "Vd1", "Vd2", "PFs", "P1e", "P1c", "P2e", "P2c", "Pfrq", "Q1e", "Q1c",
    "Q2e", "Q2c", "Qfrq",
    *(f.format(m="A") for f in _MOTOR),
    *(f.format(m="B") for f in _MOTOR),
    *(f.format(m="C") for f in _MOTOR),
    *_MOTOR_D,
    "Frcel",
)  # fmt: skip
assert len(CON_NAMES) == 133

_PSLF_MOTOR = tuple(f for f in _MOTOR if f != "Mtp{m}")
#: CMPLDW's parameters in PSLF's order (InterPSS's reader), ``MVA`` written ``mva=``.
CMPLDW_NAMES: tuple[str, ...] = (
    *CON_NAMES[:26], "frcel", *CON_NAMES[26:37], "MtpA", "MtpB", "MtpC", "MtpD",
    *(f.format(m="A") for f in _PSLF_MOTOR),
    *(f.format(m="B") for f in _PSLF_MOTOR),
    *(f.format(m="C") for f in _PSLF_MOTOR),
    "LFmD", "CompPF", "Vstall", "Rstall", "Xstall", "Tstall", "Frst", "Vrst", "Trst", "Fuvr",
    "Vtr1", "Ttr1", "Vtr2", "Ttr2", "Vc1off", "Vc2off", "Vc1on", "Vc2on", "Tth", "Th1t",
    "Th2t", "Tv",
)  # fmt: skip

#: The trip and reconnection settings written for every motor: none (no trip).
_NO_TRIP = {"Vtr1": 0.0, "Ttr1": 9999.0, "Ftr1": 0.0, "Vrc1": 0.0, "Trc1": 9999.0,
            "Vtr2": 0.0, "Ttr2": 9999.0, "Ftr2": 0.0, "Vrc2": 0.0, "Trc2": 9999.0}  # fmt: skip


def _motor_fields(parts: LoadParts) -> dict[str, float]:
    """Motor A's fields from the fitted motor (single cage: ``Lpp = Lp``)."""
    m = parts.motor
    pr = m.params
    return {
        "Mtp": 3.0,  # three-phase induction motor
        "LFm": m.p_pu,  # loading factor: P at v0 over the rating (own base)
        "Rs": pr.rs,
        "Ls": m.x_sync,  # xs + xm
        "Lp": m.x_transient,  # xs + xm xr / (xm + xr)
        "Lpp": m.x_transient,  # one rotor circuit: no subtransient
        "Tpo": m.t_open_s,  # (xr + xm) / (wb rr)
        # With Lpp = Lp the subtransient circuit carries nothing; a positive time
        # constant keeps the record valid for readers that divide by it.
        "Tppo": m.t_open_s / 100.0,
        "H": pr.h_s,
        "Etrq": 2.0 * pr.a + pr.b,  # T = T0 w^Etrq; exact for a pure power law
        **_NO_TRIP,
    }


def cmld_values(parts: LoadParts) -> dict[str, float]:
    """The 133 CONs of CMLDBLU2 (by name) for a composite load's parts.

    Parameters
    ----------
    parts : LoadParts
        From :func:`~loadbayes.export.loadparts.load_parts` with a motor.

    Returns
    -------
    dict
        ``CON_NAMES`` -> value, in the record's order.
    """
    if parts.motor is None:
        raise ValueError("the WECC composite record needs a motor (a composite fit)")
    m = parts.motor
    p_total = parts.p_total
    if not p_total > 0:
        raise ValueError(f"the load draws P = {p_total:.6g} MW at v0: CMLDBLU2 needs P > 0")
    ps, qs = parts.p_static, parts.q_static
    pfs = ps / math.hypot(ps, qs) if ps or qs else 1.0
    a1, a2, _ = parts.shares_p
    a4, a5, _ = parts.shares_q
    q_total = float(parts.q(parts.v0)) + m.q_mvar
    out = dict.fromkeys(CON_NAMES, 0.0)
    out.update({
        "MVA": math.hypot(p_total, q_total),  # no feeder or transformer: any base does
        "Tfixhs": 1.0, "Tfixls": 1.0, "Tmin": 0.9, "Tmax": 1.1, "Step": 0.00625,
        "Vmin": 1.025, "Vmax": 1.04, "Tdel": 30.0, "Ttap": 5.0,  # LTC = 0: unused
        "Fma": m.p_mw / p_total,  # f_m
        "PFel": 1.0, "Vd1": 0.7, "Vd2": 0.5,  # Fel = 0: unused
        # Static load: PFs from its P, Q at v0 (negative when it supplies Q); the ZIP
        # shares of V/v0 as two power terms, the rest constant power.
        "PFs": math.copysign(pfs, qs) if qs else pfs,
        "P1e": 2.0, "P1c": a1, "P2e": 1.0, "P2c": a2,
        "Q1e": 2.0, "Q1c": a4, "Q2e": 1.0, "Q2c": a5,
    })  # fmt: skip
    motor = _motor_fields(parts)
    for letter in "ABC":  # B and C repeat A (fraction 0) so every field is a valid motor
        for key, val in motor.items():
            out[f"{key}{letter}"] = val
    return out


#: Motor D's fields the fit has no part for, and what is written: no voltage or frequency
#: filter (Tv, Tf 0: the fit reads the samples), the loading factor 1 (the fit's motor D
#: draws 1 p.u. of its rating at 1 p.u.; so LFadj, written 1 as GridDyn's reader
#: requires, moves nothing), the frequency dependence at the WECC typical values (a
#: fault record's frequency barely moves; GridDyn's reader requires them), no contactors
#: and no undervoltage relay (the fit's motor D has none), the thermal relay at the WECC
#: typical values (it acts over seconds, beyond a fault record's window).
_MOTOR_D_UNFITTED = {"Tv": 0.0, "Tf": 0.0, "CompLF": 1.0, "LFadj": 1.0, "CmpKpf": 1.0,
                     "CmpKqf": -3.3, "Vc1off": 0.0, "Vc2off": 0.0, "Vc1on": 0.0, "Vc2on": 0.0,
                     "Tth": 15.0, "Th1t": 0.7, "Th2t": 1.9, "Fuvr": 0.0, "UVtr1": 0.0,
                     "Ttr1": 9999.0, "UVtr2": 0.0, "Ttr2": 9999.0}  # fmt: skip
#: The fit's motor D constants (``settings.model_options.motor_d_params``) -> CONs.
_MOTOR_D_FITTED = {"tstall": "Tstall", "trst": "Trst", "comp_pf": "CompPF",
                   "vstall": "Vstall", "rstall": "Rstall", "xstall": "Xstall", "kp1": "Kp1",
                   "np1": "Np1", "kq1": "Kq1", "nq1": "Nq1", "kp2": "Kp2", "np2": "Np2",
                   "kq2": "Kq2", "nq2": "Nq2", "vbrk": "Vbrk", "frst": "Frst",
                   "vrst": "Vrst"}  # fmt: skip


def parts_cmld_values(pl) -> dict[str, float]:
    """The 133 CONs of CMLDBLU2 (by name) for a model of parts (``slm``, ``cmld-lite``).

    Parameters
    ----------
    pl : loadbayes.export.partsload.PartsLoad
        From :func:`~loadbayes.export.partsload.parts_load`.

    Returns
    -------
    dict
        ``CON_NAMES`` -> value, in the record's order (see ``partsload``'s docstring for
        the feeder's split, the static Q and the loading factors).
    """
    mo = pl.options
    out = dict.fromkeys(CON_NAMES, 0.0)
    x_fdr = min(pl.x_fd, pl.r_fd)
    ps = pl.fractions["s"] * pl.p_load_mw
    qs = pl.q_load_mvar
    pfs = ps / math.hypot(ps, qs) if ps or qs else 1.0
    out.update({
        "MVA": pl.mva_base, "Bss": 0.0, "Rfdr": pl.r_fd, "Xfdr": x_fdr, "Fb": 0.0,
        "Xxf": pl.x_fd - x_fdr,
        "Tfixhs": 1.0, "Tfixls": 1.0, "Tmin": 0.9, "Tmax": 1.1, "Step": 0.00625,
        "Vmin": 1.025, "Vmax": 1.04, "Tdel": 30.0, "Ttap": 5.0,  # LTC = 0: unused
        "Fma": pl.fractions.get("A", 0.0), "Fmb": pl.fractions.get("B", 0.0), "Fmc": 0.0,
        "Fmd": pl.fractions.get("D", 0.0), "Fel": pl.fractions.get("el", 0.0),
        # The fit's electronics draw P only (their Q is in the static Q's terms).
        "PFel": 1.0, "Vd1": float(mo.get("vd1", 0.7)), "Vd2": float(mo.get("vd2", 0.5)),
        "PFs": math.copysign(pfs, qs) if qs else pfs,
        "P1e": 2.0, "P1c": pl.zip_p[0], "P2e": 1.0, "P2c": pl.zip_p[1],
        "Q1e": 2.0, "Q1c": pl.zip_q[0], "Q2e": 1.0, "Q2c": pl.zip_q[1],
        "Frcel": float(mo.get("frcel", 0.0)),
    })  # fmt: skip
    for letter in "ABC":
        m = pl.motors.get(letter) or pl.motors["A"]  # C (and an absent B): A's, fraction 0
        fields = {"Mtp": 3.0, "LFm": m["lfm"], "Rs": m["rs"], "Ls": m["ls"], "Lp": m["lp"],
                  "Lpp": m["lp"], "Tpo": m["tpo"], "Tppo": m["tpo"] / 100.0, "H": m["h"],
                  "Etrq": m["etrq"], **_NO_TRIP}  # fmt: skip
        for key, val in fields.items():
            out[f"{key}{letter}"] = float(val)
    out.update(_MOTOR_D_UNFITTED)
    d = mo.get("motor_d_params") or {}
    for key, con in _MOTOR_D_FITTED.items():
        if key in d:
            out[con] = float(d[key])
    return out


def parts_note(cons: dict[str, float]) -> str:
    """What a model of parts' CMLDBLU2 holds, in one line (the files' comments)."""
    fr = ", ".join(f"{k} {cons[k]:.6g}" for k in ("Fma", "Fmb", "Fmc", "Fmd", "Fel"))
    static = 1.0 - sum(cons[k] for k in ("Fma", "Fmb", "Fmc", "Fmd", "Fel"))
    return (
        f"CMLDBLU2 (.dyr) and CMPLDW (.dyd) on MVA {cons['MVA']:.6g} (|S| of the load at "
        f"v0): fractions {fr}, static {static:.6g} (P1c {cons['P1c']:.6g}, P2c "
        f"{cons['P2c']:.6g}; PFs {cons['PFs']:.6g}, Q1c {cons['Q1c']:.6g}, Q2c "
        f"{cons['Q2c']:.6g}); the fitted series impedance split as feeder Rfdr "
        f"{cons['Rfdr']:.6g} + j Xfdr {cons['Xfdr']:.6g} (X/R 1, the WECC typical feeder) "
        f"and transformer Xxf {cons['Xxf']:.6g} (the rest of the X), Fb 0 and Bss 0 (the "
        "fit's capacitors are at the load bus), fixed tap 1; motor C at fraction 0; motor D "
        "without contactors, relay or filters (as fitted), its thermal relay and frequency "
        "terms at WECC typical values (not fitted)"
    )


def cmpldw_extra(cons: dict[str, float]) -> dict[str, float]:
    """CMPLDW's names of the CMLDBLU2 fields it names otherwise (motor D's, ``frcel``)."""
    return {"frcel": cons["Frcel"], "MtpD": 1.0, "LFmD": cons["CompLF"],
            "Vtr1": cons["UVtr1"], "Vtr2": cons["UVtr2"]}  # fmt: skip


def _fmt(x: float) -> str:
    return f"{x + 0.0:.10g}"


def cmldblu2_text(bus: int, load_id: str, cons: dict[str, float]) -> str:
    """The CMLDBLU2 record (PSS/E 35 ``.dyr``), ten CONs a line.

    Parameters
    ----------
    bus : int
        The load's bus.
    load_id : str
        The load's ID in the ``.raw``.
    cons : dict
        From :func:`cmld_values`.

    Returns
    -------
    str
        The record, ending in ``/``.
    """
    vals = [_fmt(cons[n]) for n in CON_NAMES]
    head = f"{bus} 'USRLOD' '{load_id}' 'CMLDBLU2' 12 1 2 133 27 146 48 0 0"
    rows = [" ".join(vals[k : k + 10]) for k in range(0, len(vals), 10)]
    return head + "\n" + "\n".join(rows) + " /\n"


def cmpldw_text(
    bus: int, load_id: str, cons: dict[str, float], *, vn_kv: float, extra: dict | None = None
) -> str:
    """The same load as a PSLF CMPLDW record (``.dyd``; :data:`CMPLDW_NAMES` by position).

    Parameters
    ----------
    bus : int
        The load's bus.
    load_id : str
        The load's ID.
    cons : dict
        From :func:`cmld_values`.
    vn_kv : float
        The bus's base kV.
    extra : dict, optional
        CMPLDW's own fields (:func:`cmpldw_extra`); default: a composite fit's (no motor
        D, no electronics).

    Returns
    -------
    str
        The record; ``/`` continues a line.
    """
    # CMPLDW's fields that CMLDBLU2 has not: the electronic load's recovering fraction
    # (Fel = 0: unused), motor D single-phase (MtpD = 1) and its fields (FmD = 0: 0).
    if extra is None:
        extra = {"frcel": 1.0, "MtpD": 1.0}
    vals = [_fmt(cons.get(n, extra.get(n, 0.0))) for n in CMPLDW_NAMES]
    head = f'cmpldw {bus} "LOADBAYES" {_fmt(vn_kv)} "{load_id}" : #9 mva={vals[0]}'
    rows = [" ".join(vals[k : k + 10]) for k in range(1, len(vals), 10)]
    return head + " /\n" + " /\n".join(rows) + "\n"


def read_cmldblu2(path) -> dict[str, float]:
    """Read the CMLDBLU2 record of a ``.dyr`` written here (for round trips).

    Returns ``bus``, ``id`` and the CONs by name; raises ValueError when the record does
    not have the header and the 133 CONs.
    """
    from pathlib import Path

    tokens = Path(path).read_text().split("/")[0].split()
    if tokens[1:4:2] != ["'USRLOD'", "'CMLDBLU2'"] or len(tokens) != 13 + 133:
        raise ValueError(f"{path}: not a CMLDBLU2 record with 133 CONs")
    vals = list(map(float, tokens[13:]))
    return {"bus": int(tokens[0]), "id": tokens[2].strip("'")} | dict(
        zip(CON_NAMES, vals, strict=True)
    )
