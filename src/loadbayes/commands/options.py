"""Options shared by the commands, declared once: data, nominal point, priors, outputs.

Every option two commands share is declared here once, so that no command spells one
again, with :class:`OneLineCommand` (usage errors in one line). The options that a
command hands to the library as a settings object (the sampler's, a data spec, the
composite model) are declared and built in :mod:`.settings`.
"""

from __future__ import annotations

import math

import click

#: Keys of :data:`loadbayes.models.motor_library.MOTORS` (a unit test keeps them equal;
#: spelled here so that ``--help`` does not import the models).
MOTOR_NAMES = ("small_industrial", "large_industrial", "krause_3hp", "krause_2250hp")


class OneLineCommand(click.Command):
    """A command whose usage errors are one line, ``loadbayes: error: ...``, exit 2.

    click prints a bad option value as three lines (usage, hint, error); the rest of
    loadbayes' errors are one line, so these are too. Use as ``@click.command(cls=...)``.
    """

    def _one_line(self, exc: click.UsageError):
        from loadbayes.commands.output import UserError

        msg = exc.format_message()  # click names the option in it
        where = exc.ctx.command_path if exc.ctx is not None else f"loadbayes ... {self.name}"
        return UserError(f"{msg.rstrip('.')} (see '{where} --help')")

    def make_context(self, info_name, args, parent=None, **extra):  # noqa: D102
        from loadbayes.commands.signals import install_signal_handlers, restore_signal_handlers

        # As early as a command of ours runs: a signal from here on gets its one line.
        install_signal_handlers()
        try:
            return super().make_context(info_name, args, parent=parent, **extra)
        except click.UsageError as exc:
            restore_signal_handlers()
            raise self._one_line(exc) from None
        except BaseException:
            restore_signal_handlers()
            raise

    def invoke(self, ctx):  # noqa: D102
        from loadbayes.commands.signals import restore_signal_handlers

        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            raise self._one_line(exc) from None
        finally:
            restore_signal_handlers()


def q_column(value: str) -> tuple[str | None, bool]:
    """``--q-col`` for the library: the column (None for 'none') and whether it is required.

    A Q column named by the user is required; the default ``q`` is used when present.
    """
    return (None if value.lower() == "none" else value), value not in ("q", "none")


def distinct_columns(**cols: str | None) -> None:
    """Refuse one data column given to two options (``--p-col v``)."""
    from loadbayes.commands.output import UserError

    seen: dict[str, str] = {}
    for opt, col in cols.items():
        if not col or col.lower() == "none":
            continue
        flag = "--" + opt.replace("_", "-")
        if col in seen:
            raise UserError(f"{flag} {col}: column '{col}' is already {seen[col]}")
        seen[col] = flag


def accept_units_option(func):
    """--accept-units: fit data that do not look like per unit (warn instead of refuse)."""
    return click.option(
        "--accept-units",
        is_flag=True,
        help="Fit even when the data do not look like per unit of the nominal point "
        "(the unit check then warns instead of refusing).",
    )(func)


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
    :func:`loadbayes.measurements.columns.power_chunks`.
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
                default=None if auto else 1.0,
                show_default=not auto,
                help="Nominal P" + tail + (" [auto: estimated, and said so]" if auto else ""),
                **kind,
            ),
            click.option(
                "--q0",
                default=None if auto else 1.0,
                show_default=not auto,
                help="Nominal Q" + tail + (" [auto: estimated, and said so]" if auto else ""),
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


def nominal(value: str | None, name: str) -> float | str:
    """A nominal power from its option: a non-zero number, or "auto" (also when absent)."""
    if value is None or value.strip().lower() == "auto":
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


def nominal_note(p0: str | None, q0: str | None, *, with_q: bool = True) -> str | None:
    """The line that says P0 / Q0 were not given and are estimated, or None."""
    missing = [n for n, v in (("P0", p0), ("Q0", q0)) if v is None and (n == "P0" or with_q)]
    if not missing:
        return None
    return (
        f"{' and '.join(missing)} not given (--p0, --q0): estimated from the data (auto) "
        "rather than assumed to be 1 per unit of the base"
    )


#: A prior sd below this overflows its precision 1/sd^2 (and pins the coefficient).
MIN_PRIOR_SD = 1e-100


def check_prior_sd(sd: float, option: str) -> float:
    """Refuse a prior sd whose precision 1/sd^2 is not a finite number."""
    if not (sd >= MIN_PRIOR_SD and math.isfinite(sd)):
        raise click.BadParameter(
            f"{sd:g} is not a usable prior sd (its precision 1/sd^2 overflows; "
            f"use at least {MIN_PRIOR_SD:g}, or a fixed value through the data)",
            param_hint=option,
        )
    return sd


def parse_coef_priors(items: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """``NAME=MEAN,SD`` items of --prior as a mapping; a repeated name is an error."""
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
        check_prior_sd(sd, "--prior")
        key = name.strip()
        if key in out:
            raise click.BadParameter(
                f"{key} given twice ({key}={out[key][0]:g},{out[key][1]:g} and {item})",
                param_hint="--prior",
            )
        out[key] = (mean, sd)
    return out


def parse_nu(value: str) -> float | str:
    """``--nu``: a positive finite number, or ``"auto"`` (sampled)."""
    if value.strip().lower() == "auto":
        return "auto"
    try:
        out = float(value)
    except ValueError:
        raise click.BadParameter(
            f"{value!r} is neither a number nor 'auto'", param_hint="--nu"
        ) from None
    if not (out > 0 and math.isfinite(out)):
        raise click.BadParameter("must be a positive finite number or 'auto'", param_hint="--nu")
    return out


def likelihood_options(
    *,
    likelihood_help: str = "Gaussian noise (the paper's), or Student-t noise that discounts "
    "bad samples and lists them under 'flagged' in the JSON.",
    nu_help: str = "Student-t degrees of freedom: a number, or 'auto' to sample them.",
):
    """--likelihood normal|student-t and --nu VALUE|auto (parse ``nu`` with :func:`parse_nu`)."""

    def deco(func):
        opts = [
            click.option(
                "--likelihood",
                type=click.Choice(["normal", "student-t"]),
                default="normal",
                show_default=True,
                help=likelihood_help,
            ),
            click.option(
                "--nu",
                default="auto",
                show_default=True,
                metavar="VALUE|auto",
                help=nu_help,
            ),
        ]
        for opt in reversed(opts):
            func = opt(func)
        return func

    return deco


def event_column_options(func):
    """--t-col --v-col --p-col --q-col --f-col --angle-col: the columns of an event file."""
    opts = [
        click.option("--t-col", default="t_s", show_default=True, help="Time column (s)."),
        click.option("--v-col", default="v", show_default=True, help="Voltage-magnitude column."),
        click.option("--p-col", default="p", show_default=True, help="Active-power column."),
        click.option("--q-col", default="q", show_default=True, help="Reactive-power column."),
        click.option(
            "--f-col", default=None, help="Frequency column in Hz [default: f if present]."
        ),
        click.option(
            "--angle-col",
            default=None,
            help="Voltage-angle column in rad [default: angle_rad if present].",
        ),
    ]
    for opt in reversed(opts):
        func = opt(func)
    return func
