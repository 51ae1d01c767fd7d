"""``loadbayes export``: a posterior into a simulator's files (pandapower, PSS/E, ANDES).

One idea needs these 413 lines: ``loadbayes export``, its posterior read and checked (a
JSON summary or NetCDF draws), the values picked and said, then one writer.
A standalone click command (it does not import :mod:`loadbayes.cli`); ``cli.py``
attaches it. The format writers are imported only once chosen.

One idea at about 625 lines: one export, from reading and checking the posterior (half of
it: a JSON file may hold anything) through the checks of :mod:`loadbayes.export.checks`
to one transaction of every file of every draw (a statistic, N draws, or the planning
ensemble's draws at quantiles of a predicted fault, picked by
:mod:`loadbayes.export.planning`). Splitting the posterior reader out is the next step
when it grows.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
from pathlib import Path

import click

from loadbayes.commands.options import OneLineCommand
from loadbayes.commands.output import UserError, output_transaction, user_errors
from loadbayes.export.bases import BASE_KEYS, resolve_bases
from loadbayes.io.errors import DataError

__all__ = ["export_cmd", "pick_values", "summary_lines"]

#: Largest parameter magnitude exported (shares, p.u., MW, seconds): past it a value is
#: a corrupt file, and products of it overflow in the writers.
VALUE_MAX = 1e12
#: Smallest load level exported (per unit): below it products of it underflow to 0 (p0
#: 1e-300 was a ZeroDivisionError in the pandapower writer).
P0_MIN = 1e-9
#: The bases a network can have: 1 VA to 1 TVA, 1 V to 2000 kV.
BASE_RANGE = {"--s-base": (1e-6, 1e6, "MVA"), "--vn-kv": (1e-3, 2000.0, "kV")}
_STAT = re.compile(r"^(mean|median|q(\d{1,2}(?:\.\d+)?))$")
_MODEL_NAMES = {"zip": "zip", "exp": "exponential", "exponential": "exponential",
                "composite": "composite"}  # fmt: skip


def _read_posterior(path: str):
    """(model, {name: pooled draws or None}, {name: summary row}, settings, interval, fit id).

    The fit id is the one the file holds (None when written before fit ids).
    """
    import json

    import numpy as np

    from loadbayes.io.errors import DataError

    p = Path(path)
    if not p.is_file():
        raise DataError("file not found", path)
    if p.suffix.lower() in (".nc", ".netcdf", ".nc4"):
        from loadbayes.posterior import Posterior

        try:
            post = Posterior.from_netcdf(p)
        except Exception as exc:  # xarray/netCDF raise many types for a bad file
            raise DataError(f"not a loadbayes NetCDF posterior ({exc})", path) from None
        draws = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in post.draws.items()}
        summary = {
            k: {"mean": float(d.mean()), "sd": float(d.std()),
                "hdi_low": float(np.quantile(d, 0.025)), "hdi_high": float(np.quantile(d, 0.975))}
            for k, d in draws.items()
        }  # fmt: skip
        _add_convergence(post, summary)
        interval = "2.5% and 97.5% quantiles"
        return post.model, draws, summary, dict(post.settings), interval, post.written_fit_id
    if p.suffix.lower() in (".parquet", ".pq", ".csv"):
        # A fleet's table (or a data file) holds summaries per bus, not one posterior.
        raise DataError(
            "not a loadbayes posterior JSON or NetCDF but a table: export takes one fit's "
            "result (a fleet's bus: fit zip on that bus's rows with --json or --netcdf)",
            path,
        )
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
        params = doc["parameters"]
        model = doc["model"]
    except RecursionError:
        raise DataError("not a loadbayes posterior JSON (nested too deeply)", path) from None
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise DataError("not a loadbayes posterior JSON (no 'model'/'parameters')", path) from None
    fid = doc.get("fit_id") if isinstance(doc, dict) else None
    return (*_checked_json(doc, params, model, path), fid if isinstance(fid, str) else None)


def _add_convergence(post, summary: dict) -> None:
    """R-hat and bulk ESS of the exported quantities, from the NetCDF's chains."""
    from loadbayes.export.checks import EXPORTED

    names = [n for n in EXPORTED if n in summary]
    if not names:
        return
    try:
        table = post.summary(var_names=names)
    except (ValueError, FloatingPointError):  # too few draws for the diagnostics
        return
    for name, row in table.iterrows():
        summary[name]["r_hat"] = float(row["r_hat"])
        summary[name]["ess_bulk"] = float(row["ess_bulk"])


