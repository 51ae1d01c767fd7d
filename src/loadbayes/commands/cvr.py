"""``loadbayes cvr``: the energy and instantaneous CVR factors of an on/off test."""

from __future__ import annotations

import json

import click

from loadbayes.commands.options import OneLineCommand, data_options, distinct_columns, q_column
from loadbayes.commands.output import UserError, check_outputs, output_transaction, user_errors


@click.command("cvr", cls=OneLineCommand)
@click.argument("data", type=str)
@data_options()
@click.option("--t-col", default="time", show_default=True,
              help="Time column: ISO timestamps (the calendar) or seconds.")  # fmt: skip
@click.option("--schedule-col", default=None,
              help="The on/off schedule (1 where the reduction is on); found from the "
              "voltage's steps when not given.")  # fmt: skip
@click.option(
    "--weather-col",
    default=None,
    help="Outdoor temperature (C): heating and cooling degrees enter the regression.",
)
@click.option("--holiday-col", default=None, help="1 on holidays (a day of their own).")
@click.option("--pv-col", default=None,
              help="PV output or irradiance: its daily mean enters the regression, and "
              "dP/dV uses the dark hours' steps.")  # fmt: skip
@click.option("--instrument-col", default=None,
              help="An outside cause of V you name (a tap position, the upstream voltage): "
              "its daily mean replaces the on/off switching as the instrument.")  # fmt: skip
@click.option("--v0", type=float, default=1.0, show_default=True, help="Nominal voltage (p.u.).")
@click.option("--knot-days", type=click.FloatRange(min=1), default=7.0, show_default=True,
              help="Days between the drifting level's knots.")  # fmt: skip
@click.option("--min-switch", type=click.FloatRange(min=0, min_open=True), default=0.015,
              show_default=True,
              help="Smallest voltage step (p.u.) taken for a switch of the reduction.")  # fmt: skip
@click.option("--drop-against", is_flag=True,
              help="Leave out of dP/dV the voltage steps where P moved against V.")  # fmt: skip
@click.option("--no-instant", is_flag=True, help="Skip the instantaneous factor (dP/dV).")
@click.option("--draws", type=click.IntRange(min=100), default=4000, show_default=True,
              help="Exact draws per chain of the energy regression.")  # fmt: skip
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False),
              help="The result as JSON ('-': standard output).")  # fmt: skip
@click.option(
    "--plot",
    "plot_out",
    type=click.Path(dir_okay=False),
    help="The figures: energy against voltage, the daily pairs (PNG, SVG, PDF).",
)
@click.option("--by", default=None, metavar="COLUMN",
              help="A fleet: the column (or hive folder key) naming each row's feeder; "
              "writes --out.")  # fmt: skip
@click.option("--class-col", default=None, metavar="COLUMN",
              help="With --by: each feeder's class (for --pool class).")  # fmt: skip
@click.option("--pool", type=click.Choice(["none", "class"]), default="none", show_default=True,
              help="With --by: each feeder on its own, or pooled within its class.")  # fmt: skip
@click.option("--out", "fleet_out", type=click.Path(dir_okay=False),
              help="With --by: the fleet's CVR table (Parquet; loadbayes report draws "
              "its page).")  # fmt: skip
@click.option("--workers", type=click.IntRange(min=1),
              help="With --by: a local Dask cluster of this many worker processes.")  # fmt: skip
@click.option("--scheduler", metavar="ADDRESS",
              help="With --by: an existing Dask cluster (tcp://host:8786).")  # fmt: skip
@click.option("--quiet", is_flag=True, help="No lines on standard error but warnings.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def cvr_cmd(
    data, v_col, p_col, q_col, v_base, s_base, drop_invalid, chunk_rows, t_col, schedule_col,
    weather_col, holiday_col, pv_col, instrument_col, v0, knot_days, min_switch, drop_against,
    no_instant, draws, seed, json_out, plot_out, by, class_col, pool, fleet_out, workers,
    scheduler, quiet, force,
):  # fmt: skip
    """The CVR factor of an on/off test: energy (%dE/%dV) and instantaneous (dP/dV).

    DATA holds head telemetry (a time, V, P, optionally Q). The energy factor comes from
    a Bayesian regression of daily energy on the on/off switching, with the weekday, the
    weather and a drifting level; dP/dV at V0 from the windows around voltage steps.
    With --by, every feeder of a fleet into one table (--out; docs/cvr.md).
    """
    if by or fleet_out:
        return _fleet(locals())
    check_outputs({"--json": json_out, "--plot": plot_out}, [data], force,
                  stdout_ok=("--json",))  # fmt: skip
    if data == "-":
        raise UserError("cvr needs a file (the time column is read apart from V and P)")
    distinct_columns(v_col=v_col, p_col=p_col, q_col=q_col, t_col=t_col,
                     schedule_col=schedule_col, weather_col=weather_col,
                     holiday_col=holiday_col, pv_col=pv_col,
                     instrument_col=instrument_col)  # fmt: skip
    q_name, q_required = q_column(q_col)

    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.cvr import CVR_DEFAULTS, cvr
    from loadbayes.report.cvr import cvr_lines

    if not quiet:
        click.echo(f"loadbayes: reading {data} and fitting the CVR factors...", err=True)
    res = cvr(
        data, t_col=t_col, v_col=v_col, p_col=p_col, q_col=q_name, q_required=q_required,
        v_base=v_base, s_base=s_base, schedule_col=schedule_col, weather_col=weather_col,
        holiday_col=holiday_col, pv_col=pv_col, instrument_col=instrument_col, v0=v0,
        knot_days=knot_days,
        min_switch=min_switch, drop_against=drop_against, instant=not no_instant,
        sampler=SamplerSettings.of(CVR_DEFAULTS, draws=draws, seed=seed),
        drop_invalid=drop_invalid,
    )  # fmt: skip
    inner = res.pop("draws")
    text = json.dumps(res, indent=2, allow_nan=False)
    with output_transaction({"--json": json_out, "--plot": plot_out}, force=force) as out:
        if json_out and json_out != "-":
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        if plot_out:
            from loadbayes.plots.cvr import plot_cvr
            from loadbayes.plots.fit import pyplot

            fig = plot_cvr({**res, "draws": inner})
            target = out.temp("--plot")
            fig.savefig(target, format=target.suffix.lstrip(".").lower(), dpi=110,
                        bbox_inches="tight")  # fmt: skip
            pyplot().close(fig)
    if json_out == "-":
        click.echo(text)
    for w in res["warnings"]:
        click.echo(f"loadbayes: warning: {w}", err=True)
    if not quiet:
        for line in cvr_lines(res):
            click.echo(f"loadbayes: {line}", err=True)


