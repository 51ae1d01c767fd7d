"""``loadbayes reproduce all``: the ZIP and motor studies into one report."""

from __future__ import annotations

import time

import click

from loadbayes.cli import reproduce
from loadbayes.commands.common import user_errors
from loadbayes.commands.zip_study import check_root, run_zip

# Marker of the motor study's section in report.html (experiments.im_study).
_IM_MARK = "loadbayes:section im"


@reproduce.command("all")
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default="results",
    show_default=True,
    help="Results folder: OUT/zip/, OUT/im/ and OUT/report.html.",
)
@click.option("--quick", is_flag=True, help="Small settings (make demo, tests): about a minute.")
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
def reproduce_all_cmd(out, quick, seed, workers, quiet, force):
    """Every study of the paper (ZIP, induction motor) and past it, in one self-contained report.

    After the paper's two studies come the ones that go past it: bad data (Student-t),
    time-varying loads (online tracking), and the choice between ZIP and exponential.
    """
    from loadbayes.cases.motor_sim import MOTORS
    from loadbayes.experiments import im_study, zip_study
    from loadbayes.report.html import write_report

    motors = list(MOTORS)
    targets = zip_study.output_paths(out) + im_study.output_paths(out, motors)
    root = check_root(out, targets, force)

    def say(msg: str) -> None:
        if not quiet:
            click.echo(msg, err=True)

    t0 = time.perf_counter()
    zs = run_zip(
        root, n=None, noise=0.1, seed=seed, quick=quick, workers=workers, quiet=quiet, force=force
    )
    t_zip = time.perf_counter() - t0
    t0 = time.perf_counter()
    ims = im_study.run(motors, seed=seed, quick=quick, progress=say)
    im_study.write(ims, root, force=force)
    t_im = time.perf_counter() - t0
    t0 = time.perf_counter()
    from loadbayes.experiments import fleet_study, model_choice, robust_study, tracking_study

    past = []
    for name, mod in (("robust", robust_study), ("tracking", tracking_study),
                      ("model choice", model_choice), ("fleet", fleet_study)):  # fmt: skip
        say(f"study past the paper: {name}")
        past.append(zip_study.marked(mod.html_section(mod.run(quick=quick, seed=seed)),
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
            "command": "loadbayes reproduce all" + (" --quick" if quick else ""),
            "seed": seed,
            "ZIP study (s)": f"{t_zip:.0f}",
            "motor study (s)": f"{t_im:.0f}",
            "studies past the paper (s)": f"{t_past:.0f}",
            "ZIP: n, noise": f"{zs.settings['n']}, {zs.settings['noise_sd_pu']:g}",
        },
    )
    if not quiet:
        click.echo(zip_study.text_tables(zs))
        click.echo(im_study.text_tables(ims))
        click.echo(f"wrote {root / 'zip'}, {root / 'im'} and {report}")
