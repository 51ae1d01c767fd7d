"""Export to PSS/E: a version-33 ``.raw`` case with the load, and the composite's dynamics.

A model of parts (``slm``, ``cmld-lite``) goes out as CMLDBLU2 with every fraction
(:func:`loadbayes.export.cmld.parts_cmld_values`; :mod:`loadbayes.export.partsload` says
where each number comes from), the ``.raw``'s load ``'1'`` the whole load at the
recorded bus. A composite load goes out, by default
(``options["motor_record"] = "cmldblu2"``), as the WECC composite load record CMLDBLU2
in the ``.dyr`` (PSS/E 35; the fitted motor as motor A, the static part on the record's
static-load fields, every other fraction zero) with
the same numbers as a PSLF CMPLDW record in a ``.dyd``; see
:mod:`loadbayes.export.cmld` for the fields and their sources. The ``.raw`` then holds
one load ``'1'`` drawing the whole load's P, Q at v0 (the power flow's constant power;
CMLDBLU2 takes it over at initialisation). ``motor_record = "cim5bl"`` writes the
layout below instead:

The ``.raw`` (PSS/E 33 format) is a whole minimal case: a swing bus with a generator, the
load bus, a short branch between them, the load record(s), and every other section
empty. The load record (v33 fields ``I, 'ID', STATUS, AREA, ZONE, PL, QL, IP, IQ, YP,
YQ, OWNER, SCALE, INTRPT``) holds the static polynomial of
:func:`~loadbayes.export.loadparts.load_parts`, PSS/E's convention being

    P(V) = PL + IP V + YP V^2,     Q(V) = QL + IQ V - YQ V^2     (MW, Mvar; V in p.u.)

so ``PL = pp, IP = pi, YP = pz, QL = qp, IQ = qi, YQ = -qz`` (YQ is negative for an
inductive load, PSS/E's sign for admittance load). ANDES's PSS/E reader uses the same
formula, which the tests use to read the file back independently.

The composite load is two load records on the bus: ``'1'`` the static part and ``'M'``
the motor's steady-state P, Q at v0, with a CIM5BL record in the ``.dyr`` attached to
load ``'M'`` (PSS/E initialises the motor from that load's power)::

    IBUS 'CIM5BL' 'M' IT RA XA XM R1 X1 R2 X2 E1 SE1 E2 SE2 MBASE PMULT H VT TV TB D TNOM /

mapped from :class:`loadbayes.models.motor.MotorParams` (the motor's own base) as:

==========  ==========================================================================
field       value
==========  ==========================================================================
IT          1 (type 1 equivalent circuit: R1, X1 the rotor branch)
RA, XA      ``rs``, ``xs`` (stator resistance, leakage reactance)
XM          ``xm`` (magnetising reactance)
R1, X1      ``rr``, ``xr`` (rotor resistance, leakage reactance)
R2, X2      0, 0 (single cage: the third-order model has one rotor circuit)
E1 .. SE2   0 (no saturation; loadbayes's motor has none)
MBASE       the motor rating in MVA (``mva_m`` times the system base, or
            ``f_m p0 / P_motor(own base)``)
PMULT       0 (unused when MBASE > 0)
H           ``h_s`` (s, on MBASE)
VT, TV, TB  0 (no undervoltage trip)
D           ``2 a + b``: PSS/E's load torque is ``T (1 + dw)^D``; it equals loadbayes's
            ``t0 (a w^2 + b w + c)`` for a pure quadratic (D = 2), linear (1) or constant
            (0) load and matches its slope at synchronous speed otherwise
TNOM        0 (PSS/E computes the load torque from the power flow at initialisation;
            the fitted ``t0`` is in the summary)
==========  ==========================================================================

The posterior summary goes into ``<out>.summary.txt`` (PSS/E files have no room for
it); the ``.raw`` title lines name the model and the statistic. Options: ``bus``
(default 1), ``s_base_mva`` (system base, also written as SBASE; default 100), ``vn_kv``
(default 230), ``f_hz`` (the case frequency BASFRQ: the fit's, default 60), ``p_mw``,
``q_mvar``, ``force``, ``warnings`` (the export's checks, :mod:`loadbayes.export.checks`:
each a comment after the ``.raw``'s ``Q``, after the ``.dyr`` record's ``/`` and in the
``.dyd`` after ``#``), ``comments`` (lines said the same way: a planning draw's quantile).
"""

