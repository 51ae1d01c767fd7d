"""``loadbayes report``: the HTML report of a fit, a fleet or an archive's catalog.

The command dispatches on the file's type: a Parquet file is a fleet table, an SQLite file
(by its header, or a ``.db`` suffix) an archive's catalog, any other a fit's JSON or NetCDF.
"""

from __future__ import annotations

import click

from loadbayes.commands.options import OneLineCommand
from loadbayes.commands.output import UserError, check_outputs, user_errors


def _parse_truth(items: tuple[str, ...]) -> dict[str, float]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise click.BadParameter(
                f"{item!r}: expected NAME=VALUE such as a1=0.3", param_hint="--truth"
            ) from None
    return out


@click.command("report", cls=OneLineCommand)
@click.argument("result", type=str)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False),
    required=True,
    help="The HTML report to write (self-contained: open it in any browser).",
)
@click.option(
    "--truth",
    multiple=True,
    metavar="NAME=VALUE",
    help="A known true value (simulated data), flagged where the interval misses it; repeatable.",
)
@click.option("--title", help="Page title (default: the model and the data).")
@click.option(
    "--coords",
    type=str,
    metavar="FILE",
    help="A fleet's bus coordinates: CSV/Parquet with the bus column and x, y or lat, lon "
    "(the fleet's input will do); draws dP/dV and dQ/dV on a map.",
)
@click.option(
    "--unpooled",
    type=str,
    metavar="FILE",
    help="A --pool none fleet table of the same buses: each bus's own estimate, drawn "
    "against its pooled one.",
)
@click.option(
    "--pool",
    "pool_json",
    type=str,
    metavar="FILE",
    help="An archive's catalog: the composition from this archive pool --out JSON "
    "(default: pooled here with 500 draws x 4 chains).",
)
@click.option("--force", is_flag=True, help="Overwrite an existing report.")
@click.option("--quiet", is_flag=True, help="Do not say where the report was written.")
@user_errors
def report_cmd(result, out, truth, title, coords, unpooled, pool_json, force, quiet):
    """Write the HTML report of RESULT: a fit's .nc or .json, a fleet's .parquet, a catalog.

    A catalog is an archive's archive.db (loadbayes archive scan).

    The report starts with a summary (what was fitted, the headline numbers with their
    intervals, the diagnostics' verdict, the warnings), then a contents list, the
    parameter table, the load curves, marginals, pair plots and traces (from a NetCDF
    result), the correlations and the settings. A fleet's report has the class mixes,
    the shrinkage, the buses flagged, dP/dV and dQ/dV per bus and the settings. An
    archive's has its stations and bays, the events per month, each station's composition
    over the year with bands, and what failed and why.
    """
    check_outputs({"--out": out}, [result, coords or "", unpooled or "", pool_json or ""], force)
    truth_val = _parse_truth(truth)
    from pathlib import Path

    from loadbayes.io.atomic import atomic_write
    from loadbayes.report.archive_report import is_catalog
    from loadbayes.report.fleet_table import is_parquet

    if is_catalog(result):
        for flag, value in (("--truth", truth_val), ("--coords", coords), ("--unpooled", unpooled)):
            if value:
                raise UserError(f"{flag} is not for an archive's catalog ({result})")
        _archive(result, out, pool_json, title, force, quiet)
        return
    if pool_json:
        raise UserError(f"--pool is for an archive's catalog; {result} is not one")
    if is_parquet(result):
        if truth_val:
            raise UserError("--truth is for the report of one fit, not of a fleet")
        _fleet(result, out, coords, unpooled, title, force, quiet)
        return
    for flag, value in (("--coords", coords), ("--unpooled", unpooled)):
        if value:
            raise UserError(f"{flag} is for a fleet's .parquet table; {result} is not one")
    from loadbayes.report.fit_report import fit_report, load_result

    d, post = load_result(result)
    if not quiet:
        click.echo(f"loadbayes: drawing the figures of {result}...", err=True)
    try:
        text = fit_report(d, post, truth=truth_val, title=title, source=Path(result).name)
    except KeyError as exc:  # a JSON result missing a field of the contract
        raise UserError(f"{result}: not a complete loadbayes result (no {exc})") from None
    with atomic_write(Path(out), force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    if not quiet:
        click.echo(f"loadbayes: wrote {out}", err=True)


def _fleet(result, out, coords, unpooled, title, force, quiet) -> None:
    from loadbayes.report.fleet_report import write_fleet_report
    from loadbayes.report.fleet_table import load_fleet

    load_fleet(result)  # a bad table is the run's one line, before the note below
    if not quiet:
        click.echo(f"loadbayes: drawing the figures of the fleet {result}...", err=True)
    write_fleet_report(result, out, unpooled=unpooled, coords=coords, title=title, force=force)
    if not quiet:
        click.echo(f"loadbayes: wrote {out}", err=True)


def _archive(result, out, pool_json, title, force, quiet) -> None:
    from loadbayes.report.archive_report import POOL_CHAINS, POOL_DRAWS, write_archive_report

    if not quiet:
        how = f"the pool of {pool_json}" if pool_json else (
            f"pooling its fits ({POOL_DRAWS} draws x {POOL_CHAINS} chains)")  # fmt: skip
        click.echo(f"loadbayes: reporting the archive {result}, {how}...", err=True)
    write_archive_report(result, out, pool=pool_json, title=title, force=force)
    if not quiet:
        click.echo(f"loadbayes: wrote {out}", err=True)
