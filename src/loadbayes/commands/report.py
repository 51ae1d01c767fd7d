"""``loadbayes report``: the HTML report of any fit, from its JSON or NetCDF result."""

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
@click.option("--force", is_flag=True, help="Overwrite an existing report.")
@click.option("--quiet", is_flag=True, help="Do not say where the report was written.")
@user_errors
def report_cmd(result, out, truth, title, force, quiet):
    """Write the HTML report of a fit: RESULT is its .nc (with figures) or .json file.

    The report starts with a summary (what was fitted, the headline numbers with their
    intervals, the diagnostics' verdict, the warnings), then a contents list, the
    parameter table, the load curves, marginals, pair plots and traces (from a NetCDF
    result), the correlations and the settings.
    """
    check_outputs({"--out": out}, [result], force)
    truth_val = _parse_truth(truth)
    from pathlib import Path

    from loadbayes.io.atomic import atomic_write
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