# One idea at about 445 lines: the PSS/E case and its dynamic records, with their
# round-trip readers (the docstring above is a quarter of it).
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from loadbayes.export import cmld
from loadbayes.export.loadparts import LoadParts, load_parts
from loadbayes.export.partsload import PARTS_MODELS, parts_load
from loadbayes.io.transaction import OutputSet

__all__ = [
    "EXTRA_SUFFIXES",
    "FORMAT",
    "MOTOR_RECORDS",
    "SUFFIXES",
    "VERSION",
    "read_dyr",
    "read_loads",
    "write",
]

FORMAT = "psse"
SUFFIXES = (".raw", ".dyr")
#: Written beside them for a composite load with CMLDBLU2: the PSLF CMPLDW record.
EXTRA_SUFFIXES = (".dyd",)
#: The composite load's dynamic record: the WECC composite load, or a CIM5BL motor.
MOTOR_RECORDS = ("cmldblu2", "cim5bl")
VERSION = 33

_EMPTY_SECTIONS = (
    "TRANSFORMER", "AREA", "TWO-TERMINAL DC", "VSC DC LINE", "IMPEDANCE CORRECTION",
    "MULTI-TERMINAL DC", "MULTI-SECTION LINE", "ZONE", "INTER-AREA TRANSFER", "OWNER",
    "FACTS DEVICE", "SWITCHED SHUNT", "GNE", "INDUCTION MACHINE",
)  # fmt: skip
CIM5_FIELDS = ("RA", "XA", "XM", "R1", "X1", "R2", "X2", "E1", "SE1", "E2", "SE2",
               "MBASE", "PMULT", "H", "VT", "TV", "TB", "D", "TNOM")  # fmt: skip


def _g(x: float) -> str:
    return f"{x + 0.0:.10g}"  # + 0.0: no "-0"


def _load_record(bus: int, load_id: str, p: tuple[float, float, float], q: tuple) -> str:
    # p = (pp, pi, pz), q = (qp, qi, qz)
    fields = [str(bus), f"'{load_id:<2}'", "1", "1", "1", _g(p[0]), _g(q[0]), _g(p[1]),
              _g(q[1]), _g(p[2]), _g(-q[2]), "1", "1", "0"]  # fmt: skip
    return ",".join(fields)


def _frequency(f_hz: float) -> str:
    # As written before the case took the fit's frequency: "60.0" (PSS/E's own style).
    return f"{f_hz:.1f}" if f_hz == round(f_hz, 1) else _g(f_hz)


def _raw_text(
    parts: LoadParts,
    *,
    bus: int,
    sbase: float,
    vn_kv: float,
    title: str,
    whole: bool = False,
    f_hz: float = 60.0,
) -> str:
    src = 1 if bus != 1 else 2
    p_total = float(parts.p(parts.v0)) + (parts.motor.p_mw if parts.motor else 0.0)
    if whole:
        q_total = float(parts.q(parts.v0)) + (parts.motor.q_mvar if parts.motor else 0.0)
        load = _load_record(bus, "1", (p_total, 0.0, 0.0), (q_total, 0.0, 0.0))
        note = "composite load '1' (whole P, Q at v0) + CMLDBLU2 (.dyr)"
    else:
        p_poly, q_poly = (parts.pp, parts.pi, parts.pz), (parts.qp, parts.qi, parts.qz)
        load = _load_record(bus, "1", p_poly, q_poly)
        note = "static load as PL/IP/YP, QL/IQ/YQ; motor (if any) as load 'M' + CIM5BL (.dyr)"
    bus_line = "{},'{:<12}',{},{},1,1,1,{},0.0,1.1,0.9,1.1,0.9"
    lines = [
        f"0,{_g(sbase)},{VERSION},0,0,{_frequency(f_hz)}     / PSS(R)E-33 RAW created by loadbayes",
        title[:60],
        note[:60],
        bus_line.format(src, "SOURCE", _g(vn_kv), 3, _g(parts.v0)),
        bus_line.format(bus, "LOADBAYES", _g(vn_kv), 1, _g(parts.v0)),
        "0 / END OF BUS DATA, BEGIN LOAD DATA",
        load,
    ]
    if parts.motor is not None and not whole:
        m = parts.motor
        lines.append(_load_record(bus, "M", (m.p_mw, 0.0, 0.0), (m.q_mvar, 0.0, 0.0)))
    gen = [str(src), "'1 '", _g(p_total), "0.0", "9999.0", "-9999.0", _g(parts.v0), "0",
           _g(max(sbase, 1.0)), "0.0", "1.0", "0.0", "0.0", "1.0", "1", "100.0", "9999.0",
           "-9999.0", "1", "1.0", "0", "1.0", "0", "1.0", "0", "1.0", "0", "1.0"]  # fmt: skip
    branch = [str(src), str(bus), "'1 '", "0.0", "1e-4", "0.0", "0.0", "0.0", "0.0", "0.0",
              "0.0", "0.0", "0.0", "1", "1", "0.0", "1", "1.0", "0", "1.0", "0", "1.0", "0",
              "1.0"]  # fmt: skip
    lines += [
        "0 / END OF LOAD DATA, BEGIN FIXED SHUNT DATA",
        "0 / END OF FIXED SHUNT DATA, BEGIN GENERATOR DATA",
        ",".join(gen),
        "0 / END OF GENERATOR DATA, BEGIN BRANCH DATA",
        ",".join(branch),
        "0 / END OF BRANCH DATA, BEGIN TRANSFORMER DATA",
    ]
    for k, name in enumerate(_EMPTY_SECTIONS[:-1]):
        lines.append(f"0 / END OF {name} DATA, BEGIN {_EMPTY_SECTIONS[k + 1]} DATA")
    lines += [f"0 / END OF {_EMPTY_SECTIONS[-1]} DATA", "Q"]
    return "\n".join(lines) + "\n"


