"""``loadbayes archive scan|fit``: a recorder archive into a catalog, and its events fitted.

Standalone click objects (this module does not import :mod:`loadbayes.cli`); ``cli.py``
attaches the group. The work is :func:`loadbayes.archive.scan` and
:func:`loadbayes.archive.fit`; here are the options, the progress and the words.
"""

from __future__ import annotations

import sys
import time

import click

from loadbayes.commands.options import OneLineCommand
from loadbayes.commands.output import UserError, user_errors

__all__ = ["archive_group"]


@click.group("archive")
def archive_group() -> None:
    """A recorder archive: COMTRADE files scanned into a catalog, their events fitted."""


def _bar(total: int, label: str, quiet: bool):
    """A click progress bar on a terminal's stderr (None in a pipe, a log, or --quiet)."""
    if quiet or total == 0 or not sys.stderr.isatty():
        return None
    bar = click.progressbar(length=total, label=label, file=sys.stderr, show_pos=True,
                            show_eta=True, item_show_func=lambda x: x)  # fmt: skip
    bar.__enter__()
    return bar


@archive_group.command("scan", cls=OneLineCommand)
@click.argument("folder", type=click.Path(file_okay=True, dir_okay=True))
@click.option("--catalog", required=True, type=click.Path(dir_okay=False),
              help="The SQLite catalog (made if missing; a rescan adds new or changed "
              "files).")  # fmt: skip
@click.option("--rules", type=click.Path(dir_okay=False),
              help="TOML of bay name rules, pattern = kind (\"主变\" = \"transformer\"), tried "
              "before the defaults.")  # fmt: skip
@click.option("--workers", type=click.IntRange(1, None),
              help="Read the files in N processes (default: this one).")  # fmt: skip
@click.option("--quiet", is_flag=True)
@user_errors
def archive_scan_cmd(folder, catalog, rules, workers, quiet):
    """Walk FOLDER's COMTRADE records into the catalog: station, bays, dips found.

    Every .cfg at any depth is read (any revision, data format, encoding). A file the
    reader refuses is recorded with the reason; the scan goes on. Dips of 4 % or more of
    the lowest phase's RMS voltage are events, as a recorder's trigger finds them.
    """
    from loadbayes.archive import scan

    state: dict = {"bar": None, "done": 0}

    def progress(done: int, total: int, path: str) -> None:
        if state["bar"] is None and state["done"] == 0:
            state["bar"] = _bar(total, "files", quiet)
        if state["bar"] is not None:
            state["bar"].current_item = path[-40:]
            state["bar"].update(done - state["done"])
        state["done"] = done

    try:
        out = scan(folder, catalog, rules=rules, progress=progress, workers=workers)
    finally:
        if state["bar"] is not None:
            state["bar"].__exit__(None, None, None)
    if not quiet:
        click.echo(f"{catalog}: {out.line()}", err=True)
        for path, reason in out.broken_files[:20]:
            click.echo(f"  broken: {path}: {reason}", err=True)
        if len(out.broken_files) > 20:
            click.echo(f"  ... and {len(out.broken_files) - 20} more broken files", err=True)


@archive_group.command("fit", cls=OneLineCommand)
@click.option("--catalog", required=True, type=click.Path(dir_okay=False),
              help="The catalog of loadbayes archive scan.")  # fmt: skip
@click.option("--model", default="zip+motor", show_default=True,
              help="The dynamic load model: zip+motor, slm, cmld-lite.")  # fmt: skip
@click.option("--draws", type=int, default=6000, show_default=True,
              help="Iterations per chain, fixed (zip+motor's first round; a model of parts "
              "mixes slower: raise it).")  # fmt: skip
@click.option("--burn", type=int, default=4000, show_default=True, help="Burn-in per chain.")
@click.option("--chains", type=int, default=4, show_default=True)
@click.option("--seed", type=int, default=0, show_default=True,
              help="Each event's seed comes from it and the event's content hash.")  # fmt: skip
@click.option("--per-cycle", type=click.IntRange(1, 64), default=4, show_default=True,
              help="Phasor estimates per cycle of the fitted rows.")  # fmt: skip
@click.option("--window-s", type=click.FloatRange(0.0, 1.0),
              help="The model's phasor window (s); default one cycle, 0: point "
              "samples.")  # fmt: skip
@click.option("--workers", type=click.IntRange(1, None), help="A local Dask cluster of N workers.")
@click.option("--scheduler", help="The address of a running Dask scheduler (tcp://host:8786).")
@click.option("--retry-failed", is_flag=True, help="Fit again the events whose fit failed.")
@click.option("--quiet", is_flag=True)
@user_errors
def archive_fit_cmd(catalog, model, draws, burn, chains, seed, per_cycle, window_s, workers,
                    scheduler, retry_failed, quiet):  # fmt: skip
    """Fit every usable event of the catalog, each result kept as it finishes.

    A killed run loses only the fits in flight; run again to resume (no event is fitted
    twice). The draws go to NetCDF files in CATALOG's .results folder beside it. With
    --scheduler, the workers read the records and write that folder by the catalog's
    paths: both must be on storage every worker sees.
    """
    from loadbayes.archive import fit

    if workers and scheduler:
        raise UserError("give --workers or --scheduler, not both")
    state: dict = {"bar": None, "done": 0, "failed": 0, "t0": time.monotonic()}

    def start(todo: int, already: int) -> None:
        if not quiet:
            click.echo(
                f"{catalog}: {todo} event(s) to fit with {model}, {already} already in the catalog",
                err=True,
            )
        state["bar"] = _bar(todo, "fits", quiet)

    def progress(result: dict, done: int, failed: int, left: int) -> None:
        state.update(done=done, failed=failed)
        if state["bar"] is not None:
            state["bar"].current_item = f"done {done}, failed {failed}, left {left}"
            state["bar"].update(1)
            return
        # No terminal (a batch job's log): a line at every tenth of the run.
        total = done + failed + left
        if quiet or (done + failed) % max(total // 10, 1) and left:
            return
        spent = time.monotonic() - state["t0"]
        eta = spent / (done + failed) * left
        click.echo(f"fits: {done} done, {failed} failed, {left} left, about {eta / 60:.1f} "
                   "min left", err=True)  # fmt: skip

    try:
        run = fit(
            catalog, model=model, draws=draws, burn=burn, chains=chains, seed=seed,
            per_cycle=per_cycle, window_s=window_s, workers=workers, scheduler=scheduler,
            retry_failed=retry_failed, progress=progress, start=start,
        )  # fmt: skip
    except KeyboardInterrupt:
        if state["bar"] is not None:
            state["bar"].__exit__(None, None, None)
        click.echo(
            f"loadbayes: interrupted; {state['done']} fit(s) and {state['failed']} failure(s) "
            f"of this run are kept in {catalog}: run the same command to resume",
            err=True,
        )
        sys.exit(130)
    if state["bar"] is not None:
        state["bar"].__exit__(None, None, None)
    if not quiet:
        click.echo(f"{catalog}: {run.line()}", err=True)