def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _checked_json(doc: dict, params, model, path: str):
    """The parts of a posterior JSON the exports use, each checked and located by key.

    A file edited by hand (or by a tool) may hold anything: a list where the parameters
    go, strings for numbers, NaN or Infinity (Python's json reads both). Each is refused
    here in one line naming the key, rather than failing deep in a writer.
    """
    from loadbayes.io.errors import DataError

    if not isinstance(model, str):
        raise DataError(f"'model' is {type(model).__name__}, expected a name", path)
    if not isinstance(params, dict):
        raise DataError(f"'parameters' is {type(params).__name__}, expected an object", path)
    summary = {}
    for name, row in params.items():
        if not isinstance(row, dict) or row.get("mean") is None:
            continue
        for key in ("mean", "sd", "hdi_low", "hdi_high"):
            val = row.get(key)
            if key != "mean" and val is None:
                continue
            where = f"parameters.{name}.{key}"
            if not _number(val):
                raise DataError(f"{where} is {_shown(val)}, expected a number", path)
            if key == "mean" and not math.isfinite(val):
                raise DataError(f"{where} is {val}, expected a finite number", path)
        summary[name] = row
    settings = doc.get("settings", {})
    if settings is None:
        settings = {}
    if not isinstance(settings, dict):
        raise DataError(f"'settings' is {type(settings).__name__}, expected an object", path)
    for key in ("v0", "p0", "q0"):
        val = settings.get(key)
        if val is None or (key != "v0" and val == "auto"):
            continue
        if not _number(val) or not math.isfinite(val):
            raise DataError(f"settings.{key} is {_shown(val)}, expected a finite number", path)
    for key in (*BASE_KEYS, "v_base", "s_base"):
        val = settings.get(key)
        if val is None:
            continue
        if not _number(val) or not (math.isfinite(val) and val > 0):
            raise DataError(f"settings.{key} is {_shown(val)}, expected a positive number", path)
    prob = doc.get("hdi_prob", 0.95)
    if not _number(prob) or not 0 < prob < 1:
        raise DataError(f"'hdi_prob' is {_shown(prob)}, expected a number in (0, 1)", path)
    return model, None, summary, settings, f"{100 * prob:g}% HDI"


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 30 else text[:27] + "..."


def _check_values(values: dict, source: str) -> None:
    """Refuse a parameter set with NaN or infinity (a NetCDF's draws, a tampered JSON)."""
    from loadbayes.io.errors import DataError

    for name, val in values.items():
        if not math.isfinite(val):
            raise DataError(f"parameter {name!r} is {val}, expected a finite number", source)
        if name == "p0" and abs(val) < P0_MIN:
            raise DataError(
                f"parameter 'p0' is {val:.6g}: below {P0_MIN:g} per unit, no load to export",
                source,
            )
        if abs(val) > VALUE_MAX:
            raise DataError(
                f"parameter {name!r} is {val:.6g}: beyond {VALUE_MAX:g}, not a load's value",
                source,
            )


def _fill(values: dict, settings: dict) -> dict:
    # Fixed nominal values of the fit (p0, q0, v0 given, not sampled) come from settings.
    for key in ("p0", "q0", "v0"):
        if key not in values and isinstance(settings.get(key), int | float):
            values[key] = float(settings[key])
    return values


