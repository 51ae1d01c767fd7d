"""``loadbayes example``: print a small data file shipped with the package."""

from __future__ import annotations

import click

from loadbayes.commands.options import OneLineCommand

#: Example files by name, in ``loadbayes/data``.
EXAMPLES = {"zip": "zip_example.csv"}


@click.command("example", cls=OneLineCommand)
@click.argument("name", type=click.Choice(sorted(EXAMPLES)))
def example_cmd(name):
    """Print an example data file to stdout, e.g. loadbayes example zip > bus.csv.

    zip: a day of 1-minute samples at an 11 kV bus, columns time, v (kV), p (MW),
    q (Mvar); a ZIP load with shares a1..a3 = 0.30, 0.25, 0.45 and a4..a6 = 0.60, 0.10,
    0.30 at 5 MW and 2 Mvar. Fit it with ``loadbayes fit zip bus.csv --v-base 11
    --s-base 5 --p0 1 --q0 0.4``.
    """
    from importlib.resources import files

    text = files("loadbayes").joinpath("data", EXAMPLES[name]).read_text(encoding="utf-8")
    click.echo(text, nl=False)
