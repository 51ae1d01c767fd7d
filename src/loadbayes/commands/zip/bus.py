"""``loadbayes fit zip`` on one bus (hands over to :mod:`.fleet` with ``--by``)."""

from __future__ import annotations

from typing import Any

import click

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    check_prior_sd,
    data_options,
    distinct_columns,
    likelihood_options,
    nominal,
    nominal_note,
    nominal_options,
    output_options,
    parse_coef_priors,
    parse_nu,
    q_column,
    tau_prior_options,
)
from loadbayes.commands.output import (
    ZIP_ADDRESS_SPACE,
    Progress,
    UserError,
    check_address_space,
    check_cost,
    check_outputs,
    estimate_rows,
    user_errors,
    write_outputs,
)
from loadbayes.commands.settings import fit_spec, sampler_settings
from loadbayes.commands.zip.fleet import (
    fleet_options,
    fleet_sampler_defaults,
    run_fleet_command,
)

#: Parameters stored per draw and channel: three shares, tau, P0 (auto); Student-t adds nu.
PER_CHANNEL = 5
#: The draws and burn-in of --v-noise where the user gave none (its iterations are O(n)).
EIV_DRAWS, EIV_BURN = 4_000, 1_000


#: Iterations, burn-in and chains of a drifting-level fit where the user gave none
#: (:data:`loadbayes.fit.drift.DRIFT_DEFAULTS`, repeated: commands import the library lazily).
DRIFT_DRAWS, DRIFT_BURN, DRIFT_CHAINS = 2500, 500, 2


def zip_sampler_defaults(values: dict[str, Any], options: dict[str, Any]) -> dict[str, Any]:
    """The draws, burn-in and chains of a run where the user gave none.

    The drifting level's with --level drift, the fleet's with --by, the errors-in-variables
    ones with --v-noise.
    """
    ctx = click.get_current_context()
    src = click.core.ParameterSource.DEFAULT
    default = {k: ctx.get_parameter_source(k) == src for k in ("draws", "burn", "chains")}
    if options.get("level") == "drift":  # one bus or a fleet: each bus's own chains
        values = dict(values)
        if default["draws"]:
            values["draws"] = DRIFT_DRAWS
        if default["burn"]:
            values["burn"] = min(DRIFT_BURN, values["draws"] - 1)
        if default["chains"]:
            values["chains"] = DRIFT_CHAINS
        return values
    values = fleet_sampler_defaults(values, options)
    if options.get("by") or options.get("v_noise") is None:
        return values
    draws = EIV_DRAWS if default["draws"] else values["draws"]
    burn = min(EIV_BURN, draws - 1) if default["burn"] else values["burn"]
    return {**values, "draws": draws, "burn": burn}