def _complete_triples(values: dict) -> dict:
    # Marginal quantiles do not keep a1 + a2 + a3 = 1: recompute the third share.
    for a, b, c in (("a1", "a2", "a3"), ("a4", "a5", "a6")):
        if a in values and b in values:
            values[c] = 1.0 - values[a] - values[b]
    return values


def pick_values(draws, summary, stat: str) -> dict[str, float]:
    """One parameter set from a posterior: its mean, median or a marginal quantile.

    Parameters
    ----------
    draws : dict of str to numpy.ndarray or None
        Pooled draws (None for a JSON summary, which only has the mean).
    summary : dict
        Per-parameter summary rows (``mean`` ...).
    stat : str
        ``mean``, ``median`` or ``qNN`` (NN in percent, e.g. ``q05``, ``q97.5``).

    Returns
    -------
    dict of str to float
        The values.

    Raises
    ------
    ValueError
        For an unknown statistic, or one that needs draws when only the summary is there.
    """
    import numpy as np

    m = _STAT.match(stat)
    if not m:
        raise ValueError(f"--stat {stat!r}: expected mean, median or qNN (q05, q50, q97.5)")
    if stat == "mean":
        return {k: float(v["mean"]) for k, v in summary.items()}
    if draws is None:
        raise ValueError(
            f"--stat {stat} needs the posterior draws: export from the NetCDF file "
            "(fit ... --netcdf post.nc); the JSON holds only the mean and interval"
        )
    q = 0.5 if stat == "median" else float(m.group(2)) / 100
    if not 0 <= q <= 1:
        raise ValueError(f"--stat {stat}: the quantile must be between q0 and q100")
    return _complete_triples({k: float(np.quantile(d, q)) for k, d in draws.items()})


def summary_lines(
    source: str, model: str, summary: dict, what: str, interval: str, *, fit_id: str | None = None
) -> list[str]:
    """The posterior summary every export carries.

    Parameters
    ----------
    source : str
        The posterior file.
    model : str
        The model.
    summary : dict
        Per-parameter rows with ``mean``, ``sd``, ``hdi_low``, ``hdi_high``.
    what : str
        Which statistic or draw was exported.
    interval : str
        What the interval is.
    fit_id : str, optional
        The fit's id (its JSON's ``fit_id``), written as ``fit id: ...`` so that
        ``playback`` can check that a case belongs to the fit it is given.

    Returns
    -------
    list of str
        One line each.
    """
    lines = [f"loadbayes {model} posterior from {source}; exported: {what}",
             *([f"fit id: {fit_id}"] if fit_id else []),
             f"parameter: mean (sd) [{interval}]"]  # fmt: skip
    for name, row in summary.items():
        m, sd, lo, hi = (
            "nan" if row.get(k) is None else f"{row[k]:.6g}"
            for k in ("mean", "sd", "hdi_low", "hdi_high")
        )
        lines.append(f"{name}: {m} ({sd}) [{lo}, {hi}]")
    return lines


@click.command("export", cls=OneLineCommand)
@click.argument("posterior", type=click.Path(dir_okay=False))
@click.option("--to", "fmt", required=True, type=click.Choice(["pandapower", "psse", "andes"]))
@click.option(
    "--out",
    required=True,
    type=click.Path(dir_okay=False),
    help="Output file (pandapower .json, PSS/E .raw [+ .dyr], ANDES case).",
)
@click.option(
    "--stat",
    help="mean, median or a marginal quantile qNN (q05, q95); needs draws (NetCDF) "
    "except for the mean. Default: mean; the median for a model of parts (slm, "
    "cmld-lite) from its NetCDF.",
)
@click.option(
    "--draws",
    "n_draws",
    type=click.IntRange(min=1),
    help="Export N posterior draws instead, one output each (_draw001 ...).",
)
@click.option("--seed", type=int, default=0, show_default=True,
              help="Which draws (--draws, --planning).")  # fmt: skip
