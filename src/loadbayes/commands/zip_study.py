"""``loadbayes reproduce zip``: the paper's ZIP study on the IEEE 33-bus feeder."""

from __future__ import annotations

from pathlib import Path

import click

from loadbayes.cli import reproduce
from loadbayes.commands.common import UserError, user_errors


def check_root(out: str, targets: list[Path], force: bool) -> Path:
    """Refuse before any work: ``--out`` not a folder, or results there without --force."""
    root = Path(out)
    if root.exists() and not root.is_dir():
        raise UserError(f"{out}: --out is not a folder")
    if not force:
        existing = [str(p) for p in targets if p.exists()]
        if existing:
            raise UserError(f"{existing[0]}: exists; use --force to overwrite")
    return root


def run_zip(
    root: Path,
    *,
    n: int | None,
    noise: float,
    seed: int,
    quick: bool,
    workers: int,
    quiet: bool,
    force: bool,
):
    """Run and write the ZIP study; return it (shared with ``reproduce all``)."""
    from loadbayes.experiments import zip_study

    def say(msg: str) -> None:
        if not quiet:
            click.echo(msg, err=True)

    study = zip_study.run(
        n,
        noise,
        seed,
        quick,
        workers=workers,
        progress=say,
        pf_progress=not quiet,
    )
    say("zip: writing tables, figures and the report section ...")
    root.mkdir(parents=True, exist_ok=True)
    zip_study.write(study, root, force=force)
    return study


@reproduce.command("zip")
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default="results",
    show_default=True,
    help="Results folder: writes OUT/zip/ and the ZIP section of OUT/report.html.",
)
@click.option(
    "--n",
    "n",
    type=click.IntRange(min=10),
    help="Experiments fitted (the paper does not say) [1000; 300 with --quick].",
)
@click.option(
    "--noise",
    type=click.FloatRange(min=0, min_open=True),
    default=0.1,
    show_default=True,
    help="Noise sd on P and Q in p.u. of P0, Q0 (the paper's '10%').",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of data and samplers.")
@click.option(
    "--quick",
    is_flag=True,
    help="Small n, sweep to 1,000, fewer draws and a small predictive band (< 1 min).",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Processes for the power flows (the numbers do not depend on it).",
)
@click.option("--quiet", is_flag=True, help="No progress and no tables on the terminal.")
@click.option("--force", is_flag=True, help="Overwrite existing results.")
@user_errors
def reproduce_zip_cmd(out, n, noise, seed, quick, workers, quiet, force):
    """The paper's ZIP study: data by power flow, GS/LS/KF, validation, Table II, sweep."""
    from loadbayes.experiments import zip_study

    root = check_root(out, zip_study.output_paths(out), force)
    study = run_zip(
        root,
        n=n,
        noise=noise,
        seed=seed,
        quick=quick,
        workers=workers,
        quiet=quiet,
        force=force,
    )
    if not quiet:
        click.echo(zip_study.text_tables(study))
        click.echo(f"wrote {root / 'zip'} and {root / 'report.html'}")
