"""``loadbayes predict RESULT``: a composite fit played through a fault it has not shown.

A standalone click command (it does not import :mod:`loadbayes.cli`); ``cli.py`` attaches
it. The library does the work (:mod:`loadbayes.fit.composite.predict`); heavy imports
stay inside the function.
"""

from __future__ import annotations

import json
import math

import click

from loadbayes.commands.options import OneLineCommand
from loadbayes.commands.output import UserError, check_outputs, user_errors
from loadbayes.commands.signals import _STOP, stop_if_signalled

__all__ = ["predict_cmd"]


def _depths(text: str) -> list[float]:
    """``START:STOP:STEP`` (both ends kept) as a list of depths."""
    try:
        a, b, s = (float(x) for x in text.split(":"))
    except ValueError:
        raise UserError(f"--sweep {text!r}: give START:STOP:STEP, as 0.1:0.6:0.05") from None
    if not (0 < a <= b < 1 and s > 0) or (b - a) / s > 200:
        raise UserError(f"--sweep {text!r}: depths in (0, 1), START <= STOP, at most 200 steps")
    n = int(math.floor((b - a) / s + 1e-9)) + 1
    return [round(a + k * s, 10) for k in range(n)]


@click.command("predict", cls=OneLineCommand)
@click.argument("result", type=click.Path(exists=True, dir_okay=False))
@click.option("--sag", type=float, help="Sag depth, a share of the pre-fault voltage (0.45).")
@click.option("--duration", type=float, help="Seconds the sag lasts at its bottom.")
@click.option("--recovery", type=float, default=0.0, show_default=True,
              help="Seconds of a linear voltage recovery after the fault.")  # fmt: skip
@click.option("--angle", type=float, default=0.0, show_default=True,
              help="Phase jump with the fault (degrees).")  # fmt: skip
@click.option("--voltage", type=click.Path(exists=True, dir_okay=False),
              help="A voltage profile CSV: t_s, v (p.u.), optionally angle_rad and "
                   "v2_re, v2_im (the negative sequence: it brakes the motors).")  # fmt: skip
@click.option("--sweep", "sweep_spec", help="Depths START:STOP:STEP (with --duration): the "
              "same answers per depth, one figure of the stall probability.")  # fmt: skip
@click.option("--draws", type=click.IntRange(20, 20000), default=300, show_default=True,
              help="Posterior draws played, each with its own thresholds.")  # fmt: skip
@click.option("--prior", multiple=True, help="A threshold's prior over the default, "
              "name=centre,spread (vstall=0.55,0.05): vstall, tstall, vd1, vd2 (reweights the "
              "posterior's draws where the fit sampled them).")  # fmt: skip
@click.option("--prob", type=click.FloatRange(0.5, 1.0, max_open=True), default=0.95,
              show_default=True, help="Probability of the bands and intervals.")  # fmt: skip