@click.command("zip", cls=OneLineCommand)
@click.argument("data", type=str)
@data_options()
@accept_units_option
@nominal_options()
@click.option(
    "--scheme",
    type=click.Choice(["blocked", "single-site", "exact"]),
    default="blocked",
    show_default=True,
)
@likelihood_options()
@click.option(
    "--t-col",
    default=None,
    help="Time column (seconds, or ISO timestamps), increasing: checks the fit for a load "
    "level that drifts; needed by --level drift.",
)
@click.option(
    "--level",
    type=click.Choice(["fixed", "drift"]),
    default="fixed",
    show_default=True,
    help="One load level P0 (Q0), or a level that drifts in time (a random walk; needs --t-col).",
)
@click.option(
    "--v-noise",
    default=None,
    metavar="SD|auto",
    help="Noise on V (errors in variables): the voltage's measurement-noise sd in per unit "
    "(instrument class), or 'auto' to sample it (needs Q). Fits a latent true voltage; "
    f"default draws {EIV_DRAWS}, burn {EIV_BURN}.",
)
@sampler_settings(adjust=zip_sampler_defaults)
@click.option(
    "--prior-mean",
    type=float,
    default=0.0,
    show_default=True,
    help="Prior mean of every ZIP coefficient.",
)
@click.option(
    "--prior-sd",
    type=click.FloatRange(min=0, min_open=True),
    default=10.0,
    show_default=True,
    help="Prior sd of every ZIP coefficient.",
)
@click.option(
    "--prior",
    "coef_priors",
    multiple=True,
    metavar="NAME=MEAN,SD",
    help="Prior of one coefficient (a1, a2, a4, a5); repeatable.",
)
@tau_prior_options
@click.option(
    "--conjugate",
    is_flag=True,
    help="Normal-gamma prior (coefficient precision scaled by tau); needed by --scheme exact.",
)
@output_options
@fleet_options
@user_errors
def fit_zip_cmd(
    data,
    v_col,
    p_col,
    q_col,
    v0,
    p0,
    q0,
    v_base,
    s_base,
    scheme,
    likelihood,
    nu,
    v_noise,
    t_col,
    level,
    sampler,
    prior_mean,
    prior_sd,
    coef_priors,
    tau_shape,
    tau_rate,
    conjugate,
    drop_invalid,
    chunk_rows,
    accept_units,
    json_out,
    netcdf_out,
    plot_out,
    quiet,
    force,
    **fleet,
):
    """Posterior of the ZIP coefficients from a CSV or Parquet file of V, P (and Q).

    With --by, fits every bus of a fleet (see docs/fleet.md) into one Parquet table.
    """
    if fleet["by"]:
        return run_fleet_command(click.get_current_context().params, sampler)
    if fleet.get("fleet_out"):
        raise click.UsageError("--out is for a fleet (with --by); one bus writes --json, "
                               "--netcdf, --plot or just the table")  # fmt: skip
    check_address_space(ZIP_ADDRESS_SPACE, "fit zip")
    check_outputs(
        {"--json": json_out, "--netcdf": netcdf_out, "--plot": plot_out},
        [data],
        force,
        stdout_ok=("--json",),
    )
    distinct_columns(v_col=v_col, p_col=p_col, q_col=q_col, t_col=t_col)
    if level == "drift" and not t_col:
        raise UserError("--level drift needs the time of each sample: give --t-col")
    if level == "drift" and likelihood != "normal":
        raise UserError("--level drift has a Gaussian likelihood only (drop --likelihood)")
    if level == "drift" and (scheme != "blocked" or conjugate):
        # Its sampler (the level by a Kalman filter inside Gibbs) has no other scheme and
        # its own prior; both options were ignored without a word.
        given = " ".join(f for f, on in (("--scheme " + scheme, scheme != "blocked"),
                                          ("--conjugate", conjugate)) if on)  # fmt: skip
        raise UserError(f"--level drift has a sampler of its own: drop {given}")
    check_prior_sd(prior_sd, "--prior-sd")
    q_name, _ = q_column(q_col)  # a Q column named other than q: required by the fit
    note = nominal_note(p0, q0, with_q=q_name is not None)
    p0_val, q0_val = nominal(p0, "--p0"), nominal(q0, "--q0")
    if scheme == "exact" and not conjugate:
        raise UserError("--scheme exact needs the conjugate prior: add --conjugate")
    per_coef = parse_coef_priors(coef_priors)
    for ch, val, names in (("p", p0_val, ("a1", "a2")), ("q", q0_val, ("a4", "a5"))):
        if val == "auto" and any(n in per_coef for n in names):
            raise UserError(
                f"--prior on {'/'.join(n for n in names if n in per_coef)} needs a known "
                f"nominal power: give --{ch}0 (e.g. --{ch}0 1 for data in per unit of it)"
            )
    nu_val = parse_nu(nu)
    if likelihood == "student-t" and scheme != "blocked":
        raise UserError(
            f"--scheme {scheme} is a Gaussian-likelihood scheme; the Student-t sampler has "
            "its own (leave --scheme at blocked)"
        )
    if likelihood == "normal" and nu.strip().lower() != "auto":
        raise UserError("--nu needs --likelihood student-t")
    if level == "drift" and str(v_noise).strip().lower() == "auto":
        raise UserError("--level drift takes the instrument's sd (--v-noise 0.0005), not auto")
    v_noise_val = parse_v_noise(v_noise, likelihood=likelihood, scheme=scheme,
                                conjugate=conjugate, with_q=q_name is not None)  # fmt: skip
    check_cost(
        chains=sampler.chains, draws=sampler.draws, burn=sampler.burn, thin=sampler.thin,
        n_params=PER_CHANNEL * (1 if q_name is None else 2)
        + (1 if likelihood == "student-t" else 0),
        netcdf_out=netcdf_out, quiet=quiet,
    )  # fmt: skip
    if note and not quiet:
        click.echo(f"loadbayes: note: {note}", err=True)
    # The priors the user set on shares sampled directly: said if the data add nothing.
    prior_sds = {
        n: per_coef.get(n, (prior_mean, prior_sd))[1]
        for ch, val, names in (("p", p0_val, ("a1", "a2")), ("q", q0_val, ("a4", "a5")))
        if val != "auto"
        for n in names
    }

    from loadbayes.fit import fit_zip_file, zip_priors

    priors = zip_priors(
        p0=p0_val,
        q0=q0_val,
        mean=prior_mean,
        sd=prior_sd,
        per_coef=per_coef,
        shape=tau_shape,
        rate=tau_rate,
        conjugate=conjugate,
    )
    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        spec = fit_spec(
            v_col=v_col, p_col=p_col, q_col=q_name, t_col=t_col, v0=v0, p0=p0_val,
            q0=q0_val, v_base=v_base, s_base=s_base, drop_invalid=drop_invalid,
            accept_units=accept_units,
        )  # fmt: skip
        post, model = fit_zip_file(
            data,
            spec=spec,
            priors=priors,
            scheme=scheme,
            likelihood=likelihood,
            nu=nu_val,
            sampler=sampler,
            chunk_rows=chunk_rows,
            progress=progress,
            wording="cli",
            v_noise=v_noise_val,
            level=level,
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
        prior_sd=prior_sds,
    )


# --json is optional (the table goes to stdout); a fleet writes --out instead.
next(p for p in fit_zip_cmd.params if p.name == "json_out").required = False


def parse_v_noise(text, *, likelihood, scheme, conjugate, with_q):
    """--v-noise as the fit takes it: None, a positive sd, or "auto" (one-line errors)."""
    if text is None:
        return None
    from loadbayes.fit.eiv import check_v_noise
    from loadbayes.io.errors import OptionError

    try:
        value = check_v_noise(text)
    except OptionError as exc:
        raise click.BadParameter(
            str(exc).replace("v_noise must be", "must be"), param_hint="--v-noise"
        ) from None
    for bad, why in (
        (likelihood != "normal", "--likelihood student-t"),
        (scheme != "blocked", f"--scheme {scheme}"),
        (conjugate, "--conjugate"),
    ):
        if bad:
            raise UserError(f"--v-noise has its own Gibbs sampler: drop {why}")
    if value == "auto" and not with_q:
        raise UserError(
            "--v-noise auto needs Q as well as P: with P alone the noise on V is not "
            "identified (give the instrument's sd, e.g. --v-noise 0.005)"
        )
    return value
