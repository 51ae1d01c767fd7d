"""Export to pandapower: the fitted ZIP on a net's load, written as a pandapower JSON net.

pandapower (checked on 3.5) models a load's voltage dependence as

    P(V) = p_mw (z V^2 + i V + (1 - z - i)),   z = const_z_p_percent / 100,
                                                i = const_i_p_percent / 100

(and Q with ``const_z_q_percent``, ``const_i_q_percent``), V in per unit of the bus's
``vn_kv``. So ``p_mw = P(1)``, ``z = pz / p_mw``, ``i = pi / p_mw`` from
:func:`~loadbayes.export.loadparts.load_parts` (which refers the ZIP from V/v0 to V).

What pandapower does with unusual shares, and what this export does about it:

- ``z + i > 100 %`` (a negative constant-power share) is refused by pandapower's power
  flow (``ValueError`` in ``build_bus``): refused here, before writing, with the shares.
- A negative Z or I share passes pandapower's check and its formula stays exact: written,
  with a note in the summary.
- Several in-service loads on one bus: pandapower averages their Z and I shares
  *unweighted* by power, so a fitted load sharing its bus with loads of other shares
  would be misrepresented: refused.
- ``p_mw <= 0`` (or ``q_mvar = 0`` with non-zero Q shares): the percentages are
  undefined; refused.

The composite load is three elements on the bus, each from
:func:`~loadbayes.export.loadparts.load_parts`:

- the static part as the ``load`` above, with the fitted shares (``a1 .. a6`` of
  ``(1 - f_m) p0`` and of ``q0 - q_m + q_c``) referred from ``V/v0`` to V;
- the shunt compensation ``q_c`` as a ``shunt`` (constant impedance,
  ``q_mvar = -q_c / v0^2`` at 1 p.u.);
- the motor at its steady state at v0 (``f_m p0`` MW, ``mva Q_m(v0)`` Mvar), as
  ``options["motor_as"]`` says: ``"power"`` (default) a pandapower ``motor`` element,
  constant power in the power flow; ``"impedance"`` a ``shunt`` drawing the same P, Q
  at v0 (``p_mw = P_m / v0^2``, ``q_mvar = Q_m / v0^2`` at 1 p.u.). A power flow has
  no slip: the first is right near v0 and for a motor that rides through, the second
  for a deep sag where the motor stalls. The dynamics belong to PSS/E and ANDES.

Options: ``net`` (a pandapower JSON net to write into; default a one-bus net built here:
an ext_grid and the load on a bus of ``vn_kv``, default 20 kV), ``load_index`` (the load
to overwrite in the given net; default a new load on ``bus``, default 0), ``s_base_mva``,
``p_mw``, ``q_mvar``, ``force``. The posterior summary goes to ``<out>.summary.txt`` and
into the net's ``name`` (the export's ``warnings`` first).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from loadbayes.export.loadparts import LoadParts, load_parts
from loadbayes.export.partsload import PARTS_MODELS, parts_load
from loadbayes.io.atomic import atomic_write
from loadbayes.io.errors import DataError

__all__ = ["FORMAT", "MOTOR_AS", "SUFFIXES", "percentages", "write"]

FORMAT = "pandapower"
SUFFIXES = (".json",)
_TOL = 1e-9


def percentages(parts: LoadParts) -> dict[str, float]:
    """The load columns pandapower takes for a static polynomial.

    Parameters
    ----------
    parts : LoadParts
        From :func:`~loadbayes.export.loadparts.load_parts`.

    Returns
    -------
    dict
        ``p_mw, q_mvar, const_z_p_percent, const_i_p_percent, const_z_q_percent,
        const_i_q_percent``.

    Raises
    ------
    ValueError
        For shares pandapower cannot hold (see the module docstring).
    """
    p_mw = parts.pz + parts.pi + parts.pp
    q_mvar = parts.qz + parts.qi + parts.qp
    if not p_mw > 0:
        raise ValueError(
            f"the load draws P = {p_mw:.6g} MW at 1 p.u.: pandapower's shares need P > 0"
        )
    out = {
        "p_mw": p_mw,
        "q_mvar": q_mvar,
        "const_z_p_percent": 100 * parts.pz / p_mw,
        "const_i_p_percent": 100 * parts.pi / p_mw,
    }
    if abs(q_mvar) > _TOL:
        out["const_z_q_percent"] = 100 * parts.qz / q_mvar
        out["const_i_q_percent"] = 100 * parts.qi / q_mvar
    elif abs(parts.qz) > _TOL or abs(parts.qi) > _TOL:
        raise ValueError("Q is zero at 1 p.u. but voltage dependent: pandapower cannot hold it")
    else:
        out["const_z_q_percent"] = out["const_i_q_percent"] = 0.0
    for ch in ("p", "q"):
        z, i = out[f"const_z_{ch}_percent"], out[f"const_i_{ch}_percent"]
        if z + i > 100 + 1e-9:
            raise ValueError(
                f"{ch.upper()}: constant-impedance {z:.4g} % + constant-current {i:.4g} % "
                f"exceed 100 % (a negative constant-power share, {100 - z - i:.4g} %), which "
                "pandapower refuses; export another statistic (--stat median), or refit "
                "with shares kept in [0, 1] (fit composite --shares bounded; fit zip "
                "--prior)"
            )
    return out


#: How the composite load's motor enters the power flow (see the module docstring).
MOTOR_AS = ("power", "impedance")


def _build_net(options: Mapping[str, Any]):
    import pandapower as pp

    if options.get("net"):
        path = str(options["net"])
        if not Path(path).is_file():
            raise DataError("pandapower net not found", path)
        try:
            net = pp.from_json(path)
        except Exception as exc:  # pandapower raises many types for a bad file
            raise DataError(f"not a pandapower JSON net ({exc})", path) from None
        return net, path
    net = pp.create_empty_network(name="loadbayes export")
    bus = pp.create_bus(net, vn_kv=float(options.get("vn_kv") or 20.0), name="load bus")
    pp.create_ext_grid(net, bus, vm_pu=1.0)
    return net, None


def _power_flow_of_parts(values, model: str, options: Mapping[str, Any]) -> LoadParts:
    """A model of parts as pandapower holds it: its whole P, Q at the bus, constant power.

    The power flow's load is the recorded bus's P, Q at v0
    (:func:`~loadbayes.export.partsload.parts_load`: the load bus's plus the feeder's
    losses). Its feeder, motors, motor D and electronics have no pandapower element (a
    power flow has no dynamics); they go out in the PSS/E export's CMLDBLU2.
    """
    pl = parts_load(values, model=model, options=options)
    note = (
        f"{model}: pandapower holds the power flow only: the whole load {pl.p_mw:.6g} MW, "
        f"{pl.q_mvar:.6g} Mvar at v0 as constant power; its feeder, motors, motor D and "
        "electronics are not in the net (export --to psse writes them as CMLDBLU2)"
    )
    return LoadParts(0.0, 0.0, pl.p_mw, 0.0, 0.0, pl.q_mvar, pl.v0, notes=[*pl.notes, note])


def write(
    values: Mapping[str, float],
    out: Path,
    *,
    model: str,
    header: Sequence[str],
    options: Mapping[str, Any],
) -> list[Path]:
    """Write the load onto a pandapower net saved as JSON, and a summary sidecar.

    Parameters
    ----------
    values : mapping of str to float
        One parameter set.
    out : pathlib.Path
        The JSON net to write.
    model : {"zip", "exponential", "composite"}
        The model.
    header : sequence of str
        Posterior summary lines.
    options : mapping
        See the module docstring.

    Returns
    -------
    list of pathlib.Path
        The net and the summary sidecar.

    Raises
    ------
    ValueError
        For shares pandapower cannot hold, or a load index or bus not in the net.
    """
    import pandapower as pp

    if model in PARTS_MODELS:
        parts = _power_flow_of_parts(values, model, options)
    else:
        parts = load_parts(values, model=model, options=options)
    motor_as = str(options.get("motor_as") or "power")
    if motor_as not in MOTOR_AS:
        raise ValueError(f"motor_as {motor_as!r}: expected one of {', '.join(MOTOR_AS)}")
    static = parts
    if parts.motor is not None:
        # The load holds the static part alone; the shunt and the motor are elements.
        qz, qi, qp = parts.without_shunt()
        static = LoadParts(parts.pz, parts.pi, parts.pp, qz, qi, qp, parts.v0)
    cols = percentages(static)
    net, src = _build_net(options)
    if "const_z_q_percent" not in net.load.columns:
        # pandapower < 2.14 (or a net saved by it): one pair of shares for P and Q.
        same = all(abs(cols[f"const_{k}_p_percent"] - cols[f"const_{k}_q_percent"]) < 1e-9
                   for k in ("z", "i"))  # fmt: skip
        if not same:
            raise ValueError(
                f"pandapower {pp.__version__} has one const_z_percent / const_i_percent for "
                "both P and Q; the fitted P and Q shares differ (pandapower >= 2.14 needed)"
            )
        cols = {"p_mw": cols["p_mw"], "q_mvar": cols["q_mvar"],
                "const_z_percent": cols["const_z_p_percent"],
                "const_i_percent": cols["const_i_p_percent"]}  # fmt: skip
    idx = options.get("load_index")
    if idx is not None:
        if int(idx) not in net.load.index:
            raise ValueError(
                f"load index {idx} is not in the net {src or ''} (has {list(net.load.index)})"
            )
        idx = int(idx)
        bus = int(net.load.at[idx, "bus"])
        for k, v in cols.items():
            net.load.at[idx, k] = v
        net.load.at[idx, "name"] = "loadbayes fit"
    else:
        bus = int(options["bus"]) if options.get("bus") is not None else int(net.bus.index[0])
        if bus not in net.bus.index:
            raise ValueError(f"bus {bus} is not in the net")
        idx = pp.create_load(net, bus, name="loadbayes fit", **cols)
    others = net.load[(net.load.bus == bus) & net.load.in_service & (net.load.index != idx)]
    if len(others):
        raise ValueError(
            f"bus {bus} holds other in-service loads ({list(others.index)}): pandapower "
            "averages the Z and I shares of a bus's loads without weighting them by power, "
            "so the fitted shares would be changed; merge or move them first"
        )
    notes = list(parts.notes)
    if min(v for k, v in cols.items() if k.endswith("percent")) < 0:
        notes.append("a Z or I share is negative: pandapower takes it as is (exact)")
    if parts.motor is not None:
        m, v0 = parts.motor, parts.v0
        if parts.q_c:
            pp.create_shunt(net, bus, q_mvar=-parts.q_c / v0**2, p_mw=0.0,
                            name="loadbayes shunt compensation")  # fmt: skip
        if motor_as == "power":
            pp.create_motor(
                net, bus, pn_mech_mw=m.p_mw, cos_phi=m.p_mw / (m.p_mw**2 + m.q_mvar**2) ** 0.5,
                efficiency_percent=100.0, loading_percent=100.0, name="loadbayes motor",
                sn_mva=m.mva,
            )  # fmt: skip
        else:
            pp.create_shunt(net, bus, q_mvar=m.q_mvar / v0**2, p_mw=m.p_mw / v0**2,
                            name="loadbayes motor (constant impedance at v0)")  # fmt: skip
        notes.append(
            f"motor as constant {motor_as} at v0: {m.p_mw:.6g} MW, {m.q_mvar:.6g} Mvar; "
            f"shunt compensation {parts.q_c:.6g} Mvar at v0 (a pandapower shunt)"
        )
    lines = [*header, *notes, f"pandapower load {idx} on bus {bus}: " + ", ".join(
        f"{k} = {v:.8g}" for k, v in cols.items())]  # fmt: skip
    # The export's warnings first, so that the name's 2,000 characters always hold them.
    warns = [f"warning: {w}" for w in options.get("warnings") or ()]
    named = [*warns, *(ln for ln in lines if ln not in warns)]
    net.name = "loadbayes export | " + " | ".join(named)[:2000]
    force = bool(options.get("force"))
    with atomic_write(out, force=force) as tmp:
        pp.to_json(net, str(tmp))
    side = out.with_name(out.name + ".summary.txt")
    with atomic_write(side, force=force, mode="w") as fh:
        fh.write("\n".join(f"# {ln}" for ln in lines) + "\n")
    return [Path(out), side]
