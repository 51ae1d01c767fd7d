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
- CON J+97 .. J+132 (motor D, the single-phase motor, and the rest): no reachable
  source names them one by one for CMLDBLU2 (CMLDBLU1 has 132 CONs, CMLDBLU2 133, and
  where the extra one sits could not be confirmed). They are written as 0: motor D's
  fraction ``Fmd`` is 0, so PSS/E should not use them; if PSS/E refuses a zero there,
  take those CONs from the Load Model Data Tool's typical record.
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
    "cmldblu2_text",
    "cmpldw_text",
    "read_cmldblu2",
]

_MOTOR = ("Mtp{m}", "LFm{m}", "Rs{m}", "Ls{m}", "Lp{m}", "Lpp{m}", "Tpo{m}", "Tppo{m}",
          "H{m}", "Etrq{m}", "Vtr1{m}", "Ttr1{m}", "Ftr1{m}", "Vrc1{m}", "Trc1{m}",
          "Vtr2{m}", "Ttr2{m}", "Ftr2{m}", "Vrc2{m}", "Trc2{m}")  # fmt: skip
#: CON J .. J+132 of CMLDBLU2, by name (``J+k`` where no source names the field).
CON_NAMES: tuple[str, ...] = (
    "MVA", "Bss", "Rfdr", "Xfdr", "Fb", "Xxf", "Tfixhs", "Tfixls", "LTC", "Tmin", "Tmax",
    "Step", "Vmin", "Vmax", "Tdel", "Ttap", "Rcomp", "Xcomp", "Fma", "Fmb", "Fmc", "Fmd",
    "Fel", "PFel", "Vd1", "Vd2", "PFs", "P1e", "P1c", "P2e", "P2c", "Pfrq", "Q1e", "Q1c",
    "Q2e", "Q2c", "Qfrq",
    *(f.format(m="A") for f in _MOTOR),
    *(f.format(m="B") for f in _MOTOR),
    *(f.format(m="C") for f in _MOTOR),
    *(f"J+{k}" for k in range(97, 133)),
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


def cmpldw_text(bus: int, load_id: str, cons: dict[str, float], *, vn_kv: float) -> str:
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

    Returns
    -------
    str
        The record; ``/`` continues a line.
    """
    # CMPLDW's fields that CMLDBLU2 has not: the electronic load's recovering fraction
    # (Fel = 0: unused), motor D single-phase (MtpD = 1) and its fields (FmD = 0: 0).
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