@click.option("--planning", is_flag=True, help="A planning ensemble: play the posterior "
              "through a fault (--sag and --duration, or --voltage) and write the draws at "
              "--quantiles of its outcome (the load's reactive energy above its pre-fault Q "
              "after the fault clears), one output each (_q05 ...).")  # fmt: skip
@click.option("--sag", type=float, help="--planning: the sag's depth (0.45).")
@click.option("--duration", type=float, help="--planning: seconds the sag lasts.")
@click.option("--voltage", "profile", type=click.Path(exists=True, dir_okay=False),
              help="--planning: a voltage profile CSV (t_s, v, optionally angle_rad).")  # fmt: skip
@click.option("--quantiles", help="--planning: the outcome's quantiles written "
              "[default: 0.05,0.5,0.95].")  # fmt: skip
@click.option("--played", type=click.IntRange(20, 20000), help="--planning: posterior draws "
              "played through the fault [default: 300].")  # fmt: skip
@click.option(
    "--bus",
    type=click.IntRange(min=0),
    help="Bus number of the load (default: 1 in PSS/E; the one-bus net's bus in "
    "pandapower; ANDES: none given, the load on bus 1 fed from an infinite bus, bus 2, "
    "through 0.01+0.1j p.u.; given, the three-bus stand-in with the load on bus N).",
)
@click.option(
    "--s-base",
    type=float,
    help="MVA per p.u. of the posterior's powers (default: the fit's s_base_mva; PSS/E: "
    "also SBASE).",
)
@click.option("--p-mw", type=float, help="Load P at v0 in MW when the posterior has no p0.")
@click.option("--q-mvar", type=float, help="Load Q at v0 in Mvar when the posterior has no q0.")
@click.option(
    "--v-base",
    "--vn-kv",
    "vn_kv",
    type=float,
    help="Bus base voltage (kV) of the net/case built (default: the fit's v_base_kv).",
)
@click.option(
    "--net",
    "net_file",
    type=click.Path(dir_okay=False),
    help="pandapower: JSON net to write the load into (default: a one-bus net).",
)
@click.option("--load-index", type=int, help="pandapower: the load of --net to overwrite.")
@click.option(
    "--motor-as",
    type=click.Choice(["power", "impedance"]),
    default="power",
    show_default=True,
    help="pandapower: the composite load's motor as its constant-power (motor element) or "
    "constant-impedance (shunt) equivalent at v0.",
)
@click.option(
    "--motor-record",
    type=click.Choice(["cmldblu2", "cim5bl"]),
    default="cmldblu2",
    show_default=True,
    help="PSS/E: the composite load as the WECC CMLDBLU2 record (and a PSLF CMPLDW .dyd), "
    "or as a static load plus a CIM5BL motor.",
)
@click.option(
    "--case",
    "case_in",
    help="ANDES: a case file, or a name of ANDES's case library (kundur/kundur_full.xlsx), "
    "to place the load in, on bus --bus.",
)
@click.option(
    "--replace-load",
    "load_mode",
    flag_value="replace",
    help="ANDES --case: put the bus's own PQ load out of service; the fitted load is the "
    "bus's load.",
)
@click.option(
    "--add-load",
    "load_mode",
    flag_value="add",
    help="ANDES --case: keep the bus's own PQ load in service; the fitted load is added to it.",
)
@click.option(
    "--force-unphysical",
    is_flag=True,
    help="Export a static part with negative shares or power all the same (with warnings).",
)
@click.option("--quiet", is_flag=True)
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def export_cmd(posterior, fmt, out, stat, n_draws, seed, planning, sag, duration, profile,
               quantiles, played, bus, s_base, p_mw, q_mvar, vn_kv, net_file, load_index,
               motor_as, motor_record, case_in, load_mode, force_unphysical, quiet,
               force):  # fmt: skip
    """Write a fitted load model into pandapower, PSS/E or ANDES files.

    The posterior summary (mean, sd and interval of each parameter, the source and the
    statistic exported) goes with every output, as comments or a sidecar .summary.txt.
    """
    for name, val in (("--s-base", s_base), ("--vn-kv", vn_kv)):
        if val is not None and not (math.isfinite(val) and val > 0):
            raise click.BadParameter("must be a positive finite number", param_hint=name)
        lo, hi, unit = BASE_RANGE[name]
        if val is not None and not lo <= val <= hi:  # 1e-300 MVA was exported without a word
            raise UserError(f"{name} {val:g}: outside [{lo:g}, {hi:g}] {unit}, no network's base")
    for name, val in (("--p-mw", p_mw), ("--q-mvar", q_mvar)):
        if val is not None and not math.isfinite(val):
            raise click.BadParameter("must be a finite number", param_hint=name)
    if out.strip() in ("", "-"):  # '-' named the files -, -.dyr ...; '' the folder '.'
        raise UserError(f"--out {out!r}: an export writes files: give a file name")
    if n_draws is not None and stat is not None:
        raise UserError("give either --stat or --draws, not both")
    fault_args = {"--sag": sag, "--duration": duration, "--voltage": profile,
                  "--quantiles": quantiles, "--played": played}  # fmt: skip
    alone = [k for k, v in fault_args.items() if v is not None]
    if alone and not planning:
        raise UserError(f"{alone[0]} goes with --planning (a planning ensemble)")
    if planning and (n_draws is not None or stat is not None):
        raise UserError("--planning picks its own draws: not with --stat or --draws")
    if planning and fmt == "pandapower":
        raise UserError("--planning writes dynamic cases: --to psse (CMLDBLU2 .dyr, CMPLDW "
                        ".dyd) or --to andes")  # fmt: skip
    if case_in is not None and fmt != "andes":
        raise UserError("--case places the load in an ANDES case: it goes with --to andes")
    if case_in is not None and bus is None:
        raise UserError("--case needs the bus to put the load on: give --bus N")
    if load_mode is not None and case_in is None:
        raise UserError(f"--{load_mode}-load says what to do with a --case bus's own load")
    from loadbayes import export

    writer = export.get(fmt)
    model_raw, draws, summary, settings, interval, fid = _read_posterior(posterior)
    model = _MODEL_NAMES.get(model_raw, model_raw)
    if model == "composite" and settings.get("model") in ("slm", "cmld-lite"):
        model = settings["model"]  # a model of parts: its own mapping (export/partsload)
    try:
        export.check_model(model)
    except ValueError as exc:
        raise DataError(str(exc), posterior) from None
    said_stat = []
    if stat is None:
        # A model of parts' shares are skewed on their simplex: its median by default,
        # where the draws are there (a JSON holds the means only).
        stat = "median" if model in ("slm", "cmld-lite") and draws is not None else "mean"
        if model in ("slm", "cmld-lite") and draws is None and n_draws is None:
            said_stat.append(
                f"the posterior means exported: {posterior} holds no draws, and a {model} "
                "fit's medians (the default) need its NetCDF"
            )
    reason = export.check_parameters(model, summary if draws is None else draws)
    if reason:
        raise DataError(reason, posterior)
    outp = Path(out)
    if fmt == "psse":
        # The .raw is the case, the .dyr (and .dyd) its dynamics: all take the stem of
        # --out, and none may be written over another (nor a .summary.txt over a case).
        if outp.suffix.lower() in (".raw", ".dyr", ".dyd"):
            outp = outp.with_suffix(".raw")
    job_options: dict = {}  # per output: a planning draw's comment and thresholds
    if planning:
        if draws is None:
            raise UserError(f"{posterior}: --planning needs the NetCDF posterior (fit --netcdf)")
        asked = {"sag": sag, "duration": duration, "voltage": profile, "quantiles": quantiles}
        jobs, job_options = _planning_jobs(posterior, outp, draws, settings, played, seed, asked)
    elif n_draws is None:
        jobs = [(outp, _fill(pick_values(draws, summary, stat), settings), stat)]
    else:
        import numpy as np

        if draws is None:
            raise UserError(f"{posterior}: --draws needs the NetCDF posterior (fit --netcdf)")
        total = len(next(iter(draws.values())))
        if n_draws > total:
            raise UserError(f"--draws {n_draws}: the posterior holds {total} draws")
        picks = np.sort(np.random.default_rng(seed).choice(total, n_draws, replace=False))
        jobs = [
            (outp.with_name(f"{outp.stem}_draw{k + 1:03d}{outp.suffix}"),
             _fill({n: float(d[i]) for n, d in draws.items()}, settings),
             f"posterior draw {i} (seed {seed}, {k + 1} of {n_draws})")
            for k, i in enumerate(picks)
        ]  # fmt: skip
    sidecar = [".summary.txt"]
    for path, _, _ in jobs:
        if path.resolve() == Path(posterior).resolve():
            raise UserError(f"{path}: --out would overwrite the posterior")
        if net_file and path.resolve() == Path(net_file).resolve():
            raise UserError(f"{path}: --out would overwrite the --net it starts from")
        if case_in and path.resolve() == Path(case_in).resolve():
            raise UserError(f"{path}: --out would overwrite the --case it starts from")
        if not path.parent.is_dir():
            raise UserError(f"{path}: folder {path.parent} does not exist")
        suffixes = (*writer.SUFFIXES, *getattr(writer, "EXTRA_SUFFIXES", ()))
        related = [path, *(path.with_suffix(s) for s in suffixes)]
        related += [path.with_name(path.name + s) for s in sidecar]
        for r in related:
            if r.exists() and not force:
                raise UserError(f"{r}: exists; use --force to overwrite")
    if fmt == "psse" and outp.suffix.lower() != ".raw":
        raise UserError(
            f"{out}: a PSS/E export's --out ends in .raw (or .dyr, .dyd: the same stem), "
            f"not '{outp.suffix or '(none)'}'"
        )
    s_used, v_used, base_notes = resolve_bases(settings, fmt, s_base=s_base, v_base=vn_kv)
    base_notes = said_stat + base_notes
    options = {"bus": bus, "s_base_mva": s_used, "p_mw": p_mw, "q_mvar": q_mvar,
               "vn_kv": v_used, "net": net_file, "load_index": load_index, "force": force,
               "v0": settings.get("v0"), "f_hz": settings.get("f_hz"),
               "motor_as": motor_as, "motor_record": motor_record,
               "case": case_in}  # fmt: skip
    if model in ("slm", "cmld-lite"):
        options["model_options"] = settings.get("model_options") or {}
    for key in ("s_base_mva", "vn_kv", "f_hz"):
        if options[key] is None:
            options.pop(key)
    if load_mode is not None:
        options["load_mode"] = load_mode
    for _, values, _ in jobs:
        _check_values(values, posterior)
    problems = _problems(jobs, summary, settings, interval, model, options, fmt)
    unphysical = [(what, p) for what, ps in problems for p in ps if p.unphysical]
    if unphysical and not force_unphysical:
        what, p = unphysical[0]
        where = f"{what}: " if n_draws is not None else ""
        raise UserError(
            f"{posterior}: {where}{p.text}; refused: --force-unphysical exports it all the "
            "same, with these warnings in its files"
        )
    written: list[str] = []
    notes: list[str] = []  # what a writer tells the user (the ANDES case's own load)
    options["said"] = notes
    with _staged(outp.parent) as stage, output_transaction({}, force=force) as outs:
        for (path, values, what), (_, ps) in zip(jobs, problems, strict=True):
            warns = [p.text for p in ps]
            header = summary_lines(posterior, model, summary, what, interval, fit_id=fid)
            header += base_notes
            header += [f"warning: {w}" for w in warns]
            said_to = {"warnings": warns, "force": True}
            try:
                paths = writer.write(
                    values,
                    stage / path.name,
                    model=model,
                    header=header,
                    options={**options, **job_options.get(path, {}), **said_to},
                )
            except ValueError as exc:
                if isinstance(exc, DataError):
                    raise
                # What the writer refuses comes from the posterior: name it.
                raise UserError(f"{posterior}: {what}: {exc}") from None
            for p in paths:
                target = path.with_name(Path(p).name)
                outs.targets[str(target)] = target
                os.replace(p, outs.temp(str(target)))
                written.append(str(target))
    # Said after the work, once each (the files carry them): an error stays the run's
    # one line.
    said: set[str] = set()
    for what, ps in problems:
        for p in ps:
            line = p.text if n_draws is None or not p.unphysical else f"{what}: {p.text}"
            if line not in said:
                said.add(line)
                click.echo(f"loadbayes: warning: {line}", err=True)
    if not quiet:
        for note in [*base_notes, *dict.fromkeys(notes)]:
            click.echo(f"loadbayes: note: {note}", err=True)
        click.echo(f"{posterior}: {model} exported to {fmt}: {', '.join(written)}", err=True)


