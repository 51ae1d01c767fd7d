"""What every command does with its outputs: one-line errors, output checks, progress, writing.

One idea at about 580 lines, a command's outputs as one transaction, from the checks before
the work to the rename at the end (standard output included: written whole or said).

A run is one transaction: every output path and format is checked before any work
(:func:`check_outputs`), the cost of the draws is said before it is paid
(:func:`check_cost`), outputs are written to temporary files and renamed together at the
end (:func:`write_outputs`, :class:`loadbayes.io.transaction.OutputSet`), and SIGINT or
SIGTERM at any moment ends the run with one line, exit 130 or 143, and either every
output or none (:func:`user_errors`; the handlers are in :mod:`.signals`).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import io
import json
import os
import shutil
import signal
import sys
import warnings
from pathlib import Path
from typing import Any

import click

from loadbayes.commands.signals import (
    _STOP,
    EXIT_SIGNAL,
    install_signal_handlers,
    restore_signal_handlers,
    stop_if_signalled,
)

EXIT_DATA = 2

#: Figure formats matplotlib writes (checked before any work, not after the fit).
PLOT_FORMATS = ("png", "svg", "svgz", "pdf", "eps", "ps", "jpg", "jpeg", "tif", "tiff", "webp")
#: Memory above this share of the available memory is refused before sampling.
MEMORY_SHARE = 0.8
#: Above these, a line on stderr says what the run will take.
NOTICE_BYTES = 500 * 2**20


class UserError(click.ClickException):
    """A one-line error for the user, exit code 2."""

    exit_code = EXIT_DATA

    def show(self, file: Any = None) -> None:  # noqa: D102
        click.echo(f"loadbayes: error: {self.format_message()}", err=True)


def _speak(message: str) -> None:
    """One warning line per library warning, in loadbayes' voice (never a raw warning)."""
    click.echo(f"loadbayes: warning: {message}", err=True)


def _warning_origin(filename: str | None) -> str | None:
    """The package a warning came from (``numpy``), or None for loadbayes' own code.

    Only a path under ``site-packages`` names a package; loadbayes (wherever it is
    installed or checked out) and anything else get no ``(from ...)``.
    """
    path = (filename or "").replace("\\", "/")
    if "/site-packages/" not in path:
        return None
    origin = path.split("/site-packages/")[-1].split("/")[0]
    return None if not origin or origin == "loadbayes" else origin


