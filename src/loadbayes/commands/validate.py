"""``loadbayes validate RESULT EVENT...``: a composite fit checked on held-out events.

A standalone click command (it does not import :mod:`loadbayes.cli`); ``cli.py`` attaches
it. Each EVENT's recorded voltage (magnitude and angle) drives the fitted load's posterior
draws (:mod:`loadbayes.fit.composite.validate`); the recorded P and Q are scored against
the posterior-predictive band. Heavy imports stay inside the function.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import click

from loadbayes.commands.options import OneLineCommand, event_column_options
from loadbayes.commands.output import UserError, check_outputs, user_errors
from loadbayes.commands.signals import _STOP, stop_if_signalled

__all__ = ["validate_cmd"]

_NETCDF = (".nc", ".nc4", ".netcdf")


def _load_posterior(result: str, netcdf: str | None):
    """The composite posterior's draws: RESULT is the fit's NetCDF, or its JSON + --netcdf.

    A JSON without --netcdf takes the NetCDF of the same name beside it, when there is one
    (checked, as an explicit one is, to hold the draws of that JSON's fit).
    """
    from loadbayes.io.errors import DataError
    from loadbayes.posterior import Posterior

    doc = None
    if Path(result).suffix.lower() not in _NETCDF:
        try:
            doc = json.loads(Path(result).read_text(encoding="utf-8"))
            model = doc["model"]
        except (ValueError, KeyError, TypeError, UnicodeDecodeError):
            raise DataError("not a loadbayes posterior JSON (no 'model')", result) from None
        if model != "composite":
            raise DataError(
                f"a JSON of a {model} fit ({doc.get('method', '?')}): validate takes the "
                "result of fit composite",
                result,
            )
        beside = next(
            (Path(result).with_suffix(x) for x in _NETCDF if Path(result).with_suffix(x).is_file()),
            None,
        )
        if not netcdf and beside is not None:  # fit composite --json F.json --netcdf F.nc
            netcdf = str(beside)
        if not netcdf:
            raise UserError(
                f"{result}: the JSON holds the summary of the draws, not the draws; give the "
                "fit's NetCDF too (fit composite ... --netcdf FIT.nc, then validate "
                f"{result} --netcdf FIT.nc ...), or validate FIT.nc directly"
            )
    path = netcdf or result
    try:
        post = Posterior.from_netcdf(path)
    except Exception as exc:  # xarray/netCDF raise many types for a bad file
        raise DataError(f"not a loadbayes NetCDF posterior ({exc})", path) from None
    if post.model != "composite":
        raise DataError(
            f"the draws of a {post.model} fit ({post.method}): validate takes the result of "
            "fit composite",
            path,
        )
    unchecked = None if doc is None else _check_same_fit(doc, result, post, path)
    return post, unchecked


def _check_same_fit(doc: dict, result: str, post, path: str) -> str | None:
    """Refuse the draws of another fit: their fit ids (a hash of the settings) differ.

    A JSON or NetCDF written before fit ids is checked by its events and method only,
    and the note returned says so.
    """
    ids = (doc.get("fit_id"), post.written_fit_id)
    if None not in ids:
        if ids[0] != ids[1]:
            raise UserError(
                f"{path}: the draws of another fit than {result} (fit id {ids[1]}, the "
                f"JSON's {ids[0]}); give the NetCDF written with that JSON"
            )
        return None
    a = [e.get("name") for e in (doc.get("settings", {}).get("events") or [])]
    b = [e.get("name") for e in (post.settings.get("events") or [])]
    if a != b or doc.get("method") != post.method:
        raise UserError(
            f"{path}: not the draws of {result} (events {b} by {post.method}, the JSON's "
            f"{a} by {doc.get('method')})"
        )
    old = result if ids[0] is None else path
    return (
        f"{old} has no fit id (written before them): {path} is checked to be the draws "
        f"of {result} by its events and method only"
    )


def _scores(post, recs, masks, **kw):
    """Each event scored: a model of parts through its own prediction (its feeder solved).

    Then each channel's band widened by the model error the fitted events' own playback
    shows, where it shows more than the fit's noise (``fit/composite/validate_band.py``).
    Returns the scores and a note (None, or why the band is the fit's noise alone).
    """
    from loadbayes.export.partsload import rebuild_model
    from loadbayes.fit.composite.validate import validate_events

    try:
        model = rebuild_model(post.settings)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    if model is None:
        held = validate_events(post, recs, exclude=masks, **kw)
        return _honest(post, model, held, lambda e, m: validate_events(post, e, exclude=m, **kw),
                       kw["prob"])  # fmt: skip
    from loadbayes.fit.composite.validate_parts import validate_parts_event

    kw.pop("f_hz")  # the model's own

    def play(evs, ms):
        return [validate_parts_event(post, model, e, exclude=m, **kw)
                for e, m in zip(evs, ms, strict=True)]  # fmt: skip

    try:
        held = play(recs, masks)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return _honest(post, model, held, play, kw["prob"])


def _honest(post, model, held, play, prob):
    """``held`` with the fitted events' playback error in its bands (see :func:`_scores`)."""
    from loadbayes.fit.composite.predictive import events_of, window_of
    from loadbayes.fit.composite.validate_band import fitted_masks, honest_bands

    fitted = events_of(post)
    if not fitted:
        return held, ("the fit keeps no recordings of its events (written before they were "
                      "kept): the band is the fit's noise alone, which a model error does "
                      "not widen")  # fmt: skip
    window = model.window_s if model is not None else window_of(post.settings)
    try:
        own = play(fitted, fitted_masks(fitted, window))
    except ValueError as exc:
        return held, (f"the fitted events could not be played back through their fit "
                      f"({exc}): the band is the fit's noise alone")  # fmt: skip
    return honest_bands(post, held, own, prob), None


@click.command("validate", cls=OneLineCommand)
@click.argument("result", type=click.Path(exists=True, dir_okay=False))
@click.argument("events", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
@click.option(
    "--netcdf",
    "netcdf_in",
    type=click.Path(exists=True, dir_okay=False),
    help="The fit's draws (written by fit composite --netcdf), when RESULT is its JSON.",
)
@event_column_options
@click.option(
    "--straddle-col",
    default="straddle",
    show_default=True,
    help="Column flagging samples whose phasor window straddles a step (driven, not "
    "scored), used when present.",
)
@click.option("--v-base", type=float, help="Voltage base: data volts / v-base = per unit.")
@click.option("--s-base", type=float, help="Power base: data P, Q / s-base = per unit.")
@click.option(
    "--n-draws",
    type=click.IntRange(min=20),
    default=200,
    show_default=True,
    help="Posterior draws played through each event.",
)
@click.option(
    "--prob",
    type=click.FloatRange(0.5, 1.0, min_open=False, max_open=True),
    default=0.95,
    show_default=True,
    help="Probability of the posterior-predictive band.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed (draws picked, noise).")
@click.option(
    "--json",
    "json_out",
    type=click.Path(dir_okay=False),
    help="Scores per event (- for standard output).",
)
@click.option("--plot", "plot_out", type=click.Path(dir_okay=False), help="V, P, Q vs the band.")
@click.option("--quiet", is_flag=True, help="No table on stdout.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def validate_cmd(
    result,
    events,
    netcdf_in,
    t_col,
    v_col,
    p_col,
    q_col,
    f_col,
    angle_col,
    straddle_col,
    v_base,
    s_base,
    n_draws,
    prob,
    seed,
    json_out,
    plot_out,
    quiet,
    force,
):
    """Play each EVENT's recorded voltage through a composite fit and score its P and Q.

    RESULT is the NetCDF of `fit composite --netcdf`, or its `--json` with `--netcdf`
    naming the draws. Each EVENT file holds t_s, v, p, q (per unit on the fit's bases, or
    with --v-base/--s-base) and the voltage angle (angle_rad) or frequency (f); a
    `straddle` column (true where the phasor window straddles a step) leaves those
    samples out of the scores. Per event: n, n_excluded, rms_p and rms_q (per unit of the
    fitted P0) and coverage_p, coverage_q (share of samples inside the band).
    """
    outputs = {"--json": json_out, "--plot": plot_out}
    inputs = [result, *events] + ([netcdf_in] if netcdf_in else [])
    check_outputs(outputs, inputs, force, stdout_ok=("--json",))

    from loadbayes.fit.composite.validate import read_exclusions
    from loadbayes.io.transaction import OutputSet
    from loadbayes.measurements.events import read_events
    from loadbayes.measurements.record import check_units

    post, unchecked = _load_posterior(result, netcdf_in)
    f_hz = float(post.settings.get("f_hz", 60.0))
    recs, masks = [], []
    for path in events:
        evs = read_events(
            [path],
            t_col=t_col,
            v_col=v_col,
            p_col=p_col,
            q_col=q_col,
            f_col=f_col,
            angle_col=angle_col,
            v_base=v_base,
            s_base=s_base,
            f_hz=f_hz,
        )
        if len(evs) != 1:
            raise UserError(f"{path}: holds {len(evs)} events (an event column); give one each")
        # The fit's unit and sign checks: kV or MW without bases, or P that flows out,
        # would be scored as a (meaningless) miss of the band.
        check_units(evs, columns={"v": v_col, "p": p_col, "q": q_col}, overridable=False)
        recs += evs
        masks.append(read_exclusions(path, straddle_col, evs[0].n))
    scores, band_note = _scores(post, recs, masks, f_hz=f_hz, n_draws=n_draws, prob=prob,
                                seed=seed)  # fmt: skip
    notes = [n for n in (unchecked, band_note) if n]
    total = post.n_chains * post.n_draws
    if n_draws > total:  # the scores use every draw there is: said, not silently
        notes.append(f"only {total} draws exist in {netcdf_in or result}: all {total} used "
                     f"(--n-draws {n_draws})")  # fmt: skip
    doc = {
        "result": str(result),
        "draws": str(netcdf_in or result),
        "prob": prob,
        "p0_fitted": float(post.draws["p0"].mean()),
        "units": "rms_p, rms_q per unit of the fitted P0 (p0_fitted); coverage: share of "
        "scored samples inside the posterior-predictive band of a new observation: "
        "band_p, band_q say which (the fit's noise, or the model error fitted on the "
        "fitted events' playback where it shows more error than that noise; "
        "fitted_playback: that error per unit of P0); coverage_fit_noise_p, _q: the "
        "band of model + the fit's noise alone",
        "events": [s.to_dict() for s in scores],
    }
    text = json.dumps(doc, indent=2, allow_nan=False)
    files = {k: v for k, v in outputs.items() if v and v != "-"}
    stop_if_signalled()
    with OutputSet(files, force=force) as out:
        _STOP["outputs"] = out
        if json_out and json_out != "-":
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        if plot_out:
            from loadbayes.plots.fit import save_figure
            from loadbayes.plots.validation import plot_validation

            save_figure(plot_validation(scores, prob=prob), out.temp("--plot"), force=True)
        out.commit()
        _STOP["committed"] = True
    if json_out == "-":
        click.echo(text)
    for note in notes:  # after the work: an error stays the run's one line
        click.echo(f"loadbayes: note: {note}", err=True)
    if not quiet:
        echo = functools.partial(click.echo, err=json_out == "-")  # stdout holds the JSON
        what = m if (m := post.settings.get("model")) in ("slm", "cmld-lite") else "composite"
        echo(f"{what} fit {result} on {len(scores)} held-out event(s), {prob:.0%} band")
        echo(
            f"{'event':<40} {'n':>5} {'excl':>5} {'rms_p':>7} {'rms_q':>7} "
            f"{'cov_p':>6} {'cov_q':>6} {'fn_p':>6} {'fn_q':>6}"
        )
        for s in scores:
            fn = [getattr(s, f"coverage_fit_noise_{c}") for c in "pq"]
            fn = [getattr(s, f"coverage_{c}") if x is None else x
                  for c, x in zip("pq", fn, strict=True)]  # fmt: skip
            echo(
                f"{s.file[-40:]:<40} {s.n:>5} {s.n_excluded:>5} {s.rms_p:>7.4f} "
                f"{s.rms_q:>7.4f} {s.coverage_p:>6.2f} {s.coverage_q:>6.2f} "
                f"{fn[0]:>6.2f} {fn[1]:>6.2f}"
            )
        echo("rms per unit of the fitted P0; cov: share of scored samples in the band; fn: "
             "in the band of the fit's noise alone")  # fmt: skip
        pb = scores[0].playback
        for c in "pq" if pb else ():
            x = pb[c]
            echo(f"band of {c.upper()}: {x['band']} (the fitted events played back: RMS "
                 f"{x['rms']:.4f}; model error sd {x['model_error_sd']:.4f}, rho "
                 f"{x['model_error_rho']:.2f}; recorder noise sd {x['noise_sd']:.4f}; the "
                 f"fit's noise sd {x['fit_noise_sd']:.4f})")  # fmt: skip
