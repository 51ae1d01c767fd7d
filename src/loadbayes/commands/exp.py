"""``loadbayes fit exp``."""

from __future__ import annotations

from typing import Any

import click
import numpy as np

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    data_options,
    distinct_columns,
    nominal,
    nominal_note,
    nominal_options,
    output_options,
    q_column,
    tau_prior_options,
)
from loadbayes.commands.output import (
    Progress,
    check_cost,
    check_outputs,
    estimate_rows,
    user_errors,
    write_outputs,
)
from loadbayes.commands.settings import fit_spec, sampler_settings

#: Parameters stored per draw, at most: np, nq, kpf, kqf, tau_p, tau_q, p0, q0.
N_PARAMS = 8


@click.command("exp", cls=OneLineCommand)
@click.argument("data", type=str)
@data_options()
@accept_units_option
@click.option("--f-col", default=None, help="Frequency column (fits kpf, kqf); none by default.")
@click.option("--f0", type=float, default=60.0, show_default=True, help="Nominal frequency.")
@click.option("--t-col", default=None, help="Time column (seconds or ISO timestamps): the "
              "confounding check then asks whether the residuals drift in time.")  # fmt: skip
@nominal_options()
@click.option(
    "--noise",
    type=click.Choice(["additive", "multiplicative"]),
    default="additive",
    show_default=True,
    help="Additive Gaussian noise on P (Metropolis-within-Gibbs), or relative noise "
    "(log-linear, conjugate, fastest; needs P / P0 > 0).",
)
@sampler_settings()
@click.option(
    "--exponent-prior",
    default="0,10",
    show_default=True,
    metavar="MEAN,SD",
    help="Normal prior of np and nq.",
)
@tau_prior_options
@output_options
@user_errors
def fit_exp_cmd(
    data,
    v_col,
    p_col,
    q_col,
    f_col,
    f0,
    t_col,
    v0,
    p0,
    q0,
    v_base,
    s_base,
    noise,
    sampler,
    exponent_prior,
    tau_shape,
    tau_rate,
    drop_invalid,
    chunk_rows,
    accept_units,
    json_out,
    netcdf_out,
    plot_out,
    quiet,
    force,
):
    """Posterior of the exponential load model P = P0 (V/V0)^np [(1 + kpf df)]."""
    check_outputs(
        {"--json": json_out, "--netcdf": netcdf_out, "--plot": plot_out},
        [data],
        force,
        stdout_ok=("--json",),
    )
    distinct_columns(v_col=v_col, p_col=p_col, q_col=q_col, f_col=f_col, t_col=t_col)
    q_name, q_required = q_column(q_col)
    note = nominal_note(p0, q0, with_q=q_name is not None)
    p0_val, q0_val = nominal(p0, "--p0"), nominal(q0, "--q0")
    try:
        e_mean, e_sd = (float(x) for x in exponent_prior.split(","))
        if not (e_sd > 0 and np.isfinite(e_mean) and np.isfinite(e_sd)):
            raise ValueError
    except ValueError:
        raise click.BadParameter(
            f"{exponent_prior!r}: expected MEAN,SD with SD > 0", param_hint="--exponent-prior"
        ) from None
    check_cost(
        chains=sampler.chains, draws=sampler.draws, burn=sampler.burn, thin=sampler.thin,
        n_params=N_PARAMS,
        netcdf_out=netcdf_out, quiet=quiet,
    )  # fmt: skip
    if note and not quiet:
        click.echo(f"loadbayes: note: {note}", err=True)
    from loadbayes.core.priors import BlockPrior
    from loadbayes.fit import fit_exp
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.columns import read_power_columns, relocate
    from loadbayes.models.exponential import ExponentialModel, ExpPriors

    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        pc = read_power_columns(
            data,
            v_col=v_col,
            p_col=p_col,
            q_col=q_name,
            q_required=q_required,
            f_col=f_col,
            v_base=v_base,
            s_base=s_base,
            drop_invalid=drop_invalid,
            chunk_rows=chunk_rows,
            progress=progress,
        )
    finally:
        progress.close()
    with_q, with_f = "q" in pc.cols, f_col is not None
    model = ExponentialModel(
        v0=v0, p0=p0_val, q0=q0_val, with_q=with_q, with_f=with_f, f0=f0, noise=noise
    )
    if noise == "additive":
        priors: dict[str, Any] = {}
        for ch, nom, _, _ in model.channels():
            k = (1 if nom == "auto" else 0) + (1 if with_f else 0)
            sd = 1e4 if nom == "auto" else 10.0
            priors[ch] = ExpPriors(
                (e_mean, e_sd), BlockPrior.weak(max(k, 1), sd=sd, shape=tau_shape, rate=tau_rate)
            )
    else:
        priors = {}
        for block in model.blocks:
            means = [e_mean if c in ("np", "nq") else 0.0 for c in block.coef_names]
            sds = [
                e_sd if c in ("np", "nq") else (1e4 if c.startswith("log_") else 10.0)
                for c in block.coef_names
            ]
            priors[block.name] = BlockPrior.weak(
                block.k, mean=means, sd=sds, shape=tau_shape, rate=tau_rate
            )
    from loadbayes.fit.zip import data_checks

    names = {"v": v_col, "p": p_col, "q": q_name, "f": f_col}
    # The exponential model is near the ZIP one at V0 (P = P0 at V = V0): the same check.
    warnings = data_checks(
        pc.cols, path=data, names=names, accept_units=accept_units, eiv=False,
        v0=v0, p0=p0_val, q0=q0_val, v_base=v_base, s_base=s_base, f0=f0,
    )  # fmt: skip
    if pc.n_dropped:
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped (--drop-invalid)")
    times = None
    if t_col:
        from loadbayes.measurements.times import check_increasing, read_times

        times = read_times(data, t_col, pc.rows)
        check_increasing(times, pc.rows, path=str(data), column=t_col)
    try:
        post = fit_exp(
            pc.cols,
            times=times,
            spec=fit_spec(f_col="f", v0=v0, p0=p0_val, q0=q0_val),
            with_q=with_q,
            with_f=with_f,
            f0=f0,
            noise=noise,
            priors=priors,
            sampler=sampler,
            warnings=warnings,
            unit_check=False,  # done above on the file, worded with the options
            warn=False,
            settings={
                "data": str(data),
                "columns": names,
                "v_base": v_base,
                "s_base": s_base,
                "n_dropped": pc.n_dropped,
            },
        )
    except DataError as exc:
        raise relocate(exc, data, pc.rows, names) from None
    write_outputs(
        post,
        model=model,
        hdi_prob=sampler.hdi_prob,
        json_out=json_out,
        netcdf_out=netcdf_out,
        plot_out=plot_out,
        force=force,
        quiet=quiet,
        prior_sd={"np": e_sd, "nq": e_sd},
    )