def _fleet(o: dict) -> None:
    """``cvr --by``: every feeder's factors into the fleet table (``loadbayes.cvr_fleet``)."""
    for flag, key in (("--json", "json_out"), ("--plot", "plot_out")):
        if o[key]:
            raise UserError(f"{flag} is for one feeder; a fleet (--by) writes --out")
    if not o["by"]:
        raise UserError("--out is for a fleet: give --by COLUMN (one feeder writes --json)")
    if not o["fleet_out"] or not str(o["fleet_out"]).lower().endswith((".parquet", ".pq")):
        raise UserError("--by needs --out FILE.parquet for the fleet's CVR table")
    if o["pool"] == "class" and not o["class_col"]:
        raise UserError("--pool class needs --class-col")
    check_outputs({"--out": o["fleet_out"]}, [o["data"]], o["force"])
    distinct_columns(v_col=o["v_col"], p_col=o["p_col"], q_col=o["q_col"], t_col=o["t_col"],
                     by=o["by"], class_col=o["class_col"], schedule_col=o["schedule_col"],
                     weather_col=o["weather_col"], holiday_col=o["holiday_col"],
                     pv_col=o["pv_col"], instrument_col=o["instrument_col"])  # fmt: skip
    q_name, q_required = q_column(o["q_col"])

    from loadbayes.commands.output import Progress
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.cvr import CVR_DEFAULTS
    from loadbayes.fleet.cvr import cvr_fleet
    from loadbayes.fleet.engine import Engine
    from loadbayes.fleet.summary import write_parquet
    from loadbayes.report.cvr_fleet import cvr_fleet_lines

    quiet, bar = o["quiet"], {}

    def on_buses(n: int) -> None:
        if not quiet:
            click.echo(f"loadbayes: note: {n} feeders (pool {o['pool']})", err=True)
        bar["b"] = Progress("feeders", n, quiet, eta=True)

    try:
        with Engine(scheduler=o["scheduler"], workers=o["workers"]) as engine:
            res = cvr_fleet(
                o["data"], by=o["by"], class_col=o["class_col"], pool=o["pool"], engine=engine,
                sampler=SamplerSettings.of(CVR_DEFAULTS, draws=o["draws"], seed=o["seed"]),
                progress=lambda n: bar["b"](n), on_buses=on_buses, t_col=o["t_col"],
                v_col=o["v_col"], p_col=o["p_col"], q_col=q_name, q_required=q_required,
                v_base=o["v_base"], s_base=o["s_base"], schedule_col=o["schedule_col"],
                weather_col=o["weather_col"], holiday_col=o["holiday_col"], pv_col=o["pv_col"],
                instrument_col=o["instrument_col"], v0=o["v0"], knot_days=o["knot_days"],
                min_switch=o["min_switch"], drop_against=o["drop_against"],
                instant=not o["no_instant"], drop_invalid=o["drop_invalid"],
            )  # fmt: skip
    finally:
        if "b" in bar:
            bar["b"].close()
    bus = res.table[res.table["level"] == "bus"]
    if len(bus) and bus["parameter"].isna().all():
        first = bus.iloc[0]
        raise UserError(f"{o['data']}: none of the {bus['bus'].nunique()} feeders could be "
                        f"fitted, e.g. {first['bus']}: {first['warnings']}")  # fmt: skip
    with output_transaction({"--out": o["fleet_out"]}, force=o["force"]) as out:
        write_parquet(res.table, out.temp("--out"), atomic=False, settings=res.settings)
    for w in res.settings["warnings"]:
        click.echo(f"loadbayes: warning: {w}", err=True)
    for line in cvr_fleet_lines(res.table, res.settings):
        click.echo(line)
    if not quiet:
        click.echo(f"loadbayes: wrote {o['fleet_out']} ({res.engine})", err=True)
