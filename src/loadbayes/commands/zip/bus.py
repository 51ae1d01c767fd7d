"""``loadbayes fit zip`` on one bus (hands over to :mod:`.fleet` with ``--by``)."""

from __future__ import annotations

import click

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    check_prior_sd,
    data_options,
    distinct_columns,
    nominal,
    nominal_note,
    nominal_options,
    output_options,
    parse_coef_priors,
    sampler_options,
    tau_prior_options,
)
from loadbayes.commands.output import (
    Progress,
    UserError,
    check_cost,
    check_outputs,
    estimate_rows,
    user_errors,
    write_outputs,
)
from loadbayes.commands.zip.fleet import fleet_options, run_fleet_command

#: Parameters stored per draw and channel: three shares, tau, P0 (auto); Student-t adds nu.
PER_CHANNEL = 5


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
@click.option(
    "--likelihood",
    type=click.Choice(["normal", "student-t"]),
    default="normal",
    show_default=True,
    help="Gaussian noise (the paper's), or Student-t noise that discounts bad samples "
    "and lists them under 'flagged' in the JSON.",
)
@click.option(
    "--nu",
    default="auto",
    show_default=True,
    metavar="VALUE|auto",
    help="Student-t degrees of freedom: a number, or 'auto' to sample them.",
)
@sampler_options
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
    draws,
    burn,
    chains,
    thin,
    seed,
    init,
    hdi_prob,
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
        return run_fleet_command(click.get_current_context().params)
    if fleet.get("fleet_out"):
        raise click.UsageError("--out is for a fleet (with --by); one bus writes --json, "
                               "--netcdf, --plot or just the table")  # fmt: skip
    check_outputs(
        {"--json": json_out, "--netcdf": netcdf_out, "--plot": plot_out},
        [data],
        force,
        stdout_ok=("--json",),
    )
    distinct_columns(v_col=v_col, p_col=p_col, q_col=q_col)
    check_prior_sd(prior_sd, "--prior-sd")
    note = nominal_note(p0, q0, with_q=q_col.lower() != "none")
    p0_val, q0_val = nominal(p0, "--p0"), nominal(q0, "--q0")
    if scheme == "exact" and not conjugate:
        raise UserError("--scheme exact needs the conjugate prior: add --conjugate")
    if burn >= draws:
        raise UserError(f"--burn ({burn}) must be smaller than --draws ({draws})")
    per_coef = parse_coef_priors(coef_priors)
    for ch, val, names in (("p", p0_val, ("a1", "a2")), ("q", q0_val, ("a4", "a5"))):
        if val == "auto" and any(n in per_coef for n in names):
            raise UserError(
                f"--prior on {'/'.join(n for n in names if n in per_coef)} needs a known "
                f"nominal power: give --{ch}0 (e.g. --{ch}0 1 for data in per unit of it)"
            )
    nu_val = _parse_nu(nu)
    if likelihood == "student-t" and scheme != "blocked":
        raise UserError(
            f"--scheme {scheme} is a Gaussian-likelihood scheme; the Student-t sampler has "
            "its own (leave --scheme at blocked)"
        )
    if likelihood == "normal" and nu.strip().lower() != "auto":
        raise UserError("--nu needs --likelihood student-t")
    check_cost(
        chains=chains, draws=draws, burn=burn, thin=thin,
        n_params=PER_CHANNEL * (1 if q_col.lower() == "none" else 2)
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
    if likelihood == "student-t":
        post, model = _fit_student_t(
            data,
            nu=nu_val,
            v_col=v_col,
            p_col=p_col,
            q_col=q_col,
            v0=v0,
            p0=p0_val,
            q0=q0_val,
            v_base=v_base,
            s_base=s_base,
            priors=priors,
            drop_invalid=drop_invalid,
            chunk_rows=chunk_rows,
            quiet=quiet,
            accept_units=accept_units,
            sampler={
                "draws": draws,
                "burn": burn,
                "chains": chains,
                "thin": thin,
                "seed": seed,
                "init": init,
            },
        )
        st = post.settings
        post.extra_json.update(
            likelihood="student-t",
            flagged=list(st["flagged_rows"]),
            flagged_by_channel=dict(st["flagged"]),
            flag_rule=st["flag_rule"],
        )
        write_outputs(
            post,
            model=model,
            hdi_prob=hdi_prob,
            json_out=json_out,
            netcdf_out=netcdf_out,
            plot_out=plot_out,
            force=force,
            quiet=quiet,
            prior_sd=prior_sds,
        )
        return
    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        post, model = fit_zip_file(
            data,
            v_col=v_col,
            p_col=p_col,
            q_col=None if q_col.lower() == "none" else q_col,
            q_required=q_col not in ("q", "none"),
            v0=v0,
            p0=p0_val,
            q0=q0_val,
            v_base=v_base,
            s_base=s_base,
            priors=priors,
            scheme=scheme,
            draws=draws,
            burn=burn,
            chains=chains,
            thin=thin,
            seed=seed,
            init=init,
            drop_invalid=drop_invalid,
            chunk_rows=chunk_rows,
            progress=progress,
            accept_units=accept_units,
        )
    finally:
        progress.close()
    write_outputs(
        post,
        model=model,
        hdi_prob=hdi_prob,
        json_out=json_out,
        netcdf_out=netcdf_out,
        plot_out=plot_out,
        force=force,
        quiet=quiet,
        prior_sd=prior_sds,
    )


# ----------------------------------------------------------------- Student-t path
def _parse_nu(value: str) -> float | str:
    if value.strip().lower() == "auto":
        return "auto"
    try:
        out = float(value)
    except ValueError:
        raise click.BadParameter(
            f"{value!r} is neither a number nor 'auto'", param_hint="--nu"
        ) from None
    if not (out > 0 and out != float("inf")):
        raise click.BadParameter("must be a positive finite number or 'auto'", param_hint="--nu")
    return out


def _fit_student_t(data, *, nu, v_col, p_col, q_col, v0, p0, q0, v_base, s_base, priors,
                   drop_invalid, chunk_rows, quiet, accept_units, sampler):  # fmt: skip
    """Read the file into memory and fit the Student-t ZIP; flagged samples as file rows."""
    from loadbayes.fit import accumulate, fit_robust
    from loadbayes.fit.core import MAX_OBSERVED
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.columns import read_power_columns, relocate
    from loadbayes.models.zip import ZIPModel

    q_name = None if q_col.lower() == "none" else q_col
    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        pc = read_power_columns(
            data, v_col=v_col, p_col=p_col, q_col=q_name, q_required=q_col not in ("q", "none"),
            v_base=v_base, s_base=s_base, drop_invalid=drop_invalid, chunk_rows=chunk_rows,
            progress=progress,
        )  # fmt: skip
    finally:
        progress.close()
    from loadbayes.fit.zip import data_checks

    model = ZIPModel(v0=v0, p0=p0, q0=q0, with_q="q" in pc.cols)
    names = {"v": v_col, "p": p_col, "q": q_name}
    warnings = data_checks(
        pc.cols, path=data, names=names, accept_units=accept_units,
        v0=v0, p0=p0, q0=q0, v_base=v_base, s_base=s_base,
    )  # fmt: skip
    if pc.n_dropped:
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped (--drop-invalid)")
    try:
        warnings += model.check(accumulate(model, [pc.cols]))
        post = fit_robust(
            model,
            pc.cols,
            priors=priors,
            nu=nu,
            observed=pc.cols if pc.rows.size <= MAX_OBSERVED else None,
            warnings=warnings,
            settings={
                "data": str(data),
                "columns": {"v": v_col, "p": p_col, "q": q_name if model.with_q else None},
                "v0": v0,
                "p0": p0,
                "q0": q0 if model.with_q else None,
                "v_base": v_base,
                "s_base": s_base,
                "n_dropped": pc.n_dropped,
            },
            **sampler,
        )
    except DataError as exc:
        raise relocate(exc, data, pc.rows, names) from None
    # 0-based sample indices -> 1-based data rows of the file
    by_channel = {
        ch: [int(pc.rows[i]) for i in idx] for ch, idx in post.settings["flagged"].items()
    }
    post.settings["flagged"] = by_channel
    post.settings["flagged_rows"] = sorted({r for rows in by_channel.values() for r in rows})
    post.settings["flagged_are"] = "1-based data rows of the input (header excluded)"
    return post, model


# --json is optional (the table goes to stdout); a fleet writes --out instead.
next(p for p in fit_zip_cmd.params if p.name == "json_out").required = False
