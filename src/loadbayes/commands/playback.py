"""``loadbayes playback RESULT EXPORT EVENT``: the recorded voltage played into the ANDES case.

A standalone click command (it does not import :mod:`loadbayes.cli`); ``cli.py`` attaches
it. The library does the work (:mod:`loadbayes.export.andes.playback`); heavy imports
stay inside the function.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import click

from loadbayes.commands.options import OneLineCommand, event_column_options
from loadbayes.commands.output import UserError, check_outputs, user_errors
from loadbayes.commands.signals import _STOP, stop_if_signalled

__all__ = ["playback_cmd"]

_FIT_ID = re.compile(r"^# fit id: ([0-9a-f]+)\s*$", re.MULTILINE)


def _check_same_fit(result: str, export: str) -> str | None:
    """Refuse the case of another fit: the fit id its summary names is not RESULT's.

    ``export --to andes`` writes the fit's id into the case's sidecar
    ``<case>.summary.txt``; a JSON or a case written before fit ids, or a case without
    its sidecar, is played all the same: the note returned says it was not checked.
    """
    sidecar = Path(export).with_name(Path(export).name + ".summary.txt")
    try:
        doc = json.loads(Path(result).read_text(encoding="utf-8"))
        ours = doc.get("fit_id") if isinstance(doc, dict) else None
    except (OSError, ValueError, UnicodeDecodeError):  # read_fit has said what is wrong
        ours = None
    try:
        found = _FIT_ID.search(sidecar.read_text(encoding="utf-8", errors="replace"))
    except OSError:
        found, why = None, f"its summary {sidecar.name} is not beside it"
    else:
        why = f"its summary {sidecar.name} names no fit id (written before them)"
    if not isinstance(ours, str):
        why = f"{result} has no fit id (written before them)"
    elif found is not None:
        if found.group(1) != ours:
            raise UserError(
                f"{export}: the case of another fit than {result} (fit id {found.group(1)} "
                f"in {sidecar.name}, the JSON's {ours}); export the case from {result}"
            )
        return None
    return f"{export} is not checked to be the case of {result}: {why}"


def _refuse_parts(result: str) -> None:
    """A model of parts has no ANDES case to play into: said in one line, with the way."""
    try:
        doc = json.loads(Path(result).read_text(encoding="utf-8"))
        name = doc["settings"]["model"]
    except (OSError, ValueError, KeyError, TypeError, UnicodeDecodeError):
        return  # read_fit says what is wrong with the file
    if name in ("slm", "cmld-lite"):
        raise UserError(
            f"{result}: a {name} fit: playback plays a record into the ANDES case of a fit, "
            f"and ANDES holds no {name} (export --to andes refuses it); play its events "
            f"through the fit's own prediction, the feeder solved: loadbayes validate "
            f"{result} EVENT (with the fit's NetCDF)"
        )


@click.command("playback", cls=OneLineCommand)
@click.argument("result", type=click.Path(exists=True, dir_okay=False))
@click.argument("export", type=click.Path(exists=True, dir_okay=False))
@click.argument("event", type=click.Path(exists=True, dir_okay=False))
@event_column_options
@click.option("--v-base", type=float, help="Voltage base: data volts / v-base = per unit.")
@click.option("--s-base", type=float, help="Power base: data P, Q / s-base = per unit.")
@click.option(
    "--json",
    "json_out",
    type=click.Path(dir_okay=False),
    help="The numbers (- for standard output).",
)
@click.option(
    "--plot", "plot_out", type=click.Path(dir_okay=False), help="V, P, Q recorded vs played."
)
@click.option("--quiet", is_flag=True, help="No summary on stdout.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def playback_cmd(
    result,
    export,
    event,
    t_col,
    v_col,
    p_col,
    q_col,
    f_col,
    angle_col,
    v_base,
    s_base,
    json_out,
    plot_out,
    quiet,
    force,
):
    """Play EVENT's recorded voltage into the ANDES case EXPORT and compare P, Q.

    RESULT is the JSON of `fit composite`, EXPORT the case `export --to andes` wrote from
    it, EVENT an event file (t_s, v, p, q per unit or with --v-base/--s-base, and
    angle_rad or f when recorded). The voltage (magnitude and angle) is imposed at the
    load bus by an ideal source; the RMS of ANDES's P and Q against the record, per unit
    of the fitted P0, is compared with the fit's residual noise.
    """
    outputs = {"--json": json_out, "--plot": plot_out}
    check_outputs(outputs, [result, export, event], force, stdout_ok=("--json",))

    from loadbayes.export.andes.playback import compare, playback, read_fit
    from loadbayes.io.transaction import OutputSet
    from loadbayes.measurements.events import read_events

    _refuse_parts(result)
    fit = read_fit(result)
    unchecked = _check_same_fit(result, export)
    evs = read_events(
        [event],
        t_col=t_col,
        v_col=v_col,
        p_col=p_col,
        q_col=q_col,
        f_col=f_col,
        angle_col=angle_col,
        v_base=v_base,
        s_base=s_base,
        f_hz=fit.f_hz,
    )
    if len(evs) != 1:
        raise UserError(f"{event}: holds {len(evs)} events (an event column); give one")
    from loadbayes.measurements.record import check_units

    # The fit's unit and sign checks: data in kV or MW without bases, or P that flows
    # out, said as such (not as a disagreement with the case's power).
    check_units(evs, columns={"v": v_col, "p": p_col, "q": q_col}, overridable=False)
    steps = fit.steps_for(event)
    # MVA per p.u. of the event: --s-base, else the fit's recorded base, else the case's.
    s_event = s_base if s_base is not None else fit.s_base_mva
    pb = playback(export, evs[0], p0=fit.p0_for(event), steps=steps, s_base_mva=s_event)
    numbers = compare(pb, fit, event=event)
    numbers["fitted_event"] = fit.fitted_event(event)
    numbers["steps_from"] = "the fit" if steps is not None else "the middle of each interval"
    doc = {"result": str(result), "export": str(export), "event": str(event), **numbers}
    doc["units"] = "rms_*, max_abs_*, fit_residual_* per unit of the fitted P0 (p0)"
    text = json.dumps(doc, indent=2, allow_nan=False)
    files = {k: v for k, v in outputs.items() if v and v != "-"}
    stop_if_signalled()
    with OutputSet(files, force=force) as out:
        _STOP["outputs"] = out
        if json_out and json_out != "-":
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        if plot_out:
            from loadbayes.plots.fit import save_figure
            from loadbayes.plots.playback import plot_playback

            fig = plot_playback(pb, numbers, title=f"{event} played into {export}")
            save_figure(fig, out.temp("--plot"), force=True)
        out.commit()
        _STOP["committed"] = True
    if json_out == "-":
        click.echo(text)
    if unchecked:  # after the work: an error stays the run's one line
        click.echo(f"loadbayes: note: {unchecked}", err=True)
    if not quiet:
        click.echo(f"{event} played into {export} ({pb.t_s.size} samples, ANDES step "
                   f"{pb.step_s:.3g} s): {numbers['verdict']}",
                   err=json_out == "-")  # fmt: skip