def cim5_values(parts: LoadParts) -> dict[str, float]:
    """The CIM5BL constants of a composite load's motor (see the module docstring).

    Parameters
    ----------
    parts : LoadParts
        With a motor.

    Returns
    -------
    dict
        Field name -> value, in the record's order.
    """
    m = parts.motor
    if m is None:
        raise ValueError("no motor in this load")
    pr = m.params
    return dict(
        zip(
            CIM5_FIELDS,
            [
                pr.rs,
                pr.xs,
                pr.xm,
                pr.rr,
                pr.xr,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                m.mva,
                0.0,
                pr.h_s,
                0.0,
                0.0,
                0.0,
                2 * pr.a + pr.b,
                0.0,
            ],  # fmt: skip
            strict=True,
        )
    )


def write(
    values: Mapping[str, float],
    out: Path,
    *,
    model: str,
    header: Sequence[str],
    options: Mapping[str, Any],
) -> list[Path]:
    """Write the ``.raw`` (and for a composite load the ``.dyr``) and a summary sidecar.

    Parameters
    ----------
    values : mapping of str to float
        One parameter set.
    out : pathlib.Path
        The ``.raw`` file; the ``.dyr`` takes the same stem.
    model : {"zip", "exponential", "composite"}
        The model.
    header : sequence of str
        Posterior summary lines.
    options : mapping
        See the module docstring.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    ValueError
        For another model, missing parameters, or a bad bus number.
    """
    opts = dict(options)
    opts.setdefault("s_base_mva", 100.0)
    sbase = float(opts["s_base_mva"] or 100.0)
    bus = int(opts["bus"]) if opts.get("bus") is not None else 1
    if not 1 <= bus <= 999_997:
        raise ValueError(f"PSS/E bus numbers run from 1 to 999997, got {bus}")
    raw, dyr = _paths(Path(out))
    record = str(opts.get("motor_record") or "cmldblu2")
    if record not in MOTOR_RECORDS:
        raise ValueError(f"motor_record {record!r}: expected one of {', '.join(MOTOR_RECORDS)}")
    pl = None
    if model in PARTS_MODELS:
        if record != "cmldblu2":
            raise ValueError(
                f"a {model} fit goes out as CMLDBLU2 only: CIM5BL holds one motor, not "
                "its feeder, motor D or electronics"
            )
        pl = parts_load(values, model=model, options=opts)
        # The power flow's load: the whole load at the recorded bus (CMLDBLU2 takes it
        # over at initialisation), as constant power.
        parts = LoadParts(0.0, 0.0, pl.p_mw, 0.0, 0.0, pl.q_mvar, pl.v0, notes=list(pl.notes))
    else:
        parts = load_parts(values, model=model, options=opts)
    _check_record(parts)
    force = bool(opts.get("force"))
    what = header[0].split("exported: ")[-1] if header else "parameters given"
    title = f"loadbayes {model} load, {what}"
    vn_kv = float(opts.get("vn_kv") or 230.0)
    f_hz = float(opts.get("f_hz") or 60.0)
    if not (math.isfinite(f_hz) and f_hz > 0):
        raise ValueError(f"the case frequency must be a positive number, got {f_hz}")
    whole = (parts.motor is not None or pl is not None) and record == "cmldblu2"
    text = _raw_text(parts, bus=bus, sbase=sbase, vn_kv=vn_kv, title=title, whole=whole, f_hz=f_hz)
    files = {"raw": raw}
    notes = list(parts.notes)
    dyr_text = dyd_text = None
    if pl is not None:
        cons = cmld.parts_cmld_values(pl)
        _check_fields(cons, "CMLDBLU2")
        dyr_text = cmld.cmldblu2_text(bus, "1", cons)
        dyd_text = cmld.cmpldw_text(bus, "1", cons, vn_kv=vn_kv, extra=cmld.cmpldw_extra(cons))
        files["dyr"], files["dyd"] = dyr, dyr.with_suffix(".dyd")
        said = cmld.parts_note(cons)
        notes.append(said)
        # After a record's "/" a line is a comment (.dyr); "#" starts one in the .dyd.
        dyr_text = dyr_text.rstrip("\n") + f" loadbayes {model}: {said}\n"
        dyd_text += f"# loadbayes {model}: {said}\n"
    elif whole:
        cons = cmld.cmld_values(parts)
        _check_fields(cons, "CMLDBLU2")
        dyr_text = cmld.cmldblu2_text(bus, "1", cons)
        dyd_text = cmld.cmpldw_text(bus, "1", cons, vn_kv=vn_kv)
        files["dyr"], files["dyd"] = dyr, dyr.with_suffix(".dyd")
        notes.append(
            f"CMLDBLU2 (.dyr) and CMPLDW (.dyd): motor A = the fitted motor, Fma = "
            f"{cons['Fma']:.6g}; static part P1c, P2c = {cons['P1c']:.4g}, {cons['P2c']:.4g}, "
            f"Q1c, Q2c = {cons['Q1c']:.4g}, {cons['Q2c']:.4g}, PFs = {cons['PFs']:.4g}; "
            "motors B, C, D and the electronic load at fraction 0"
        )
    elif parts.motor is not None:
        cim = cim5_values(parts)
        _check_fields(cim, "CIM5BL")
        nums = " ".join(_g(v) for v in cim.values())
        dyr_text = f"{bus} 'CIM5BL' 'M' 1 {nums} /\n"
        files["dyr"] = dyr
        pr = parts.motor.params
        notes.append(
            f"CIM5BL: t0 = {parts.motor.t0:.6g} (own base), torque a, b, c = "
            f"{pr.a:.4g}, {pr.b:.4g}, {pr.c:.4g} -> D = {cim['D']:.4g}"
        )
    for line in opts.get("comments") or ():  # a planning draw's quantile and fault
        text += f"@! loadbayes: {line}\n"
        if dyr_text is not None:
            dyr_text = dyr_text.rstrip("\n") + f" loadbayes: {line}\n"
        if dyd_text is not None:
            dyd_text += f"# loadbayes: {line}\n"
    warns = list(opts.get("warnings") or [])
    if warns:
        # PSS/E (and ANDES's reader) stop at "Q"; after a record's "/" a line is a
        # comment in the .dyr; "#" starts a PSLF comment.
        text += "".join(f"@! loadbayes warning: {w}\n" for w in warns)
        if dyr_text is not None:
            dyr_text = dyr_text.rstrip("\n") + " loadbayes warning: " + " | ".join(warns) + "\n"
        if dyd_text is not None:
            dyd_text += "".join(f"# loadbayes warning: {w}\n" for w in warns)
    side = Path(out).with_name(Path(out).name + ".summary.txt")
    files["summary"] = side
    rec = next(ln for ln in text.splitlines() if ln.startswith(f"{bus},'1 '"))
    what_rec = "load record (the whole load at v0)" if whole else "load record"
    summary = "\n".join(f"# {ln}" for ln in [*header, *notes, f"{what_rec}: {rec}"]) + "\n"
    # The case, its dynamics and the summary are one output: all written, or none.
    with OutputSet(files, force=force) as outs:
        outs.temp("raw").write_text(text, encoding="utf-8")
        if dyr_text is not None:
            outs.temp("dyr").write_text(dyr_text, encoding="utf-8")
        if dyd_text is not None:
            outs.temp("dyd").write_text(dyd_text, encoding="utf-8")
        outs.temp("summary").write_text(summary, encoding="utf-8")
        return outs.commit()