def _planning_jobs(posterior, outp, draws, settings, played, seed, asked):
    """The jobs of a planning ensemble (``export/planning.py``) and each one's options."""
    from loadbayes.export.planning import (
        DEFAULT_QUANTILES,
        comment,
        file_name,
        model_options,
        parse_quantiles,
        select,
    )
    from loadbayes.fit.composite.predict import predict
    from loadbayes.fit.composite.predict_scope import OUTCOME

    quantiles = asked.pop("quantiles")
    qs = DEFAULT_QUANTILES if quantiles is None else parse_quantiles(quantiles)
    pred = predict(posterior, **asked, draws=300 if played is None else played, seed=seed)
    stall_of = None if pred.stall is None else pred.stall.get("part", "motor D")
    jobs, extra = [], {}
    for pick in select(pred.outcomes, qs, outcome=OUTCOME):
        path = file_name(outp, pick)
        what = comment(pick, pred.fault, outcome=OUTCOME, unit="p.u. s", stall_of=stall_of,
                       meaning="the load's reactive energy above its pre-fault Q after "
                       "the fault clears")  # fmt: skip
        jobs.append((path, _fill({n: float(d[pick.index]) for n, d in draws.items()},
                                 settings), what))  # fmt: skip
        mo = model_options(settings.get("model_options"), pick)
        extra[path] = {"comments": [what], **({"model_options": mo} if mo else {})}
    return jobs, extra