def user_errors(func):
    """Run a command as one transaction: one-line errors (exit 2), signals (130, 143).

    Library warnings are caught and said once each, in one line; SIGINT and SIGTERM
    stop the run with one line saying what was written (all outputs or none).
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from loadbayes.io.errors import DataError

        install_signal_handlers()
        try:
            with warnings.catch_warnings(record=True) as caught:
                try:
                    result = func(*args, **kwargs)
                    # What the command printed must have reached standard output whole
                    # (a full disk or a file-size limit cut it silently, exit 0).
                    failed = stdout_failure()
                    if failed is not None:
                        raise UserError(stdout_line(failed))
                    return result
                finally:
                    seen = set()
                    for w in caught:
                        text = (str(w.message).strip().splitlines() or [""])[0]
                        origin = _warning_origin(w.filename)
                        line = f"{text} (from {origin})" if origin else text
                        if line not in seen:
                            seen.add(line)
                            _speak(line)
        except MemoryError:
            raise UserError(memory_line()) from None
        except ImportError as exc:
            if "failed to map segment" in str(exc):  # a library unmapped under ulimit -v
                raise UserError(memory_line()) from None
            # A signal during a compiled module's import (the commands import their
            # libraries as they run: SciPy's HiGHS) comes out as "ImportError:
            # initialization failed" caused by the KeyboardInterrupt: the signal still.
            if _STOP["signal"] is None or not _caused_by_interrupt(exc):
                raise
            del exc
            _say_interrupted()
        except DataError as exc:
            raise UserError(str(exc)) from None
        except (FileExistsError, ValueError) as exc:
            raise UserError(str(exc)) from None
        except OSError as exc:
            raise UserError(_os_error_line(exc)) from None
        except Exception as exc:
            # A signal that lands where Python wraps the exception it raises comes out as
            # another exception whose cause is the KeyboardInterrupt: a Python callback of
            # a compiled function (numba's dispatcher: "SystemError: ... returned a result
            # with an exception set"), or a class being created during an import
            # ("RuntimeError: Error calling __set_name__"). It is the signal all the same.
            if _STOP["signal"] is None or not _caused_by_interrupt(exc):
                raise
            del exc
            _say_interrupted()
        except KeyboardInterrupt as exc:
            del exc
            _say_interrupted()
        finally:
            restore_signal_handlers()

    return wrapper


class _WholeWrites(io.RawIOBase):
    """File descriptor 1 where every write is whole or an ``OSError``, never short.

    Python's own standard output drops the rest of a write that ``write(2)`` cut short
    (a file-size limit: 10,240 of 57,481 bytes written, the flush "succeeds", exit 0;
    the red-team's H3). The first failure is kept in :attr:`failed`.
    """

    failed: OSError | None = None

    def writable(self) -> bool:  # noqa: D102
        return True

    def fileno(self) -> int:  # noqa: D102
        return 1

    def isatty(self) -> bool:  # noqa: D102
        return os.isatty(1)

    def write(self, data) -> int:  # noqa: D102
        view = memoryview(data).cast("B")
        done = 0
        while done < len(view):
            try:
                done += os.write(1, view[done:])
            except OSError as exc:
                if not isinstance(exc, BrokenPipeError):  # a reader gone: click's case
                    _WholeWrites.failed = _WholeWrites.failed or exc
                raise
        return done


class _ClosedStdout(io.TextIOBase):
    """Standard output of a process started with it closed (``>&-``): every write fails.

    Python sets ``sys.stdout`` to None then, and click's echo dropped the text: exit 0 and
    nothing written anywhere (red-team L10).
    """

    def writable(self) -> bool:  # noqa: D102
        return True

    def write(self, s: str) -> int:  # noqa: D102
        exc = OSError(errno.EBADF, "closed")
        _WholeWrites.failed = _WholeWrites.failed or exc
        raise exc


def check_stdout_writes() -> None:
    """Standard output through :class:`_WholeWrites` (for the program, not a test's runner)."""
    old = sys.stdout
    if old is None:
        try:
            os.fstat(1)
        except OSError:  # closed: hold descriptor 1 so that no output file is opened on it
            fd = os.open(os.devnull, os.O_WRONLY)
            if fd != 1:
                os.dup2(fd, 1)
                os.close(fd)
        sys.stdout = _ClosedStdout()
        return
    if not hasattr(old, "buffer") or getattr(old, "fileno", None) is None:
        return
    try:
        if old.fileno() != 1:
            return
        old.flush()
    except (OSError, ValueError):
        return
    sys.stdout = io.TextIOWrapper(
        io.BufferedWriter(_WholeWrites()),
        encoding=old.encoding,
        errors=old.errors,
        line_buffering=old.line_buffering,
    )


def stdout_failure() -> OSError | None:
    """Flush standard output; the error if what was printed could not all be written."""
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except OSError as exc:
        if not isinstance(exc, BrokenPipeError):
            return exc
    except ValueError:  # closed
        pass
    return _WholeWrites.failed


#: Address space ``fit composite`` needs (measured: aborts natively under 2 GB, runs at 3).
COMPOSITE_ADDRESS_SPACE = 3 * 2**30
#: Address space one bus's ``fit zip`` needs (the red-team's hang was at 650-800 MB; under
#: 650 MB a fresh clone's first run, compiling its kernels, crashed natively in numba's
#: compiler instead of the MemoryError a check can word).
ZIP_ADDRESS_SPACE = 2**30


#: Set in ``ctx.meta`` by :func:`end_without_teardown`; read by ``cli.py`` at the exit.
NO_TEARDOWN = "loadbayes.end_without_teardown"


def end_without_teardown() -> None:
    """Ask ``loadbayes`` to end, after this command succeeds, without the teardown.

    For a command whose outputs are all written and closed when it returns: the
    interpreter's teardown of the modules a fit loaded costs 0.3-0.4 CPU s (``cli.py``).
    """
    click.get_current_context().meta[NO_TEARDOWN] = True


def check_address_space(need: int, what: str) -> None:
    """Refuse before any work when ``ulimit -v`` leaves less address space than ``need``."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY and soft < need:
        raise UserError(
            f"not enough memory: {what} needs about {_mib(need)} of address space and the "
            f"limit (ulimit -v) is {_mib(soft)}; raise it"
        )


def memory_line() -> str:
    """The one line for a MemoryError, naming the address-space limit if there is one."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return "not enough memory: the run needs more than this machine has free"
    return (
        f"not enough memory: the address-space limit (ulimit -v) is {_mib(soft)}; "
        "raise it (fit zip needs about 1 GiB, fit composite 3 GiB)"
    )


def stdout_line(exc: OSError) -> str:
    """The one line for a failed write to standard output."""
    if exc.errno == errno.EBADF:
        return "standard output is closed (>&-): what it would print is lost"
    return f"standard output: {exc.strerror or exc}; what was printed is incomplete"


def _os_error_line(exc: OSError) -> str:
    """``file: what went wrong``, naming the output, not its hidden temporary file."""
    what = exc.strerror or str(exc)
    out = _STOP.get("outputs")
    if exc.filename is None:
        # A failed write(2) names no file: standard output's, or the output being
        # written (a transaction creates each temporary just before writing it).
        if stdout_failure() is not None:
            return stdout_line(exc)
        temps = getattr(out, "_temps", {})
        if temps and not out.committed:
            label = list(temps)[-1]
            return f"{out.targets[label]}: {label} cannot be written: {what}"
        return what
    path = Path(os.fspath(exc.filename))
    for label, tmp in getattr(out, "_temps", {}).items():
        if path == tmp:
            return f"{out.targets[label]}: {label} cannot be written: {what}"
    if path.parent.name.startswith(".loadbayes-") and path.parent.name.endswith(".tmp"):
        # A file staged in a hidden folder for its folder's commit (--netcdf-dir).
        return f"{path.parent.parent / path.name}: cannot be written: {what}"
    return f"{path}: {what}"


def _caused_by_interrupt(exc: BaseException) -> bool:
    seen = 0
    cur: BaseException | None = exc
    while cur is not None and seen < 50:
        if isinstance(cur, KeyboardInterrupt):
            return True
        cur, seen = cur.__cause__ or cur.__context__, seen + 1
    return False


def _say_interrupted() -> None:
    # One line saying what a signal left (every output or none), and exit 130 or 143.
    sig = _STOP["signal"] or signal.SIGINT
    what = "terminated (SIGTERM)" if sig == signal.SIGTERM else "interrupted"
    if _STOP["committed"] or getattr(_STOP.get("outputs"), "committed", False):
        msg = f"{what} after every output was written"
    else:
        msg = f"{what}; no output was written"
    click.echo(f"loadbayes: {msg}", err=True)
    sys.exit(EXIT_SIGNAL.get(sig, 130))


def check_outputs(
    outputs: dict[str, str | None],
    inputs: list[str],
    force: bool,
    *,
    stdout_ok: tuple[str, ...] = (),
    plots: tuple[str, ...] = ("--plot",),
) -> None:
    """Refuse before any work: a path that cannot be written, or a format that cannot.

    An existing output without --force, an output that is an input or given twice, a
    directory, a missing folder, an unsupported figure format (options in ``plots``), or
    ``-`` (standard output) for an option not in ``stdout_ok``.
    """
    seen: dict[Path, str] = {}

    def resolve(path: str, what: str) -> Path:
        try:
            return Path(path).resolve()
        except (OSError, RuntimeError) as exc:  # a symlink loop, say
            raise UserError(f"{path}: {what} cannot be resolved ({exc})") from None

    ins = {resolve(p, "the input") for p in inputs if p and p != "-"}
    for opt, path in outputs.items():
        if path is None:
            continue
        if not path.strip():  # taken for "no output" it wrote nothing, with exit 0
            raise UserError(f"{opt} {path!r}: an empty file name (give one, or leave {opt} out)")
        if path == "-":
            if opt not in stdout_ok:
                raise UserError(f"{opt} -: standard output is only for --json")
            continue
        p = Path(path)
        if opt in plots:
            fmt = p.suffix.lstrip(".").lower()
            if fmt not in PLOT_FORMATS:
                raise UserError(
                    f"{path}: {opt} format '{fmt or '(no extension)'}' is not supported; "
                    f"use one of {', '.join(PLOT_FORMATS[:4])} (by extension)"
                )
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
        if not os.access(p.parent, os.W_OK):
            raise UserError(f"{path}: folder {p.parent} is not writable")


def _mib(n: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 2**10:.3g} KiB"


def _available_memory() -> int | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    return None


def check_cost(
    *,
    chains: int,
    draws: int,
    burn: int,
    thin: int,
    n_params: int,
    netcdf_out: str | None = None,
    quiet: bool = False,
) -> dict[str, int]:
    """Say what the draws will cost before sampling; refuse what cannot fit.

    Parameters
    ----------
    chains, draws, burn, thin : int
        The sampler settings (``draws`` includes the burn-in).
    n_params : int
        Parameters stored per draw (raw and reported, an upper bound).
    netcdf_out : str, optional
        Where the draws will be written (its folder's free space is checked).
    quiet : bool
        No notice on stderr.

    Returns
    -------
    dict
        ``kept``, ``memory`` and ``netcdf`` (bytes).

    Notes
    -----
    The kept draws take ``chains x kept x n_params x 8`` bytes; the summary (ArviZ's
    rank-normalised R-hat and ESS) and the conversion to InferenceData hold about three
    more copies, so the peak is estimated at 4 times that (measured: 1.7 GB for
    ``--draws 2000000`` of a ZIP fit with Q, 4 times its 481 MB NetCDF).
    """
    kept = max((draws - burn) // thin, 0)
    if kept < 4:
        raise UserError(
            f"--draws {draws} --burn {burn} --thin {thin} keep {kept} draw(s) per chain; "
            "R-hat and ESS need at least 4 (100 or more for a reliable summary)"
        )
    netcdf = chains * kept * n_params * 8
    memory = 4 * netcdf
    avail = _available_memory()
    if avail is not None and memory > MEMORY_SHARE * avail:
        raise UserError(
            f"{chains} chains x {kept} kept draws x {n_params} parameters need about "
            f"{_mib(memory)} of memory, more than the {_mib(avail)} available; lower "
            "--draws or raise --thin"
        )
    if netcdf_out and netcdf_out != "-":
        folder = Path(netcdf_out).parent
        try:
            free = shutil.disk_usage(folder).free
        except OSError:
            free = None
        if free is not None and netcdf > free:
            raise UserError(
                f"{netcdf_out}: the draws take about {_mib(netcdf)}, more than the "
                f"{_mib(free)} free in {folder}; lower --draws or raise --thin"
            )
    if not quiet and memory > NOTICE_BYTES:
        disk = f", NetCDF about {_mib(netcdf)}" if netcdf_out else ""
        click.echo(
            f"loadbayes: note: {chains} x {kept} kept draws x {n_params} parameters: about "
            f"{_mib(memory)} of memory{disk}",
            err=True,
        )
    return {"kept": kept, "memory": memory, "netcdf": netcdf}


class Progress:
    """A progress bar on a terminal's stderr; nothing otherwise (nor with --quiet).

    Only a person watching a terminal needs it: in a pipe or a log it would put lines
    before a one-line error. ``eta`` adds the time left (from the rate so far).
    """

    def __init__(self, label: str, total: int | None, quiet: bool, *, eta: bool = False) -> None:
        self.bar = None
        self.label = label
        self.count = 0
        self.quiet = quiet or not _isatty(sys.stderr)
        if not self.quiet and total:
            self.bar = click.progressbar(
                length=total, label=label, file=sys.stderr, show_pos=True, show_eta=eta
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
        elif not self.quiet and self.count:
            click.echo(f"{self.label}: {self.count} rows", err=True)
        self.quiet = True


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{max(seconds, 1):.0f} s"
    if seconds < 3600:
        return f"{seconds // 60:.0f} min {seconds % 60:02.0f} s"
    return f"{seconds // 3600:.0f} h {seconds % 3600 / 60:02.0f} min"


class SamplingBar:
    """The estimated cost of a sampling run, then a progress bar with the time left.

    ``begin(total, seconds)`` says on stderr what the run will take (unless quiet);
    calls with a number of iterations done move the bar, which is drawn only on a
    terminal (as :class:`Progress`). Safe to call from the chains' threads.
    """

    def __init__(self, quiet: bool, label: str = "sampling") -> None:
        import threading

        self.quiet = quiet
        self.label = label
        self.bar = None
        self.lock = threading.Lock()

    def begin(self, total: int, seconds: float) -> None:
        """Say the estimate; start the bar."""
        if self.quiet:
            return
        click.echo(
            f"loadbayes: {self.label} {total} iterations (all chains): about "
            f"{_duration(seconds)} on this machine (timed on a short run)",
            err=True,
        )
        if _isatty(sys.stderr):
            self.bar = click.progressbar(
                length=total, label=self.label, file=sys.stderr, show_eta=True, show_percent=True
            )
            self.bar.__enter__()

    def __call__(self, n: int) -> None:
        if self.bar is not None:
            with self.lock:
                self.bar.update(n)

    def extend(self, total: int, seconds: float, short: str) -> None:
        """The run goes on (not converged yet): say why and for how long; a new bar."""
        self.close()
        if self.quiet:
            return
        click.echo(
            f"loadbayes: not converged yet ({short}): {total} more iterations (all chains), "
            f"about {_duration(seconds)}",
            err=True,
        )
        if _isatty(sys.stderr):
            self.bar = click.progressbar(
                length=total, label=self.label, file=sys.stderr, show_eta=True, show_percent=True
            )
            self.bar.__enter__()

    def close(self) -> None:
        """End the bar (a line of its own)."""
        with self.lock:
            if self.bar is not None:
                self.bar.__exit__(None, None, None)
                self.bar = None


@contextlib.contextmanager
def output_transaction(files: dict[str, str | None], *, force: bool):
    """Write a command's outputs as one transaction (every one, or none).

    Yields a :class:`loadbayes.io.transaction.OutputSet` over the outputs given (``-``
    and None left out): write each to ``out.temp(option)``; leaving the block normally
    renames them all onto their targets, and :func:`user_errors` then says truly what a
    signal left (every output, or none). Call :func:`stop_if_signalled` between two
    writes whose libraries may swallow a KeyboardInterrupt (netCDF/HDF5).
    """
    from loadbayes.io.transaction import OutputSet

    targets = {k: v for k, v in files.items() if v and v != "-"}
    _import_writers(targets)
    stop_if_signalled()
    with OutputSet(targets, force=force) as out:
        _STOP["outputs"] = out
        yield out
        stop_if_signalled()
        out.commit()
        _STOP["committed"] = True


def _import_writers(options) -> None:
    """Import the C extensions the outputs' writers load, with the signals held.

    A signal that lands inside an extension module's initialisation (matplotlib's
    ``_image`` or ``ft2font`` on a figure's first draw, h5py under a NetCDF write) makes
    the import fail half done, and the interpreter then aborts (exit -6) instead of
    saying in one line what was written. Imported here, before any output exists and
    with SIGINT/SIGTERM held back (delivered right after), a signal can no longer land
    in one.
    """
    from loadbayes.io.atomic import held_signals

    drawn = any("plot" in o or "figure" in o for o in options)
    netcdf = any("netcdf" in o for o in options)
    if not (drawn or netcdf):
        return
    with held_signals():
        if drawn:
            from loadbayes.plots.fit import pyplot

            pyplot()
            import matplotlib.backends.backend_agg  # noqa: F401
            import PIL.Image  # noqa: F401  (matplotlib writes PNG through Pillow)
        if netcdf:
            import h5netcdf  # noqa: F401  (h5py's extension)
            import xarray  # noqa: F401  (the writer: io/idata.py, io/atomic.write_groups)


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


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


def write_outputs(
    post, *, model, hdi_prob, json_out, netcdf_out, plot_out, force, quiet, prior_sd=None
):
    """Write the JSON, NetCDF and figure as one transaction; print the table unless quiet.

    The warnings are completed first (:func:`loadbayes.diagnostics.fit_warnings`: R-hat,
    ESS, identifiability with what is determined, dominant priors). Every file goes to a
    temporary beside its target; they are renamed together only when all are written.
    ``json_out == "-"`` prints the JSON on standard output (the table then goes to
    stderr).
    """
    from loadbayes.diagnostics import fit_warnings
    from loadbayes.io.transaction import OutputSet
    from loadbayes.report.text import derived_lines, summary_table

    stop_if_signalled()  # a signal a library swallowed: not one more line of progress
    if not quiet:
        click.echo("loadbayes: summarising the draws (R-hat, ESS)...", err=True)
    table = post.summary(hdi_prob=hdi_prob)
    fit_warnings(post, table, hdi_prob=hdi_prob, prior_sd=prior_sd)
    targets = {"--json": json_out, "--netcdf": netcdf_out, "--plot": plot_out}
    files = {k: v for k, v in targets.items() if v and v != "-"}
    _import_writers(files)
    stop_if_signalled()
    with OutputSet(files, force=force) as out:
        _STOP["outputs"] = out
        # The JSON as Posterior.to_json writes it, but straight into the set's temporary.
        text = json.dumps(post.to_dict(hdi_prob=hdi_prob, summary=table), indent=2,
                          allow_nan=False)  # fmt: skip
        if json_out and json_out != "-":
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        stop_if_signalled()
        if netcdf_out:
            if not quiet:
                click.echo(f"loadbayes: writing {netcdf_out} (draws, predictions)...", err=True)
            post.to_netcdf(out.temp("--netcdf"), force=True, atomic=False)
            # netCDF/HDF5 may swallow the KeyboardInterrupt raised inside its C calls.
            stop_if_signalled()
        if plot_out:
            from loadbayes.plots.fit import plot_fit, pyplot

            fig = plot_fit(post, model=model, hdi_prob=hdi_prob)
            target = out.temp("--plot")
            fig.savefig(target, format=target.suffix.lstrip(".").lower(), dpi=110,
                        bbox_inches="tight")  # fmt: skip
            pyplot().close(fig)
            stop_if_signalled()
        out.commit()
        _STOP["committed"] = True
    if json_out == "-":
        click.echo(text)
    for w in post.warnings:
        click.echo(f"loadbayes: warning: {w}", err=True)
    if not quiet:
        # The 80-column table of loadbayes.report.text (stderr when the JSON is on stdout).
        click.echo(summary_table(post, hdi_prob=hdi_prob, summary=table, derived=False),
                   err=json_out == "-")  # fmt: skip
        # The derived quantities (dP/dV at v0 ...) after the table, on stderr: the table on
        # stdout keeps one row per sampled parameter, as scripts parse it.
        for line in derived_lines(post, hdi_prob=hdi_prob):
            click.echo(f"loadbayes: {line}", err=True)


def sidecar(path: str) -> Path | None:
    """The JSON settings file written beside a data file (``data.csv`` -> ``data.json``)."""
    if path == "-":
        return None
    p = Path(path)
    side = p.with_suffix(".json")
    return side if side != p else None