def _paths(out: Path) -> tuple[Path, Path]:
    """The ``.raw`` and ``.dyr`` of ``out``: one stem, two names, never one path twice.

    ``case.raw``, ``case.dyr`` or ``case.dyd`` all give ``case.raw`` and ``case.dyr``
    (the ``.dyd`` beside them); any other name is the ``.raw`` itself, its ``.dyr``
    beside it (the command refuses other suffixes).
    """
    if out.suffix.lower() in (*SUFFIXES, *EXTRA_SUFFIXES):
        return out.with_suffix(".raw"), out.with_suffix(".dyr")
    dyr = out.with_suffix(".dyr")
    return out, (dyr if dyr != out else out.with_name(out.name + ".dyr"))


#: Largest magnitude written into a PSS/E field (MW, Mvar, p.u.): past it a value is
#: a corrupt input, not a load (the largest power systems are about 1e6 MW).
FIELD_MAX = 1e9


def _check_fields(fields: Mapping[str, float], record: str) -> None:
    for name, val in fields.items():
        if not math.isfinite(val):
            raise ValueError(f"PSS/E {record} field {name} would be {val}: not a finite number")
        if abs(val) > FIELD_MAX:
            raise ValueError(
                f"PSS/E {record} field {name} would be {val:.6g}: beyond {FIELD_MAX:g}, "
                "not a load's value"
            )


