"""What every command does with its outputs: one-line errors, output checks, progress, writing."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Any

import click

EXIT_DATA = 2


class UserError(click.ClickException):
    """A one-line error for the user, exit code 2."""

    exit_code = EXIT_DATA

    def show(self, file: Any = None) -> None:  # noqa: D102
        click.echo(f"loadbayes: error: {self.format_message()}", err=True)


def user_errors(func):
    """Turn the library's user-facing exceptions into one-line errors with exit code 2."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from loadbayes.io.errors import DataError

        try:
            return func(*args, **kwargs)
        except DataError as exc:
            raise UserError(str(exc)) from None
        except (FileExistsError, ValueError) as exc:
            raise UserError(str(exc)) from None
        except KeyboardInterrupt as exc:
            done = getattr(exc, "written", [])
            if done:
                msg = f"interrupted; only {', '.join(done)} written (complete), the rest not"
            else:
                msg = "interrupted; no output was written"
            click.echo(f"loadbayes: {msg}", err=True)
            sys.exit(130)

    return wrapper


def check_outputs(outputs: dict[str, str | None], inputs: list[str], force: bool) -> None:
    """Refuse before any work: an existing output without --force, or an output = input."""
    seen: dict[Path, str] = {}

    def resolve(path: str, what: str) -> Path:
        try:
            return Path(path).resolve()
        except (OSError, RuntimeError) as exc:  # a symlink loop, say
            raise UserError(f"{path}: {what} cannot be resolved ({exc})") from None

    ins = {resolve(p, "the input") for p in inputs if p and p != "-"}
    for opt, path in outputs.items():
        if not path:
            continue
        p = Path(path)
        rp = resolve(path, opt)
        if rp in ins:
            raise UserError(f"{path}: {opt} would overwrite the input data")
        if rp in seen:
            raise UserError(f"{path}: given to both {seen[rp]} and {opt}")
        seen[rp] = opt
        if p.is_dir():
            raise UserError(f"{path}: {opt} is a directory")
        if p.exists() and not force:
            raise UserError(f"{path}: exists; use --force to overwrite")
        if not p.parent.exists():
            raise UserError(f"{path}: folder {p.parent} does not exist")


class Progress:
    """A progress bar on stderr (a no-op with --quiet); a plain count when the total is unknown."""

    def __init__(self, label: str, total: int | None, quiet: bool) -> None:
        self.bar = None
        self.label = label
        self.count = 0
        self.quiet = quiet
        if not quiet and total:
            self.bar = click.progressbar(
                length=total, label=label, file=sys.stderr, show_pos=True, show_eta=False
            )
            self.bar.__enter__()

    def __call__(self, n: int) -> None:
        self.count += n
        if self.bar is not None:
            self.bar.update(n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
            if not sys.stderr.isatty():
                click.echo("", err=True)
        elif not self.quiet and self.count:
            click.echo(f"{self.label}: {self.count} rows", err=True)
        self.quiet = True


def estimate_rows(path: str) -> int | None:
    """Rows in a data file: exact for Parquet, estimated from the size for CSV."""
    p = Path(path)
    if path == "-" or not p.is_file():
        return None
    try:
        if p.suffix.lower() in (".parquet", ".pq"):
            import pyarrow.parquet as pq

            return pq.ParquetFile(p).metadata.num_rows
        with open(p, "rb") as fh:
            head = fh.read(1 << 16)
        lines = head.count(b"\n")
        if lines < 2:
            return None
        return max(int(p.stat().st_size / (len(head) / lines)) - 1, 1)
    except Exception:  # an estimate only: the reader reports real problems
        return None


def write_outputs(post, *, model, hdi_prob, json_out, netcdf_out, plot_out, force, quiet):
    """Write the JSON, NetCDF and figure (each optional); print the table unless quiet."""
    from loadbayes.report.text import summary_table

    if not quiet:
        click.echo("loadbayes: summarising the draws (R-hat, ESS)...", err=True)
    table = post.summary(hdi_prob=hdi_prob)
    written: list[str] = []
    try:
        if json_out:
            post.to_json(json_out, hdi_prob=hdi_prob, force=force, summary=table)
            written.append(str(json_out))
        if netcdf_out:
            if not quiet:
                click.echo(f"loadbayes: writing {netcdf_out} (draws, predictions)...", err=True)
            post.to_netcdf(netcdf_out, force=force)
            written.append(str(netcdf_out))
        if plot_out:
            from loadbayes.plots import plot_fit, save_figure

            save_figure(plot_fit(post, model=model, hdi_prob=hdi_prob), plot_out, force=force)
            written.append(str(plot_out))
    except KeyboardInterrupt as exc:
        # Each file is atomic; say truthfully which ones were completed before the stop.
        exc.written = written  # type: ignore[attr-defined]
        raise
    for w in post.warnings:
        click.echo(f"loadbayes: warning: {w}", err=True)
    if not quiet:
        click.echo(summary_table(post, hdi_prob=hdi_prob, summary=table))


def sidecar(path: str) -> Path | None:
    """The JSON settings file written beside a data file (``data.csv`` -> ``data.json``)."""
    if path == "-":
        return None
    p = Path(path)
    side = p.with_suffix(".json")
    return side if side != p else None
