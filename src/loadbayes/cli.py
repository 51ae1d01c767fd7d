"""The ``loadbayes`` command line.

Only click is imported at start-up; everything heavy (numba, ArviZ, matplotlib,
pandapower) is imported inside the command that needs it, so ``loadbayes --help`` is fast.
The commands live in :mod:`loadbayes.commands`, one module per subject.

Exit codes: 0 success, 2 bad usage or bad data (one line on stderr naming the file, the
column and the row, never a traceback), 130 interrupted (no output left half-written).
"""

from __future__ import annotations

import click


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="loadbayes")
def main() -> None:
    """Bayesian identification of power-system load models (ZIP, exponential, motor)."""


@main.group()
def fit() -> None:
    """Fit a load model to measurements and write its posterior."""


@main.group()
def simulate() -> None:
    """Simulate measurements from a known load (for studies and tests)."""


@main.group()
def reproduce() -> None:
    """Reproduce the paper's studies into a results folder with a report."""


@main.group()
def track() -> None:
    """Track load-model coefficients over time, sample by sample (online Bayes)."""


# Each module attaches its commands to the groups above (imported last on purpose).
from loadbayes.commands import exp as _exp  # noqa: E402, F401
from loadbayes.commands import im as _im  # noqa: E402, F401
from loadbayes.commands import reproduce_all as _reproduce_all  # noqa: E402, F401
from loadbayes.commands import track as _track  # noqa: E402, F401
from loadbayes.commands import zip as _zip  # noqa: E402, F401
from loadbayes.commands import zip_study as _zip_study  # noqa: E402, F401
from loadbayes.commands.composite import fit_composite_cmd as _fit_composite_cmd  # noqa: E402

fit.add_command(_fit_composite_cmd)
