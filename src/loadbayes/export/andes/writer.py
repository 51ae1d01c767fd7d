"""Export a fitted ZIP or composite load as an ANDES case (xlsx or json, ANDES's own writers).

The case (:mod:`loadbayes.export.andes.case`) is the load on its bus behind a stand-in
network whose source voltage puts the load bus at ``v0``: by default the load on bus 1 fed
from an infinite bus (bus 2) through ``z_src`` (0.01 + 0.1j p.u. on the system base), with
``bus`` given the harness's three buses (an infinite bus and two lines, load bus ``bus``):

- the static part as a ``PQ`` (its power at ``v0``) replaced in the time domain by a
  ``ZIP`` with ``kpz, kpi, kpp = 100 (a1, a2, a3)`` and ``kqz, kqi, kqp = 100 (a4, a5, a6)``;
  ANDES refers the shares to the power-flow voltage, which is ``v0`` here;
- for ``model="composite"`` the motor as a ``Motor3`` on its own rating
  ``Sn = mva_m * base_mva``, load torque ``c1, c2, c3`` on the system base
  (docs/andes.md), and, when ``q_c`` is not zero, a ``Shunt`` with ``b = q_c / v0^2``.

Copy the load bus's devices into your own network, or run the case as it is with a
``Fault`` added. ANDES solves the case on its own (``andes run case.json``): the case's
``_config`` sets ``PFlow.linsolve = 1`` and ``TDS.linsolve = 1``. Without them ANDES 2.0's
default KLU solver crashes the interpreter on any case with a running ``Motor3``: the motor
enters the power flow at ANDES's start values (``vd = vq = Iq = 0``), ten Jacobian entries
are exactly zero at the first Newton step and absent from the sparsity pattern KLU
factorises symbolically, and reusing that factorisation at the second step, where they
are not zero, segfaults in ``klu.numeric`` (ANDES's own help for ``linsolve`` reads
"enable when KLU segfaults"). The posterior summary and these notes go to a sidecar
``<case file name>.summary.txt``.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from loadbayes.export.andes.case import SINGLE_LOAD_BUS, VN_KV
from loadbayes.io.atomic import atomic_write

__all__ = ["CASE_CONFIG", "DEFAULT_BUS", "FORMAT", "SUFFIXES", "write"]

FORMAT = "andes"
SUFFIXES: tuple[str, ...] = (".xlsx", ".json")
#: The load bus idx when none is given: the single-bus case (the source bus is idx 2).
DEFAULT_BUS = SINGLE_LOAD_BUS
#: Configuration written into the case's ``_config`` so that ANDES alone solves it.
CASE_CONFIG = {"PFlow": {"linsolve": 1}, "TDS": {"linsolve": 1}}

_MODELS = ("zip", "composite")


def _values_with_power(values: Mapping[str, float], options: Mapping[str, Any]) -> dict:
    """The parameter set with its powers in p.u. of the case's system base ``base_mva``.

    The posterior's ``p0, q0, q_c`` are per unit of ``s_base_mva`` (the fit's base, or
    ``--s-base``); without it they are taken as per unit of the system base (100 MVA).
    """
    out = dict(values)
    base = float(options.get("base_mva", 100.0))
    s_base = options.get("s_base_mva")
    scale = 1.0 if s_base is None else float(s_base) / base
    for key in ("p0", "q0", "q_c"):
        if key in out:
            out[key] = float(out[key]) * scale
    for key, option in (("p0", "p_mw"), ("q0", "q_mvar")):
        if key not in out:
            if option not in options:
                raise ValueError(
                    f"the posterior has no '{key}'; give the load's power as the option "
                    f"'{option}' (MW or Mvar at v0)"
                )
            out[key] = float(options[option]) / base
    return out


def _sidecar(out: Path) -> Path:
    # Named after the whole file name, so an .xlsx and a .json export never share one.
    return out.with_name(out.name + ".summary.txt")


#: Why a model of parts has no ANDES case (ANDES 1.9's load models: PQ, ZIP, FLoad, and
#: the motors Motor3, Motor5; no composite load, no single-phase motor, no tripping
#: electronics).
_PARTS_REFUSED = {
    "cmld-lite": (
        "ANDES has no composite load (CMLD) and no model of motor D (single-phase air "
        "conditioners that stall) or of power electronics that trip: a cmld-lite fit has "
        "no ANDES case; export it --to psse (CMLDBLU2 with every part) or --to pandapower "
        "(its power flow)"
    ),
    "slm": (
        "ANDES has no load behind a feeder impedance in one model, and this export does "
        "not build the slm's feeder as a bus and a line: an slm fit has no ANDES case; "
        "export it --to psse (CMLDBLU2) or --to pandapower (its power flow)"
    ),
}


def write(
    values: Mapping[str, float],
    out: Path,
    *,
    model: str,
    header: Sequence[str],
    options: Mapping[str, Any],
) -> list[Path]:
    """Write one parameter set as an ANDES case, and its summary as a sidecar.

    Parameters
    ----------
    values : mapping
        One parameter set (naming contract): ``a1..a6``, ``p0``, ``q0``, optional ``v0``
        and ``q_c``; for ``"composite"`` also ``f_m, rs, xs, xm, rr, xr, h_s, t0`` and
        optional ``a, b, c, f_hz``.
    out : Path
        The case file; its suffix (``.xlsx`` or ``.json``) picks ANDES's writer.
    model : {"zip", "composite"}
        The fitted model. ``"exponential"`` is refused: ANDES has no exponential static
        load.
    header : sequence of str
        Lines of the posterior summary, written to the sidecar.
    options : mapping
        ``base_mva`` (the case's system base, default 100), ``s_base_mva`` (MVA per p.u.
        of the posterior's powers; default ``base_mva``), ``vn_kv`` (every bus's kV,
        default 110), ``bus`` (load bus idx of the three-bus case; None or absent: the
        single-bus case, load bus 1), ``z_src`` (source impedance, complex, default
        0.01 + 0.1j), ``p_mw``/``q_mvar`` when ``values`` has no ``p0``/``q0``.
        ``case``: an ANDES case file, or a name of ANDES's case library
        (``kundur/kundur_full.xlsx``), to place the load in, on its bus ``bus``; the
        case's system base and the bus's ``Vn`` replace ``base_mva`` and ``vn_kv``.
        ``load_mode``: "replace" or "add", what becomes of the bus's own PQ load in
        ``case`` (required when it has one). ``warnings``: the export's checks, written
        into the loadbayes PQ's ``name`` (a comment cell). ``said``: a list the note on
        the bus's own load is appended to.

    Returns
    -------
    list of Path
        The case file and the sidecar, each written atomically (the caller has checked
        ``--force``, so existing files are replaced).

    Raises
    ------
    ValueError
        For another model or suffix, missing or inconsistent values.
    """
    if model in _PARTS_REFUSED:
        raise ValueError(_PARTS_REFUSED[model])
    if model not in _MODELS:
        hint = " (ANDES has no exponential static load)" if model == "exponential" else ""
        raise ValueError(f"ANDES export takes model 'zip' or 'composite', not {model!r}{hint}")
    out = Path(out)
    if out.suffix.lower() not in SUFFIXES:
        raise ValueError(f"ANDES export writes {' or '.join(SUFFIXES)}, not '{out.suffix}'")

    from loadbayes.export.andes.case import CompositeCase

    base = float(options.get("base_mva", 100.0))
    vn_kv = float(options.get("vn_kv") or VN_KV)
    z_src = complex(options.get("z_src", complex(0.01, 0.1)))
    # --bus not given reaches here as None: the single-bus case.
    bus = int(options["bus"]) if options.get("bus") is not None else None
    host = None
    if options.get("case") is not None:
        if bus is None:
            raise ValueError("a load placed in a case needs its bus: give --bus with --case")
        host, base, vn_kv = _load_host(str(options["case"]), bus)
    case = CompositeCase.from_values(
        _values_with_power({**values}, {**options, "base_mva": base}),
        with_motor=model == "composite",
        base_mva=base,
        z_src=z_src,
        vn_kv=vn_kv,
    )
    own = _own_load(host, bus, str(options.get("case")), options.get("load_mode"))
    system, devices = _build(case, bus, host)
    warns = list(options.get("warnings") or ())
    if warns:
        # A comment cell: the loadbayes PQ's name (ANDES reads every sheet as a model, so
        # a notes sheet would not load).
        uid = system.PQ.idx2uid(devices["pq"])
        system.PQ.name.v[uid] = "loadbayes warning: " + " | ".join(warns)
    if own:
        header = [*header, own]
        said = options.get("said")
        if isinstance(said, list):
            said.append(own)
    with atomic_write(out, force=True) as tmp:
        _write_case(system, Path(tmp))
    sidecar = _sidecar(out)
    with atomic_write(sidecar, force=True, mode="w") as fh:
        fh.write(_summary(header, values, case, devices, out, model))
    return [out, sidecar]


def _own_load(host: Any, bus: int | None, name: str, mode: Any) -> str | None:
    """What happens to the PQ loads the case already has on ``bus``, said in one line.

    ``mode`` "replace" puts them out of service (``u = 0``: the fitted load is the
    bus's load), "add" keeps them (the bus draws both); a bus with a load of its own and
    neither is refused, since the load would be counted twice without a word.
    """
    if host is None:
        return None
    uids = [k for k, b in enumerate(host.PQ.bus.v) if b == bus and host.PQ.u.v[k]]
    if not uids:
        return None
    base = float(host.config.mva)
    shown = ", ".join(
        f"PQ {host.PQ.idx.v[k]} ({host.PQ.p0.v[k] * base:.6g} MW, "
        f"{host.PQ.q0.v[k] * base:.6g} Mvar)"
        for k in uids
    )
    if mode == "replace":
        for k in uids:
            host.PQ.u.v[k] = 0
        return f"--case {name}: bus {bus}'s own load {shown} put out of service (--replace-load)"
    if mode == "add":
        return (
            f"--case {name}: bus {bus}'s own load {shown} kept in service, the fitted load "
            "added to it (--add-load): the bus draws both"
        )
    raise ValueError(
        f"--case {name}: bus {bus} already has a load, {shown}: give --replace-load (the "
        "fitted load replaces it) or --add-load (it is added to it)"
    )


def _load_host(name: str, bus: int) -> tuple[Any, float, float]:
    """An ANDES case to place the load in (not set up), its MVA base and the bus's kV."""
    import andes

    from loadbayes.export.andes.conventions import andes_quiet

    path = Path(name)
    if not path.is_file():
        try:
            path = Path(andes.get_case(name))
        except Exception:  # ANDES raises several types for a name it does not have
            path = None  # type: ignore[assignment]
        if path is None or not path.is_file():
            raise ValueError(f"--case {name}: neither a file nor a case of ANDES's library")
    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp, andes_quiet():
        try:
            host = andes.load(
                str(path), setup=False, no_output=True, default_config=True, output_path=tmp
            )
        except Exception as exc:  # ANDES raises many types for a file it cannot parse
            raise ValueError(
                f"--case {name}: ANDES cannot read it ({type(exc).__name__})"
            ) from None
    if host is None or not host.Bus.n:  # a text file ANDES reads as an empty system
        raise ValueError(f"--case {name}: not an ANDES case (ANDES finds no bus in it)")
    if bus not in list(host.Bus.idx.v):
        known = [] if host is None else list(host.Bus.idx.v)
        shown = ", ".join(map(str, known[:12])) + (" ..." if len(known) > 12 else "")
        raise ValueError(f"--case {name}: no bus {bus} (its buses: {shown or 'none'})")
    uid = host.Bus.idx2uid(bus)
    return host, float(host.config.mva), float(host.Bus.Vn.v[uid])


def _build(case: Any, bus: int | None, host: Any = None) -> tuple[Any, dict[str, Any]]:
    import andes

    from loadbayes.export.andes.case import add_composite, add_single_bus, add_to_case
    from loadbayes.export.andes.conventions import andes_quiet

    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp, andes_quiet():
        if host is not None:
            system = host
            ids = add_to_case(system, case, bus)
        elif bus is None:
            system = andes.System(no_output=True, default_config=True, output_path=tmp)
            ids = add_single_bus(system, case)
        else:
            system = andes.System(no_output=True, default_config=True, output_path=tmp)
            ids = add_composite(system, case, load_bus=bus)
        for routine, fields in CASE_CONFIG.items():
            for key, value in fields.items():
                setattr(getattr(system, routine).config, key, value)
    return system, ids


def _write_case(system: Any, path: Path) -> None:
    from andes.io import json as andes_json
    from andes.io import xlsx as andes_xlsx

    from loadbayes.export.andes.conventions import andes_quiet

    writer = andes_xlsx if path.suffix.lower() == ".xlsx" else andes_json
    with andes_quiet():
        ok = writer.write(system, str(path), overwrite=True)
    if not ok:
        raise RuntimeError(f"ANDES did not write {path}")


def _summary(header, values, case, devices, out: Path, model: str) -> str:
    lines = [f"# loadbayes export to ANDES: {out.name} ({model})", "#"]
    lines += [f"# {line}" for line in header]
    lines += ["#", "# Parameter set exported (naming contract, system p.u.):"]
    lines += [f"#   {k} = {float(v):.10g}" for k, v in sorted(values.items())]
    if devices["net_bus"] is None:
        where = (
            "a bus of the case given (its power flow sets the bus's voltage, the ZIP's reference)"
        )
    elif devices["net_bus"] == devices["load_bus"] + 1:
        z = case.z_src
        where = (f"fed from the infinite bus idx {devices['net_bus']} through "
                 f"z = {z.real:g} + j{z.imag:g} p.u. (put a Fault on the load bus)")  # fmt: skip
    else:
        where = f"network bus idx {devices['net_bus']} (put a Fault there)"
    lines += [
        "#",
        f"# Load bus idx {devices['load_bus']} at v0 = {case.v0:.6g} p.u.; {where}; "
        f"base {case.base_mva:g} MVA, buses at {case.vn_kv:g} kV.",
        f"# The load: {case.p0 * case.base_mva:.8g} MW, {case.q0 * case.base_mva:.8g} Mvar at "
        f"v0; motor {case.motor_pq.real * case.base_mva:.8g} MW.",
        f"# PQ {devices['pq']} (static part at v0): p0 = {case.static_pq.real:.10g}, "
        f"q0 = {case.static_pq.imag:.10g}; ZIP {devices['zip']} replaces it in the time "
        "domain.",
    ]
    if case.motor is not None:
        fields = ", ".join(f"{k}={v:.6g}" for k, v in case.motor3().items())
        lines += [
            f"# Motor3 {devices['motor']}: {fields}",
            f"#   mva_m = {case.mva_m:.10g} (system p.u.), t0 = {case.t0:.10g} (own base); "
            "c1..c3 are on the system base (docs/andes.md).",
        ]
    if devices["shunt"] is not None:
        b = case.q_c / case.v0**2
        lines.append(f"# Shunt {devices['shunt']}: b = {b:.10g} (q_c = {case.q_c:.10g} at v0)")
    lines += [
        "#",
        "# ANDES alone solves it: `andes run <case>` or, with a fault,",
        "#   ss = andes.load(path, setup=False); ss.add('Fault', {...}); ss.setup()",
        "#   ss.PFlow.run(); ss.TDS.config.tf = 2; ss.TDS.run()",
        "# The case's _config sets PFlow.linsolve = TDS.linsolve = 1: ANDES 2.0's KLU",
        "# otherwise segfaults on a running Motor3 (docs/andes.md). With loadbayes at hand,",
        "# loadbayes.export.andes.conventions.solve_power_flow(ss) also seeds the motor",
        "# at its steady state before ANDES's Newton steps.",
        "",
    ]
    return "\n".join(lines)