@click.option("--seed", type=int, default=0, show_default=True, help="Seed (draws, thresholds).")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="The numbers.")
@click.option("--plot", "plot_out", type=click.Path(dir_okay=False), help="The figure.")
@click.option("--quiet", is_flag=True, help="No summary on stdout.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def predict_cmd(result, sag, duration, recovery, angle, voltage, sweep_spec, draws, prior, prob,
                seed, json_out, plot_out, quiet, force):  # fmt: skip
    """Play a fault through a composite fit (zip+motor, slm, cmld-lite): what the load does.

    RESULT is the fit's NetCDF (fit composite --netcdf), or its JSON with that NetCDF of
    the same name beside it. The fault is --sag DEPTH --duration S (and --recovery,
    --angle), a --voltage profile, or --sweep START:STOP:STEP with --duration. Motor D's
    stall voltage and time and the electronics' trip voltages are each draw's own (the
    fit samples them: where its events never reached them, they are their priors', said
    with the source; --prior reweights them); a zip+motor fit has none: its induction
    motor stalls by its own torque curve.
    """
    outputs = {"--json": json_out, "--plot": plot_out}
    inputs = [result] + ([voltage] if voltage else [])
    check_outputs(outputs, inputs, force)
    given = [x for x, on in (("--sag", sag is not None), ("--voltage", voltage),
                             ("--sweep", sweep_spec)) if on]  # fmt: skip
    if len(given) != 1:
        raise UserError("give the fault as one of --sag DEPTH --duration S, --voltage "
                        "PROFILE.csv, --sweep START:STOP:STEP (given: "
                        f"{', '.join(given) or 'none'})")  # fmt: skip
    if sweep_spec and duration is None:
        raise UserError("--sweep needs --duration S (the seconds each sag lasts)")

    from loadbayes.fit.composite.predict import predict, sweep
    from loadbayes.fit.composite.stall_depth import stall_depth
    from loadbayes.io.transaction import OutputSet

    kw = {"draws": draws, "prior": list(prior), "prob": prob, "seed": seed}
    if sweep_spec:
        depths = _depths(sweep_spec)
        preds = sweep(result, depths, duration=duration, recovery=recovery, angle=angle, **kw)
        doc = {
            "result": str(result),
            "sweep": [
                {"depth": d, **p.to_dict(band=False)} for d, p in zip(depths, preds, strict=True)
            ],
            "stall_depth": _stall_depth(stall_depth, depths, preds, prob, duration),
        }
    else:
        pred = predict(result, sag=sag, duration=duration, recovery=recovery, angle=angle,
                       voltage=voltage, **kw)  # fmt: skip
        doc = {"result": str(result), **pred.to_dict()}
    text = json.dumps(doc, indent=1, allow_nan=False)
    files = {k: v for k, v in outputs.items() if v}
    stop_if_signalled()
    with OutputSet(files, force=force) as out:
        _STOP["outputs"] = out
        if json_out:
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        if plot_out:
            from loadbayes.plots.fit import save_figure
            from loadbayes.plots.prediction import plot_prediction, plot_sweep

            fig = (plot_sweep(preds, depths, title=f"{result}: sags of {duration:g} s")
                   if sweep_spec else plot_prediction(pred, title=str(result)))  # fmt: skip
            save_figure(fig, out.temp("--plot"), force=True)
        out.commit()
        _STOP["committed"] = True
    if not quiet:
        if sweep_spec:
            for d, p in zip(depths, preds, strict=True):
                # A collapse is counted as a stall (the summary's words): the line says so.
                kind = "stall or collapse" if p.stall and p.stall.get("n_collapsed") else "stall"
                st = "" if p.stall is None or p.stall["probability"] is None else (
                    f"{kind} {p.stall['probability']:.2f} [{p.stall['interval'][0]:.2f}, "
                    f"{p.stall['interval'][1]:.2f}]")  # fmt: skip
                flag = " extrapolated" if p.extrapolation["extrapolated"] else ""
                if p.outcome is not None:  # some draws did not play: their shares, in words
                    flag += "; " + p.outcome["message"]
                click.echo(f"depth {d:.3g}: {st}{flag}")
            click.echo(doc["stall_depth"]["message"])
            click.echo(preds[-1].extrapolation["message"])
        else:
            for line in pred.summary_lines():
                click.echo(line)


def _stall_depth(stall_depth, depths, preds, prob, duration):
    """The sweep's stall depth over the depths that have a stall probability.

    A depth where every draw fails numerically has none: it is left out, and said.
    """
    part = (preds[0].stall or {}).get("part", "motor D")
    probs = [p.stall and p.stall["probability"] for p in preds]
    if preds[0].stall is None:
        return stall_depth(depths, probs, prob=prob, duration=duration, part=part)
    keep = [i for i, x in enumerate(probs) if x is not None]
    if not keep:
        words = "no depth has a draw that plays or collapses: no stall curve"
        return {"depth": None, "interval": [None, None], "levels": None, "message": words}
    out = stall_depth([depths[i] for i in keep], [probs[i] for i in keep], prob=prob,
                      duration=duration, part=part)  # fmt: skip
    if len(keep) < len(depths):
        gone = ", ".join(f"{depths[i]:.3g}" for i in range(len(depths)) if i not in keep)
        out["message"] += f" (left out: {gone}, where every draw failed numerically)"
    return out
