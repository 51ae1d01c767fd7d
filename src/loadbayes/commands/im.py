"""``loadbayes fit im``: the motor's coefficients from its states (the paper's IM study)."""

from __future__ import annotations

import json

import click

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    check_prior_sd,
    output_options,
    parse_coef_priors,
)
from loadbayes.commands.output import (
    Progress,
    UserError,
    check_cost,
    check_outputs,
    estimate_rows,
    sidecar,
    user_errors,
    write_outputs,
)
from loadbayes.commands.settings import data_spec, sampler_settings


def _f_hz_fromsidecar(data: str) -> float | None:
    side = sidecar(data)
    if side is None or not side.is_file():
        return None
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
        value = float(meta["f_nominal_hz"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return value if value > 0 else None


#: Parameters stored per draw: 5 coefficients, 3 noise precisions, 9 physical parameters.
N_PARAMS = 17


@click.command("im", cls=OneLineCommand)
@click.argument("data", type=str)
@accept_units_option
@click.option("--t0", type=float, help="Load torque T0 (p.u.) [from the first sample].")
@click.option(
    "--f-hz",
    type=click.FloatRange(min=0, min_open=True),
    help="Nominal frequency (wb = 2 pi f) [the data's .json sidecar, else 60].",
)
@click.option(
    "--currents",
    type=click.Choice(["modelled", "measured"]),
    default="modelled",
    show_default=True,
    help="Currents in the flux and speed regressors: the model's (coupled blocks, no "
    "errors-in-variables bias) or the measured ones (the paper's independent blocks).",
)
@click.option(
    "--scheme",
    type=click.Choice(["blocked", "single-site", "exact"]),
    default="blocked",
    show_default=True,
    help="exact: measured form with --conjugate only.",
)
@sampler_settings()
@click.option("--prior-mean", type=float, default=0.0, show_default=True)
@click.option(
    "--prior-sd",
    type=click.FloatRange(min=0, min_open=True),
    default=100.0,
    show_default=True,
    help="Prior sd of every coefficient.",
)
@click.option(
    "--prior",
    "coef_priors",
    multiple=True,
    metavar="NAME=MEAN,SD",
    help="Prior of one coefficient (b1, b2, b3, ab, ac); repeatable.",
)
@click.option(
    "--tau-shape", type=click.FloatRange(min=0, min_open=True), default=1e-3, show_default=True
)
@click.option(
    "--tau-rate", type=click.FloatRange(min=0, min_open=True), default=1e-9, show_default=True
)
@click.option("--conjugate", is_flag=True, help="Normal-gamma prior (measured form only).")
@click.option("--drop-invalid", is_flag=True, help="Drop rows with NaN or inf (and count them).")
@click.option("--chunk-rows", type=click.IntRange(min=1), default=1 << 18, show_default=True)
@output_options
@data_spec("drop_invalid", "accept_units")
@user_errors
def fit_im_cmd(
    data,
    t0,
    f_hz,
    currents,
    scheme,
    sampler,
    prior_mean,
    prior_sd,
    coef_priors,
    tau_shape,
    tau_rate,
    conjugate,
    spec,
    chunk_rows,
    json_out,
    netcdf_out,
    plot_out,
    quiet,
    force,
):
    """Posterior of the induction-motor coefficients and physical parameters from a CSV/Parquet.

    Reads t_s, ud, uq, ed, eq, w, id, iq, ded, deq, dw (per unit, derivatives per second;
    other columns ignored).
    """
    side = sidecar(data)
    inputs = [data] + ([str(side)] if side is not None and side.exists() else [])
    check_outputs(
        {"--json": json_out, "--netcdf": netcdf_out, "--plot": plot_out},
        inputs,
        force,
        stdout_ok=("--json",),
    )
    check_prior_sd(prior_sd, "--prior-sd")
    if t0 is not None and not (t0 > 0 and t0 != float("inf")):
        raise UserError(f"--t0 must be a positive number, got {t0}")
    if scheme == "exact" and (currents != "measured" or not conjugate):
        raise UserError("--scheme exact needs --currents measured and --conjugate")
    if conjugate and currents != "measured":
        raise UserError("--conjugate needs --currents measured (the coupled form is not conjugate)")
    per_coef = parse_coef_priors(coef_priors)
    if f_hz is None:
        f_hz = _f_hz_fromsidecar(data) or 60.0
    check_cost(
        chains=sampler.chains, draws=sampler.draws, burn=sampler.burn, thin=sampler.thin,
        n_params=N_PARAMS,
        netcdf_out=netcdf_out, quiet=quiet,
    )  # fmt: skip

    from loadbayes.fit import fit_im_file, im_priors

    priors = im_priors(
        mean=prior_mean,
        sd=prior_sd,
        per_coef=per_coef,
        shape=tau_shape,
        rate=tau_rate,
        conjugate=conjugate,
    )
    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        post, model = fit_im_file(
            data,
            t0=t0,
            f_hz=f_hz,
            currents=currents,
            priors=priors,
            spec=spec,
            chunk_rows=chunk_rows,
            progress=progress,
            scheme=scheme,
            sampler=sampler,
            wording="cli",
        )
    finally:
        progress.close()
    write_outputs(
        post,
        model=model,
        hdi_prob=sampler.hdi_prob,
        json_out=json_out,
        netcdf_out=netcdf_out,
        plot_out=plot_out,
        force=force,
        quiet=quiet,
        prior_sd={n: per_coef.get(n, (prior_mean, prior_sd))[1] for n in model.free},
    )