def _problems(jobs, summary, settings, interval, model, options, fmt):
    """(what, problems) of each job: the fit's own (a, d) and its parameter set's (b, c)."""
    from loadbayes.export.bases import DEFAULT_BASES
    from loadbayes.export.checks import fit_problems, parts_problems, value_problems
    from loadbayes.export.loadparts import load_parts
    from loadbayes.export.partsload import PARTS_MODELS

    # The MW the writer will write: its default base when the fit has none.
    options = {"s_base_mva": DEFAULT_BASES[fmt][0], **options}

    common = fit_problems(summary, settings, interval)
    out = []
    for _, values, what in jobs:
        if model in PARTS_MODELS:
            out.append((what, [*common, *parts_problems(values, options["model_options"])]))
            continue
        try:
            parts = load_parts(values, model=model, options=options)
        except ValueError:  # the writer says why, in its own words
            parts = None
        out.append((what, [*common, *value_problems(values, parts, model)]))
    return out


@contextlib.contextmanager
def _staged(folder: Path):
    """A hidden folder beside the outputs where the writers write, removed at the end.

    Every file of every draw is written there first, then moved into one
    :func:`~loadbayes.commands.output.output_transaction` (same file system: a rename),
    so that an export lands whole or not at all, and a signal's message is true.
    """
    import shutil
    import tempfile

    try:
        stage = Path(tempfile.mkdtemp(dir=folder, prefix=".loadbayes-export-"))
    except OSError as err:
        raise UserError(f"{folder}: cannot create a file there ({err.strerror})") from None
    try:
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)
