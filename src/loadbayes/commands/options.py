"""Options shared by the commands, declared once: data, nominal point, sampler, priors, outputs."""

from __future__ import annotations

import click


def sampler_options(func):
    """--draws --burn --chains --thin --seed --init --scheme --hdi-prob."""
    opts = [
        click.option(
            "--draws",
            type=click.IntRange(min=1),
            default=40_000,
            show_default=True,
            help="Iterations per chain including burn-in (the paper's M).",
        ),
        click.option(
            "--burn",
            type=click.IntRange(min=0),
            default=5_000,
            show_default=True,
            help="Leading iterations discarded (the paper's m).",
        ),
        click.option("--chains", type=click.IntRange(min=1), default=4, show_default=True),
        click.option("--thin", type=click.IntRange(min=1), default=1, show_default=True),
        click.option("--seed", type=int, default=0, show_default=True),
        click.option(
            "--init",
            type=click.Choice(["prior", "dispersed"]),
            default="prior",
            show_default=True,
            help="Start from a prior draw (the paper) or scattered around LS.",
        ),
        click.option(
            "--hdi-prob",
            type=click.FloatRange(0, 1, min_open=True, max_open=True),
            default=0.95,
            show_default=True,
        ),
    ]
    for opt in reversed(opts):
        func = opt(func)
    return func


def output_options(func):
    """--json --netcdf --plot --quiet --force."""
    opts = [
        click.option(
            "--json",
            "json_out",
            type=click.Path(dir_okay=False),
            required=False,
            help="Summary in the loadbayes JSON contract (optional: the table goes to stdout).",
        ),
        click.option(
            "--netcdf",
            "netcdf_out",
            type=click.Path(dir_okay=False),
            help="Draws, predictions and log-likelihood as an ArviZ NetCDF file "
            "(draws thinned evenly when large; docs/getting_started.md).",
        ),
        click.option(
            "--plot",
            "plot_out",
            type=click.Path(dir_okay=False),
            help="Figure (PNG, SVG or PDF by extension).",
        ),
        click.option("--quiet", is_flag=True, help="No progress bar and no table on stdout."),
        click.option("--force", is_flag=True, help="Overwrite existing outputs."),
    ]
    for opt in reversed(opts):
        func = opt(func)
    return func


def data_options(*, chunk_rows: int = 1 << 18, q_help: str | None = None):
    """--v-col --p-col --q-col --v-base --s-base --drop-invalid --chunk-rows.

    The columns of V, P, Q in a table and the bases that turn them into per unit; read by
    :func:`loadbayes.measurements.power_chunks`.
    """

    def deco(func):
        opts = [
            click.option("--v-col", default="v", show_default=True, help="Voltage column."),
            click.option("--p-col", default="p", show_default=True, help="Active-power column."),
            click.option(
                "--q-col",
                default="q",
                show_default=True,
                help=q_help or "Reactive-power column, or 'none' to fit P only.",
            ),
            click.option(
                "--v-base", type=float, help="Voltage base: data volts / v-base = per unit."
            ),
            click.option("--s-base", type=float, help="Power base: data P, Q / s-base = per unit."),
            click.option(
                "--drop-invalid",
                is_flag=True,
                help="Drop rows with NaN, inf or non-positive voltage (and report how many).",
            ),
            click.option(
                "--chunk-rows",
                type=click.IntRange(min=1),
                default=chunk_rows,
                show_default=True,
                help="Rows read at a time (memory does not grow with the file).",
            ),
        ]
        for opt in reversed(opts):
            func = opt(func)
        return func

    return deco


def nominal_options(*, auto: bool = True):
    """--v0 --p0 --q0: the nominal point of the load (P0, Q0 estimated with ``auto``)."""

    def deco(func):
        kind = {} if auto else {"type": float}
        tail = ", or 'auto'." if auto else " (numeric)."
        opts = [
            click.option(
                "--v0", type=float, default=1.0, show_default=True, help="Nominal voltage."
            ),
            click.option(
                "--p0",
                default="1.0" if auto else 1.0,
                show_default=True,
                help="Nominal P" + tail,
                **kind,
            ),
            click.option(
                "--q0",
                default="1.0" if auto else 1.0,
                show_default=True,
                help="Nominal Q" + tail,
                **kind,
            ),
        ]
        for opt in reversed(opts):
            func = opt(func)
        return func

    return deco


def tau_prior_options(func):
    """--tau-shape --tau-rate: the gamma prior of the noise precisions."""
    opts = [
        click.option(
            "--tau-shape",
            type=click.FloatRange(min=0, min_open=True),
            default=1e-3,
            show_default=True,
            help="Gamma prior shape of the noise precisions.",
        ),
        click.option(
            "--tau-rate",
            type=click.FloatRange(min=0, min_open=True),
            default=1e-9,
            show_default=True,
            help="Gamma prior rate of the noise precisions.",
        ),
    ]
    for opt in reversed(opts):
        func = opt(func)
    return func


def nominal(value: str, name: str) -> float | str:
    if value.strip().lower() == "auto":
        return "auto"
    try:
        out = float(value)
    except ValueError:
        raise click.BadParameter(
            f"{value!r} is neither a number nor 'auto'", param_hint=name
        ) from None
    if not (out == out and abs(out) != float("inf")) or out == 0:
        raise click.BadParameter("must be a finite non-zero number or 'auto'", param_hint=name)
    return out


def parse_coef_priors(items: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    out = {}
    for item in items:
        try:
            name, rest = item.split("=", 1)
            mean_s, sd_s = rest.split(",", 1)
            mean, sd = float(mean_s), float(sd_s)
        except ValueError:
            raise click.BadParameter(
                f"{item!r}: expected NAME=MEAN,SD such as a1=0.25,0.1", param_hint="--prior"
            ) from None
        if not sd > 0 or sd == float("inf") or mean != mean or abs(mean) == float("inf"):
            raise click.BadParameter(
                f"{item!r}: SD must be positive, MEAN finite", param_hint="--prior"
            )
        out[name.strip()] = (mean, sd)
    return out
