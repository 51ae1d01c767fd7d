"""``loadbayes archive pool``: each station's composition over the year from its fitted events.

A standalone command, attached to the ``archive`` group in ``cli.py``.
"""

from __future__ import annotations

import json

import click

from loadbayes.commands.options import OneLineCommand
from loadbayes.commands.output import UserError, check_outputs, output_transaction, user_errors


def read_catalog(path: str):
    """The catalog's fits, one row per event and part (``catalog.fits_frame``)."""
    import sqlite3

    from loadbayes.archive.catalog import fits_frame

    try:
        return fits_frame(path)
    except sqlite3.DatabaseError as exc:
        raise UserError(f"{path}: not an archive catalog ({exc})") from None


def read_temperatures(path: str):
    """The temperature CSV (station, time, temperature), its encoding detected."""
    import pandas as pd

    from loadbayes.io.encoding import SNIFF_BYTES, detect_encoding
    from loadbayes.io.errors import DataError

    with open(path, "rb") as fh:
        head = fh.read(SNIFF_BYTES + 1)
    enc = detect_encoding(head[:SNIFF_BYTES], complete=len(head) <= SNIFF_BYTES)
    try:
        return pd.read_csv(path, encoding=enc, dtype={"station": str})
    except (ValueError, pd.errors.ParserError) as exc:
        line = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise DataError(f"not a CSV table ({line})", path) from None


def table_lines(res) -> list[str]:
    """What the command prints: per part, each unit's monthly shares, the groups, words."""
    from loadbayes.archive.pool import MONTHS

    lines = []
    for name, part in res.parts.items():
        lines.append(f"{name}: the median event's share by month (95% bands in --out)")
        lines.append(f"{'station / bay':<24}{'events':>7} " + " ".join(f"{m:>4}" for m in MONTHS))
        for (station, bay), frame in part.monthly.groupby(["station", "bay"], sort=False):
            who = f"{station} / {bay}"
            if station == "(all)":
                who = "population" if bay == "(all)" else f"population / {bay}"
            vals = " ".join(f"{v:4.2f}" for v in frame.sort_values("month")["mean"])
            lines.append(f"{who[:23]:<24}{int(frame['events'].iloc[0]):>7} {vals}")
        groups = "; ".join(", ".join(g) for g in part.groups)
        lines.append(f"{name}: alike within {res.settings['tolerance']:g} (groups): {groups}")
    lines.append(res.events_line())
    return lines


@click.command("pool", cls=OneLineCommand)
@click.option("--catalog", required=True, type=click.Path(exists=True, dir_okay=False),
              help="The archive's catalog (written by archive scan / fit).")  # fmt: skip
@click.option("--temperature", "temperature_csv", type=click.Path(exists=True, dir_okay=False),
              help="CSV of station, time, temperature (C): a temperature term.")  # fmt: skip
@click.option("--hour", is_flag=True, help="Add the hour of day (two harmonics).")
@click.option("--by-bay", is_flag=True,
              help="A population per bay name across stations (bays named alike at every "
              "station), instead of one for all bays.")  # fmt: skip
@click.option("--tolerance", type=click.FloatRange(0, 1, min_open=True, max_open=True),
              default=0.1, show_default=True,
              help="Share difference under which two stations' curves are alike.")  # fmt: skip
@click.option("--draws", type=click.IntRange(min=50), default=1000, show_default=True,
              help="Kept draws per chain (after half as many of burn-in).")  # fmt: skip
@click.option("--chains", type=click.IntRange(min=1), default=4, show_default=True)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--out", "json_out", type=click.Path(dir_okay=False),
              help="The result as JSON ('-': standard output).")  # fmt: skip
@click.option("--plot", "plot_out", type=click.Path(dir_okay=False),
              help="Composition over the year per station with bands (PNG, SVG, PDF).")  # fmt: skip
@click.option("--quiet", is_flag=True, help="No lines on standard error but warnings.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def pool_cmd(catalog, temperature_csv, hour, by_bay, tolerance, draws, chains, seed, json_out,
             plot_out, quiet, force):  # fmt: skip
    """Pool each station's fitted events: its composition over the year, with bands.

    Per part share (the motor's for zip+motor), a hierarchical model over the stations'
    bays: a seasonal curve per bay, event-to-event spread around it, the curves pooled
    across stations. Says which stations are alike, different, or not told apart. Each
    event's share is pooled when its chains agree on it (R-hat < 1.05) with 100 effective
    draws or more, whatever its other coordinates did; the others are left out and
    counted by reason.
    """
    inputs = [catalog] + ([temperature_csv] if temperature_csv else [])
    check_outputs({"--out": json_out, "--plot": plot_out}, inputs, force,
                  stdout_ok=("--out",))  # fmt: skip
    from loadbayes.archive.pool import pool

    frame = read_catalog(catalog)
    temps = read_temperatures(temperature_csv) if temperature_csv else None
    if not quiet:
        click.echo(f"loadbayes: pooling {len(frame)} fitted shares from {catalog}...", err=True)
    res = pool(frame, covariates=("season", "hour") if hour else ("season",),
               temperature=temps, draws=draws, chains=chains, seed=seed, tolerance=tolerance,
               by_bay=by_bay, source=catalog,
               temperature_source=temperature_csv or "")  # fmt: skip
    text = json.dumps(res.to_dict(), indent=2, allow_nan=False)
    with output_transaction({"--out": json_out, "--plot": plot_out}, force=force) as out:
        if json_out and json_out != "-":
            out.temp("--out").write_text(text + "\n", encoding="utf-8")
        if plot_out:
            from loadbayes.plots.archive_pool import plot_pool
            from loadbayes.plots.fit import save_figure

            fig = plot_pool(res)
            save_figure(fig, out.temp("--plot"), force=True)
    if json_out == "-":
        click.echo(text)
    for w in res.warnings:
        click.echo(f"loadbayes: warning: {w}", err=True)
    if not quiet:
        for line in res.notes + table_lines(res):
            click.echo(f"loadbayes: {line}", err=True)
