"""The ``loadbayes`` command line.

Only click is imported at start-up; everything heavy (numba, ArviZ, matplotlib,
pandapower) is imported inside the command that needs it, so ``loadbayes --help`` is fast.
The commands live in :mod:`loadbayes.commands`, one module per subject, and are attached
to the groups at the bottom of this module by name: a command's module is imported when
that command is asked for (run, or listed by ``--help``), so ``loadbayes fit composite``
does not import the other twenty (:class:`LazyCommands`).

Exit codes: 0 success, 2 bad usage or bad data (one line on stderr naming the file, the
column and the row, never a traceback), 130 interrupted (no output left half-written).

The process ends cleanly: after a command that failed or was stopped, what it left
half-used (a reader abandoned mid-file, its frames kept alive by the error) is released
while the interpreter is still whole, not during its shutdown (see :class:`LoadbayesGroup`).
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import os
import signal
import sys

import click


def _cap_native_threads() -> None:
    """Under an address-space limit (``ulimit -v``), one thread in each native pool.

    Each OpenBLAS thread maps its own buffers when the library loads, and Arrow's
    jemalloc reserves its arenas; under a limit they fail and retry ``mmap`` for ever
    (the red-team's H8: ``fit zip`` under 800 MB hung at 96% CPU). So, before NumPy
    and Arrow are imported (the commands import them as they run), a limit sets the pools to
    one thread and Arrow to the system allocator, unless the user chose.
    """
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return
    for name, value in _UNDER_A_LIMIT.items():
        os.environ.setdefault(name, value)


#: Arrow's default allocator (jemalloc) reserves address space up front and hung the
#: same way: the system allocator fails with a MemoryError, said in one line instead.
_UNDER_A_LIMIT = {
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "ARROW_DEFAULT_MEMORY_POOL": "system",
}
_cap_native_threads()


class LoadbayesGroup(click.Group):
    """The top group; its :meth:`main` releases native resources before the process exits.

    An error raised mid-read leaves the reader's generator suspended, held by the
    error's traceback until the interpreter tears down. A native thread (Arrow's
    read-ahead) that then drops its last reference to a Python object cannot take the
    GIL any more, and the process aborts: "terminate called without an active
    exception", exit 134 instead of 2 (measured: 17 of 30 runs on a loaded machine).
    So, when run as the program (arguments from ``sys.argv``), the exit code is taken,
    the exception and its frames are dropped, and after a failure or a signal the
    garbage is collected before ``sys.exit``; output and exit codes are unchanged. (A
    command run in-process, by a test's CliRunner, returns as click's would.)
    """

    def invoke(self, ctx):  # noqa: D102
        try:
            return super().invoke(ctx)
        finally:
            from loadbayes.commands.output import NO_TEARDOWN

            _LATE["finished"] = True
            _LATE["no_teardown"] = bool(ctx.meta.get(NO_TEARDOWN))

    def main(self, args=None, *rest, **kwargs):  # noqa: D102
        if args is not None:
            return super().main(args, *rest, **kwargs)
        _LATE.update(signal=None, finished=False, no_teardown=False)
        _check_stdout_writes()
        with contextlib.suppress(ValueError):  # not the main thread: leave them be
            for s in _EXIT_CODE:
                signal.signal(s, _on_late_signal)
        unsaid = None  # a failed write to standard output not yet said
        try:
            return super().main(args, *rest, **kwargs)
        except SystemExit as exc:
            code = exc.code
        except MemoryError:  # a command without user_errors (theirs say it the same way)
            from loadbayes.commands.output import memory_line

            click.echo(f"loadbayes: error: {memory_line()}", err=True)
            code = EXIT_DATA
        except OSError:  # click re-raises every OSError but EPIPE: a command's raw print
            unsaid = _stdout_broken()
            if unsaid is None:
                raise
            code = EXIT_DATA
        broken = unsaid or _stdout_broken()
        if broken is not None:
            # What was printed is cut short (a full disk, a file-size limit): one line,
            # exit 2 (a command's own error has said it already), and no second attempt
            # to flush at the interpreter's exit.
            if unsaid is not None or code in (0, None):
                click.echo(f"loadbayes: error: {_stdout_line(broken)}", err=True)
                code = EXIT_DATA
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            os._exit(code if isinstance(code, int) else 1)
        # Outside the except block: the exception, its traceback and the frames it held
        # are unreferenced now, and what only they kept alive can be collected.
        if code not in (0, None):
            release_native()
        # From here the process only ends: SIGINT and SIGTERM are ignored. Otherwise one
        # landing after the interpreter's finalisation has put back the default
        # handlers (it keeps SIG_IGN) would kill it, exit -2 or -15 and no word, with
        # every output written. (Blocking them would not do: the mask is per thread,
        # and a native pool's thread would take the signal.)
        with contextlib.suppress(ValueError):
            for s in _EXIT_CODE:
                signal.signal(s, signal.SIG_IGN)
        late = _LATE["signal"]
        if late is not None and code in (0, None):
            what = "terminated (SIGTERM)" if late == signal.SIGTERM else "interrupted"
            click.echo(f"loadbayes: {what} after every output was written", err=True)
            code = _EXIT_CODE[late]
        if code in (130, 143):
            _forget_unhandled_interrupt()
            # A run a signal ended has said so and left every output or none: end the
            # process here, without the interpreter's finalisation, where a native
            # library's thread (a compiled pool, HDF5) still running at the signal can
            # abort it (seen once in 40 signalled runs: "PyThreadState_Get ... the GIL
            # is released", exit -6 after the one line).
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            os._exit(code)
        if code in (0, None) and _LATE["no_teardown"]:
            _end_without_teardown()
        sys.exit(code)


EXIT_DATA = 2


def _end_without_teardown() -> None:
    """Exit 0 without the interpreter's teardown of its modules, after a command asked.

    The teardown frees every module and object one by one: 0.3-0.4 CPU s once a
    composite fit has loaded numba, SciPy and pandas, for nothing a finished command
    needs. The atexit handlers run and the standard streams are flushed, as at a normal
    exit; a stream that cannot be flushed leaves the exit to the interpreter.
    """
    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        return
    os._exit(0)


def _stdout_broken() -> OSError | None:
    from loadbayes.commands.output import stdout_failure

    return stdout_failure()


def _check_stdout_writes() -> None:
    from loadbayes.commands.output import check_stdout_writes

    check_stdout_writes()


def _stdout_line(exc: OSError) -> str:
    from loadbayes.commands.output import stdout_line

    return stdout_line(exc)


def _forget_unhandled_interrupt() -> None:
    """Keep the exit code of a run stopped by a signal (130) from becoming -2.

    A KeyboardInterrupt that once left code run by ``PyRun_*`` (HDF5's NetCDF writer
    goes through it; the exception is then caught and said in one line) leaves CPython
    flagged to kill itself with SIGINT after its finalisation. Running an empty string
    through the same function clears the flag. Measured: 7 of 12 runs stopped during
    the NetCDF write exited -2 after "interrupted; no output was written".
    """
    import ctypes

    with contextlib.suppress(Exception):
        ctypes.pythonapi.PyRun_SimpleString(b"")


_EXIT_CODE = {signal.SIGINT: 130, signal.SIGTERM: 143}
_LATE: dict = {"signal": None, "finished": False, "no_teardown": False}


def _on_late_signal(signum, frame) -> None:
    """SIGINT/SIGTERM outside a command's own handling (its handlers are restored to this).

    Before the command has run it acts as Python's default would (KeyboardInterrupt, or
    the end of the process for SIGTERM). Once the command has finished, every output is
    written or none: the signal is recorded and said in one line with exit 130 or 143,
    instead of killing the process in its teardown (exit -2 and no word).
    """
    if _LATE["finished"]:
        if _LATE["signal"] is None:
            _LATE["signal"] = signum
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def release_native() -> None:
    """Finish what a failed or stopped command left open, while the interpreter is whole.

    Closes suspended generators (a reader abandoned mid-file closes its Arrow reader and
    its file in its ``finally``) and frees what reference cycles kept alive. A command
    that succeeded has read every file to its end, so the exit after it skips this (a
    full collection costs 0.1-0.3 s with the fit's modules loaded).
    """
    gc.collect()


class LazyCommands(dict):
    """A group's commands by name, each imported from its module when first asked for.

    A value is a click command, or a callable that returns one (:func:`_command`); it is
    replaced by the command the first time it is read. Keys alone (``--help``'s list,
    a mistyped name's suggestions) import nothing. Importing every command module took
    0.18 CPU s before ``fit composite`` started (0.07 for its own), a subclass of dict so
    that click's ``group.commands`` and the tests that walk it work as before.
    """

    def __getitem__(self, name: str) -> click.Command:
        value = super().__getitem__(name)
        if not isinstance(value, click.Command):
            value = value()
            super().__setitem__(name, value)
        return value

    def get(self, name: str, default=None):  # noqa: D102
        return self[name] if name in self else default

    def values(self):  # noqa: D102
        return [self[name] for name in self]

    def items(self):  # noqa: D102
        return [(name, self[name]) for name in self]


def _command(module: str, attr: str):
    """A loader of ``loadbayes.commands.<module>.<attr>`` for :class:`LazyCommands`."""

    def load() -> click.Command:
        import importlib

        return getattr(importlib.import_module(f"loadbayes.commands.{module}"), attr)

    return load


def _archive_group() -> click.Command:
    from loadbayes.commands import archive, archive_pool

    if "pool" not in archive.archive_group.commands:
        archive.archive_group.add_command(archive_pool.pool_cmd)
    return archive.archive_group


@click.group(cls=LoadbayesGroup, context_settings={"help_option_names": ["-h", "--help"]})
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


# The commands know nothing of this module: they are attached here, by name, so the
# imports run one way (cli -> commands) with no circle, and only the command run loads.
fit.commands = LazyCommands(
    zip=_command("zip", "fit_zip_cmd"),
    exp=_command("exp", "fit_exp_cmd"),
    im=_command("im", "fit_im_cmd"),
    composite=_command("composite", "fit_composite_cmd"),
)
simulate.commands = LazyCommands(
    im=_command("simulate", "simulate_im_cmd"),
    andes=_command("andes_sim", "simulate_andes_cmd"),
)
track.commands = LazyCommands(zip=_command("track", "track_zip_cmd"))
reproduce.commands = LazyCommands(
    zip=_command("reproduce", "reproduce_zip_cmd"),
    im=_command("reproduce", "reproduce_im_cmd"),
    all=_command("reproduce", "reproduce_all_cmd"),
)
main.commands = LazyCommands(
    main.commands,
    read=_command("recordings", "read_group"),
    events=_command("recordings", "events_cmd"),
    export=_command("export", "export_cmd"),
    report=_command("report", "report_cmd"),
    example=_command("example", "example_cmd"),
    validate=_command("validate", "validate_cmd"),
    playback=_command("playback", "playback_cmd"),
    predict=_command("predict", "predict_cmd"),
    steps=_command("steps", "steps_cmd"),
    cvr=_command("cvr", "cvr_cmd"),
    archive=_archive_group,
)

if __name__ == "__main__":  # python -m loadbayes.cli ... did nothing and exited 0
    main(prog_name="loadbayes")
