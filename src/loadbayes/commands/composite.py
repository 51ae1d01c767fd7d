"""``loadbayes fit composite FILES...``: ZIP + induction motor from terminal recordings.

A standalone click command (it does not import :mod:`loadbayes.cli`); ``cli.py``
registers it under ``fit``. Heavy imports stay inside the function. One idea needs these
453 lines: the command's flags, checks, fit, summaries and outputs, in one function.
"""

from __future__ import annotations

import contextlib
import json

import click

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    event_column_options,
    likelihood_options,
    parse_nu,
)
from loadbayes.commands.output import (
    COMPOSITE_ADDRESS_SPACE,
    SamplingBar,
    UserError,
    check_address_space,
    check_cost,
    check_outputs,
    end_without_teardown,
    output_transaction,
    stop_if_signalled,
    user_errors,
)
from loadbayes.commands.settings import check_model_flags, named_model, sampler_settings

__all__ = ["fit_composite_cmd"]


def _parse_priors(items: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    # NAME=A,B of each --prior (the model checks the names and the values).
    out = {}
    for item in items:
        try:
            name, rest = item.split("=", 1)
            a, b = (float(x) for x in rest.split(","))
        except ValueError:
            raise click.BadParameter(
                f"{item!r}: expected NAME=MEDIAN,SD_LOG such as h_s=0.7,0.3 (a motor "
                "parameter) or NAME=MEAN,SD such as a1=0.3,0.1 (a share, f_m, p0, q0)",
                param_hint="--prior",
            ) from None
        out[name.strip()] = (a, b)
    return out


def _parse_torque(text: str) -> tuple[float, ...] | str:
    if text.strip().lower() == "estimate":
        return "estimate"
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected A,B,C", param_hint="--torque") from None


@click.command("composite", cls=OneLineCommand)
@click.argument("files", nargs=-1, required=True, type=str)
@click.option(
    "--model",
    "model_name",
    type=click.Choice(["zip+motor", "slm", "cmld-lite", "auto"]),
    default="zip+motor",
    show_default=True,
    help="The load model: 'zip+motor' (a ZIP part and one motor at the bus), 'slm' (ZIP + "
    "one motor behind the feeder's Rd + jXd), 'cmld-lite' (feeder, motors A and B, motor D, "
    "electronics, static part; shares on their simplex, physical priors); 'auto': the one "
    "of the three that best predicts each event from the others (two or more events).",
)
@click.option(
    "--negative-sequence",
    type=click.Choice(["auto", "on", "off"]),
    default="auto",
    show_default=True,
    help="slm, cmld-lite: the negative-sequence current as data where an event has v2_*, "
    "i2_* columns and |V2| >= 0.02 p.u. (auto), always (on: refused without them), never.",
)
@event_column_options
@click.option(
    "--event-col", default="event", show_default=True, help="Event-id column (if present)."
)
@click.option("--v-base", type=float, help="Voltage base: data volts / v-base = per unit.")
@click.option("--s-base", type=float, help="Power base: data P, Q / s-base = per unit.")
@accept_units_option
@click.option(
    "--f-hz",
    type=click.FloatRange(min=10, max=1000),
    default=None,
    help="Nominal frequency (the motor's time base), 10-1000 Hz. Default: the record's, "
    "from events.csv beside files cut by `loadbayes events`, else 60.",
)
@click.option(
    "--torque",
    default="1,0,0",
    show_default=True,
    metavar="A,B,C|estimate",
    help="Load torque T0 (A w^2 + B w + C), A + B + C = 1; or 'estimate' (a uniform "
    "Dirichlet prior on A, B, C).",
)
@likelihood_options(
    likelihood_help="Gaussian noise on P and Q, or Student-t noise that discounts bad samples "
    "and lists them under 'flagged' in the JSON.",
    nu_help="Student-t degrees of freedom: a number, or 'auto' to sample them.",
)
@click.option(
    "--steps/--no-steps",
    default=True,
    show_default=True,
    help="Place each voltage step (a fault, its clearing) at an estimated instant inside "
    "its sample interval; --no-steps reads it as a ramp across the interval.",
)
@click.option(
    "--prior",
    "priors",
    multiple=True,
    metavar="NAME=MEDIAN,SD_LOG|NAME=MEAN,SD",
    help="Log-normal prior of rs, x_prime, dx, t_prime_s, h_s or t0 (NAME=MEDIAN,SD_LOG), "
    "or a normal prior factor on a1..a6, f_m, p0 or q0 of every event (NAME=MEAN,SD); "
    "repeatable.",
)
@click.option(
    "--shares",
    type=click.Choice(["free", "bounded"]),
    default="free",
    show_default=True,
    help="'bounded' holds every static ZIP share in [0, 1] (so f_m in (0, 1)) by its "
    "prior: a load a simulator can take; 'free' lets the data put them anywhere.",
)
@click.option("--noise", type=click.Choice(["white", "ar1"]), default="white", show_default=True,
              help="Noise on P and Q independent from sample to sample, or AR(1) in each "
              "channel (rho_p, rho_q sampled; with slm and cmld-lite I2 stays white): for "
              "residuals that run in stretches, so that the intervals widen.")  # fmt: skip
@click.option("--rho-max", type=click.FloatRange(min=0, max=0.999, min_open=True),
              help="--noise ar1 with slm or cmld-lite: rho uniform on (-RHO_MAX, RHO_MAX) "
              "[0.999]; 0.9 keeps a short record's noise from a random walk.")  # fmt: skip
@click.option(
    "--window-s",
    type=click.FloatRange(min=0, max=1),
    default=None,
    help="The recorder's phasor window in s: each sample is read as the motor's mean over "
    "it, centred on its stamp (a fault's edge's samples left out). 0: point samples (as "
    "simulators write them). Default: one cycle for events cut by `loadbayes events`; for a "
    "plain table, points or one-cycle means, whichever fits better (the run says which). "
    "zip+motor only: slm and cmld-lite read point samples.",
)
@sampler_settings(
    draws=6_000,  # COMPOSITE_DEFAULTS, not imported: the command starts light (parts: 16,000)
    burn=4_000,
    init=False,
    draws_min=2,
    burn_min=1,
    draws_help="Iterations per chain, burn-in included (16,000 for slm, 10,000 for cmld-lite). "
    "Left at its default, the chains then run on until every reported quantity has R-hat "
    "< 1.01 and bulk ESS >= 400 (or --max-seconds runs out); given, exactly that many.",
    burn_help="Burn-in (the proposal adapts during it, then freezes).",
)
@click.option(
    "--max-seconds",
    type=float,
    default=300.0,
    show_default=True,
    help="Time budget of the sampling when it runs until convergence; the run says so "
    "when it ends unconverged.",
)
@click.option(
    "--until-converged/--fixed-draws",
    default=None,
    help="Run on after --draws until converged (the default when --draws is not given), "
    "or exactly --draws iterations (the default when it is).",
)
@click.option(
    "--json",
    "json_out",
    type=click.Path(dir_okay=False),
    required=True,
    help="Summary JSON ('-': standard output, the table then goes to stderr).",
)
@click.option("--netcdf", "netcdf_out", type=click.Path(dir_okay=False), help="All draws.")
@click.option("--plot", "plot_out", type=click.Path(dir_okay=False), help="Figure.")
@click.option(
    "--baseline-json",
    "baseline_out",
    type=click.Path(dir_okay=False),
    help="The NLS baseline (Gaussian approximation) in the same JSON contract.",
)
@click.option("--quiet", is_flag=True, help="No progress, no estimate and no table.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def fit_composite_cmd(
    files,
    model_name,
    negative_sequence,
    t_col,
    v_col,
    p_col,
    q_col,
    f_col,
    angle_col,
    event_col,
    v_base,
    s_base,
    accept_units,
    f_hz,
    torque,
    steps,
    likelihood,
    nu,
    priors,
    shares,
    noise,
    rho_max,
    window_s,
    sampler,
    max_seconds,
    until_converged,
    json_out,
    netcdf_out,
    plot_out,
    baseline_out,
    quiet,
    force,
):
    """Posterior of a composite load (ZIP + induction motor) from disturbance recordings.

    Each FILE holds columns t_s, v, p, q (per unit, or with --v-base/--s-base), optionally
    f (Hz) or angle_rad, and optionally an event column. All events are fitted jointly:
    one motor, each event its own operating point and mix.
    """
    outputs = {
        "--json": json_out,
        "--netcdf": netcdf_out,
        "--plot": plot_out,
        "--baseline-json": baseline_out,
    }
    check_outputs(outputs, list(files), force, stdout_ok=("--json",))
    parts = model_name != "zip+motor"
    check_model_flags(model_name, negative_sequence=negative_sequence, plot=bool(plot_out))
    # Its compiled kernels abort the process natively below this (LLVM's "Unable to
    # allocate section memory", std::bad_alloc: exit 134), where no error can be said.
    check_address_space(COMPOSITE_ADDRESS_SPACE, "fit composite")
    if likelihood != "student-t" and nu != "auto":
        raise UserError("--nu needs --likelihood student-t")
    if sampler.seed < 0:
        raise UserError(f"--seed {sampler.seed}: the seed must be a non-negative integer")

    import numpy as np

    from loadbayes.fit.composite import predictive_band
    from loadbayes.fit.composite.checks import check_run
    from loadbayes.fit.composite.choice import choose_model
    from loadbayes.fit.composite.driver import fit_composite, parts_defaults
    from loadbayes.fit.composite.reading import reading_model, reading_note
    from loadbayes.measurements.events import index_bases, index_f_hz, read_events
    from loadbayes.measurements.record import check_units

    # Events cut by `loadbayes events` carry the record's frequency in events.csv.
    f_found = index_f_hz(list(files))
    f_note = None
    if f_found is not None and f_hz is not None and f_hz != f_found[0]:
        raise UserError(
            f"--f-hz {f_hz:g}, but {f_found[1]} says the record's nominal frequency is "
            f"{f_found[0]:g} Hz: leave out --f-hz, or give --f-hz {f_found[0]:g}"
        )
    if f_hz is None:
        f_hz = f_found[0] if f_found is not None else 60.0
        f_note = f"frequency from events.csv: {f_hz:g} Hz" if f_found is not None else None

    check_run(f_hz=f_hz, draws=sampler.draws, burn=sampler.burn, thin=sampler.thin,
              seed=sampler.seed, max_seconds=max_seconds)  # fmt: skip
    # The flags, mapped onto the model's fields in one table (commands/settings.py).
    model = named_model(model_name, f_hz=f_hz, priors=_parse_priors(priors),
                        negative_sequence=negative_sequence, torque=_parse_torque(torque),
                        steps=steps, window_s=window_s, shares=shares, noise=noise,
                        rho_max=rho_max,
                        likelihood=likelihood, nu=parse_nu(nu))  # fmt: skip
    source = click.get_current_context().get_parameter_source("draws")
    if until_converged is None:
        until_converged = source in (None, click.core.ParameterSource.DEFAULT)
    if parts and source in (None, click.core.ParameterSource.DEFAULT):
        # A model of parts: 16,000 (cmld-lite 10,000: driver.parts_defaults)
        sampler = sampler.with_(draws=parts_defaults(model).draws)
    sampler = sampler.with_(until_converged=until_converged, max_seconds=max_seconds)
    events = read_events(
        list(files),
        t_col=t_col,
        v_col=v_col,
        p_col=p_col,
        q_col=q_col,
        f_col=f_col,
        angle_col=angle_col,
        event_col=event_col,
        v_base=v_base,
        s_base=s_base,
        f_hz=f_hz,
    )
    # Named by the data's own columns (--v-col ...); the base check below then passes.
    check_units(events, accept_units=accept_units, columns={"v": v_col, "p": p_col, "q": q_col})
    unit_warnings = check_units(events, accept_units=accept_units)
    choice = None
    if model is None:  # --model auto: held-out prediction chooses (fit/composite/choice.py)
        with _quiet_arviz():
            model, choice = choose_model(events, f_hz=f_hz, sampler=sampler,
                                         negative_sequence=negative_sequence)  # fmt: skip
        click.echo(f"loadbayes: --model auto: {choice['words']}", err=True)
        parts = model.name != "zip+motor"
    # A plain table does not say how it was sampled (events.csv does): read by the data.
    model, reading = reading_model(model, events, chosen=window_s is not None or bool(f_found))
    bases_note = None
    if v_base is None and s_base is None:
        # Per-unit events cut by `loadbayes events`: their bases are in events.csv.
        found = index_bases(list(files))
        if found is not None:
            v_base_rec, s_base_rec = found
            bases_note = (
                f"bases from events.csv: {v_base_rec:.6g} kV, {s_base_rec:.6g} MVA "
                "(recorded for export)"
            )
        else:
            v_base_rec = s_base_rec = None
    else:
        v_base_rec, s_base_rec = v_base, s_base
    # Stored per kept draw (an upper bound): the named draws of the motor, torque and
    # noise (~30), each event's 7 coefficients and its derived shares and powers, the
    # steps' fractions (at most 2 per event), the raw blocks kept alongside.
    check_cost(
        chains=sampler.chains, draws=sampler.draws, burn=sampler.burn, thin=sampler.thin,
        n_params=2 * (30 + 20 * len(events)), netcdf_out=netcdf_out, quiet=quiet,
    )  # fmt: skip
    if not quiet:
        if bases_note:
            click.echo(f"loadbayes: note: {bases_note}", err=True)
        own = model.window_s if parts else None  # a model of parts' reading is its own
        for note in (f_note, reading_note(reading, window_s, f_found, f_hz, model_window_s=own)):
            if note:
                click.echo(f"loadbayes: note: {note}", err=True)
        n = sum(e.n for e in events)
        click.echo(
            f"fitting {len(events)} event(s), {n} samples: NLS start, then sampling", err=True
        )
        if until_converged and sampler.chains >= 2:
            click.echo(
                f"loadbayes: after {sampler.draws} iterations per chain the chains run on "
                f"until converged (R-hat < 1.01, bulk ESS >= 400), at most {max_seconds:g} s "
                "of sampling (--max-seconds)",
                err=True,
            )
    if sampler.chains < 2:
        click.echo(
            "loadbayes: warning: one chain: R-hat needs two or more chains, so convergence "
            "is not checked (use --chains 2 or more)",
            err=True,
        )
    bar = SamplingBar(quiet)
    try:
        with _quiet_arviz():
            fit = fit_composite(
                model,
                events,
                sampler=sampler,
                progress=None if quiet else bar,  # --quiet: no cost to announce, no probe
                data_warnings=unit_warnings,
                provenance={
                    **({"model_choice": choice} if choice else {}),
                    **({"sample_reading": reading.as_dict()} if reading else {}),
                    "files": list(files),
                    "v_base_kv": v_base_rec,
                    "s_base_mva": s_base_rec,
                },
                start=reading.start if reading else None,
            )
    finally:
        bar.close()
    post = fit.posterior
    with _quiet_arviz():
        table = post.summary(hdi_prob=sampler.hdi_prob)
        text = json.dumps(post.to_dict(hdi_prob=sampler.hdi_prob, summary=table), indent=2,
                          allow_nan=False)  # fmt: skip
    bands = faults = None
    if plot_out:
        from loadbayes.fit.composite.predictive import fault_times

        bands = predictive_band(post, events, f_hz=f_hz, torque=model.torque, seed=sampler.seed)
        faults = fault_times(post, events)
    stop_if_signalled()
    # One transaction: every output to a temporary beside its target, renamed together
    # at the end (a signal before that leaves none of them, and the message says so).
    with output_transaction(outputs, force=force) as out:
        if json_out != "-":
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        stop_if_signalled()
        if baseline_out:
            base = fit.baseline.to_dict(hdi_prob=sampler.hdi_prob)
            out.temp("--baseline-json").write_text(
                json.dumps(base, indent=2, allow_nan=False) + "\n", encoding="utf-8"
            )
            stop_if_signalled()
        if netcdf_out:
            # Into the transaction's temporary (to_netcdf's own one a signal could leave).
            post.to_netcdf(out.temp("--netcdf"), atomic=False)
            stop_if_signalled()
        if plot_out:
            from loadbayes.plots.composite import plot_composite_fit
            from loadbayes.plots.fit import save_figure
            from loadbayes.report.composite_table import run_lines, static_lines

            ident = post.extra_json["identifiability"]
            notes = [ident["summary"], *static_lines(ident["static_part"]), *run_lines(post)]
            fig = plot_composite_fit(post, events, bands, faults, baseline=fit.baseline,
                                     notes=notes)  # fmt: skip
            save_figure(fig, out.temp("--plot"), force=True)
    end_without_teardown()  # every output is written and closed: no teardown at the exit
    if json_out == "-":
        click.echo(text)
    for w in post.warnings:
        click.echo(f"loadbayes: warning: {w}", err=True)
    if not quiet and parts:
        from loadbayes.report.parts_table import parts_lines

        for line in parts_lines(post, table, quantities=model.quantities,
                               hdi_prob=sampler.hdi_prob):  # fmt: skip
            click.echo(line, err=json_out == "-")
    elif not quiet:
        from loadbayes.report.composite_table import composite_table, static_lines

        err = json_out == "-"  # the JSON has standard output
        click.echo(composite_table(post, table, n_events=len(events),
                                   hdi_prob=sampler.hdi_prob), err=err)  # fmt: skip
        ident = post.extra_json["identifiability"]
        click.echo(ident["summary"], err=err)
        for line in static_lines(ident["static_part"], hdi_prob=sampler.hdi_prob):
            click.echo(line, err=err)
        acc = np.round(post.settings["acceptance"], 3).tolist()
        click.echo(f"Metropolis acceptance per chain: {acc}", err=err)


@contextlib.contextmanager
def _quiet_arviz():
    # ArviZ's own "arviz - WARNING" lines (one chain's R-hat...): the fit's warnings say it.
    import logging

    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)  # its loggers have handlers and levels of their own
    try:
        yield
    finally:
        logging.disable(previous)