def _check_record(parts: LoadParts) -> None:
    """Every number of the load records finite and plausible; no negative load."""
    _check_fields(
        {"PL": parts.pp, "IP": parts.pi, "YP": parts.pz, "QL": parts.qp, "IQ": parts.qi,
         "YQ": -parts.qz, "V0": parts.v0},
        "load record",
    )  # fmt: skip
    if parts.motor is not None:
        _check_fields({"PL": parts.motor.p_mw, "QL": parts.motor.q_mvar}, "motor load 'M'")
    p_total = float(parts.p(parts.v0)) + (parts.motor.p_mw if parts.motor else 0.0)
    if p_total < 0:
        raise ValueError(
            f"the load draws P = {p_total:.6g} MW at v0: a negative load is a generator; "
            "PSS/E export takes loads that consume power (check p0)"
        )


def read_loads(path: str | Path) -> dict[str, dict[str, float]]:
    """Read the load records of a v33 ``.raw`` written by :func:`write` (for round trips).

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.raw``.

    Returns
    -------
    dict
        Load ID -> ``{"bus", "pl", "ql", "ip", "iq", "yp", "yq"}``.
    """
    lines = Path(path).read_text().splitlines()
    start = next(k for k, ln in enumerate(lines) if "BEGIN LOAD DATA" in ln) + 1
    out = {}
    for ln in lines[start:]:
        if ln.startswith("0 /"):
            break
        f = [c.strip() for c in ln.split(",")]
        keys = ("pl", "ql", "ip", "iq", "yp", "yq")
        out[f[1].strip("'").strip()] = {"bus": int(f[0])} | dict(
            zip(keys, map(float, f[5:11]), strict=True)
        )
    return out


def read_dyr(path: str | Path) -> dict[str, float]:
    """Read the CIM5BL record of a ``.dyr`` written by :func:`write` (for round trips).

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.dyr``.

    Returns
    -------
    dict
        ``bus``, ``id``, ``IT`` and the CIM5BL constants by name.
    """
    text = Path(path).read_text().split("/")[0].split()
    if text[1] != "'CIM5BL'":
        raise ValueError(f"{path}: not a CIM5BL record")
    vals = list(map(float, text[4:]))
    return {"bus": int(text[0]), "id": text[2].strip("'"), "IT": int(text[3])} | dict(
        zip(CIM5_FIELDS, vals, strict=True)
    )
