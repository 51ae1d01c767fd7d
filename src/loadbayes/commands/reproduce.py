"""``loadbayes reproduce zip|im|all``: the paper's studies, and the ones past it, into a report."""

from __future__ import annotations

import time
from pathlib import Path

import click

from loadbayes.commands.options import MOTOR_NAMES, OneLineCommand
from loadbayes.commands.output import UserError, user_errors


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
    smoke: bool = False,
):
    """Run and write the ZIP study; return it (shared with ``reproduce all``)."""
    from loadbayes.studies import zip_paper as zip_study

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
        smoke=smoke,
    )
    say("zip: writing tables, figures and the report section ...")
    root.mkdir(parents=True, exist_ok=True)
    zip_study.write(study, root, force=force)
    return study


@click.command("zip", cls=OneLineCommand)
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
    from loadbayes.studies import zip_paper as zip_study

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


@click.command("im", cls=OneLineCommand)
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default="results",
    show_default=True,
    help="Results folder: writes OUT/im/ and the IM section of OUT/report.html.",
)
@click.option(
    "--motor",
    "motors",
    multiple=True,
    type=click.Choice(MOTOR_NAMES),
    help="Motors to study (repeatable) [all four].",
)
@click.option("--noise", type=click.FloatRange(min=0), default=0.05, show_default=True)
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--quick", is_flag=True, help="Fewer draws (for make demo and tests).")
@click.option("--quiet", is_flag=True, help="No progress messages.")
@click.option("--force", is_flag=True, help="Overwrite existing results.")
@user_errors
def reproduce_im_cmd(out, motors, noise, seed, quick, quiet, force):
    """The paper's induction-motor study: Table I, Table III, Fig. 6, physical parameters."""
    from loadbayes.studies import im_paper as im_study

    root = Path(out)
    if root.exists() and not root.is_dir():
        raise UserError(f"{out}: --out is not a folder")
    motors = list(motors) or list(MOTOR_NAMES)
    targets = im_study.output_paths(root, motors)
    existing = [str(p) for p in targets if p.exists()]
    if existing and not force:
        raise UserError(f"{existing[0]}: exists; use --force to overwrite")

    def say(msg: str) -> None:
        if not quiet:
            click.echo(msg, err=True)

    study = im_study.run(motors, noise=noise, seed=seed, quick=quick, progress=say)
    paths = im_study.write(study, root, force=force)
    if not quiet:
        click.echo(im_study.text_tables(study))
        click.echo(f"wrote {len(paths)} files under {root / 'im'} and {root / 'report.html'}")


#: What ``reproduce all --smoke`` says on stdout and atop the report.
SMOKE_NOTE = (
    "--smoke: a pipeline check, not results. Every section ran at sizes too small for "
    "its numbers to mean anything; run --quick or the full study for results."
)
# Marker of the motor study's section in report.html (experiments.im_study).
_IM_MARK = "loadbayes:section im"


@click.command("all", cls=OneLineCommand)
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default="results",
    show_default=True,
    help="Results folder: OUT/zip/, OUT/im/ and OUT/report.html.",
)
@click.option("--quick", is_flag=True, help="Small settings (make demo, tests): about a minute.")
@click.option(
    "--smoke",
    is_flag=True,
    help="A pipeline check, not results: every section's whole code path at the smallest "
    "sizes that still write every file and section (the tests' check).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of every study.")
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Processes for the power flows of the ZIP study.",
)
@click.option("--quiet", is_flag=True, help="No progress messages.")
@click.option("--force", is_flag=True, help="Overwrite existing results.")
@user_errors
def reproduce_all_cmd(out, quick, smoke, seed, workers, quiet, force):
    """Every study of the paper (ZIP, induction motor) and past it, in one self-contained report.

    After the paper's two studies come the ones that go past it: bad data (Student-t),
    time-varying loads (online tracking), and the choice between ZIP and exponential.

    ``--smoke`` runs every step of every section at sizes too small for its numbers to
    mean anything (a check that the pipeline runs and writes everything, for the tests);
    the report's summary and stdout say so, even with ``--quiet``.
    """
    from loadbayes.models.motor_library import MOTORS
    from loadbayes.studies import im_paper as im_study
    from loadbayes.studies import zip_paper as zip_study
    from loadbayes.studies.report import write_report

    motors = list(MOTORS)
    targets = zip_study.output_paths(out) + im_study.output_paths(out, motors)
    root = check_root(out, targets, force)

    def say(msg: str) -> None:
        if not quiet:
            click.echo(msg, err=True)

    t0 = time.perf_counter()
    zs = run_zip(
        root, n=None, noise=0.1, seed=seed, quick=quick, workers=workers, quiet=quiet,
        force=force, smoke=smoke,
    )  # fmt: skip
    t_zip = time.perf_counter() - t0
    t0 = time.perf_counter()
    ims = im_study.run(motors, seed=seed, quick=quick, progress=say, smoke=smoke)
    im_study.write(ims, root, force=force)
    t_im = time.perf_counter() - t0
    t0 = time.perf_counter()
    from loadbayes.studies import archive as archive_study
    from loadbayes.studies import composite as composite_study
    from loadbayes.studies import cvr as cvr_study
    from loadbayes.studies import fleet as fleet_study
    from loadbayes.studies import model_choice
    from loadbayes.studies import planning as planning_study
    from loadbayes.studies import real_record as real_record_study
    from loadbayes.studies import real_record_physical as physical_study
    from loadbayes.studies import robust as robust_study
    from loadbayes.studies import tracking as tracking_study

    past = []
    for name, mod in (("composite", composite_study), ("real record", real_record_study),
                      ("physical load", physical_study), ("planning", planning_study),
                      ("robust", robust_study),
                      ("tracking", tracking_study), ("model choice", model_choice),
                      ("fleet", fleet_study), ("cvr", cvr_study),
                      ("archive", archive_study)):  # fmt: skip
        say(f"study past the paper: {name}")
        past.append(zip_study.marked(mod.html_section(mod.run(quick=quick, seed=seed, smoke=smoke)),
                                     f"loadbayes:section {name.replace(' ', '-')}"))  # fmt: skip
    t_past = time.perf_counter() - t0
    # One page, ZIP first as in the paper; each section keeps its markers so that a later
    # ``reproduce zip`` or ``reproduce im`` replaces only its own.
    sections = [
        zip_study.marked((root / "zip" / "section.html").read_text(encoding="utf-8").strip()),
        zip_study.marked(
            (root / "im" / "section.html").read_text(encoding="utf-8").strip(), _IM_MARK
        ),
        *past,
    ]
    report = write_report(
        root / "report.html",
        sections,
        settings={
            "command": "loadbayes reproduce all"
            + (" --quick" if quick else "")
            + (" --smoke" if smoke else ""),
            "seed": seed,
            "ZIP study (s)": f"{t_zip:.0f}",
            "motor study (s)": f"{t_im:.0f}",
            "studies past the paper (s)": f"{t_past:.0f}",
            "ZIP: n, noise": f"{zs.settings['n']}, {zs.settings['noise_sd_pu']:g}",
        },
        summary=f"<p><strong>{SMOKE_NOTE}</strong></p>" if smoke else "",
    )
    if not quiet:
        click.echo(zip_study.text_tables(zs))
        click.echo(im_study.text_tables(ims))
        click.echo(f"wrote {root / 'zip'}, {root / 'im'} and {report}")
    if smoke:
        click.echo(SMOKE_NOTE)
