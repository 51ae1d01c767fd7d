"""Write a file all at once or not at all.

Every writer in loadbayes (tables, JSON, NetCDF, figures) writes to a temporary file in
the target's folder and renames it over the target only when the writing has finished,
so an error, a full disk or Ctrl-C never leaves a half-written file, and an existing
file is either kept whole or replaced whole.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from loadbayes.io.errors import DataError

__all__ = ["atomic_write", "check_target", "held_signals", "write_groups"]

_WRITE_MODES = ("w", "wt", "wb")


def check_target(path: str | os.PathLike[str], *, force: bool = False) -> Path:
    """Check that a file can be written at ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    force : bool, default False
        Allow replacing an existing file.

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.

    Raises
    ------
    DataError
        If ``path`` exists and ``force`` is False, is a directory, or its folder does
        not exist.
    """
    target = Path(path)
    name = os.fspath(path)
    if target.is_dir():
        raise DataError("is a directory, expected a file name", name)
    if not target.parent.is_dir():
        raise DataError(f"folder '{target.parent}' does not exist", name)
    if target.exists() and not force:
        raise DataError("exists; use --force to overwrite", name)
    return target


@contextlib.contextmanager
def atomic_write(
    path: str | os.PathLike[str],
    *,
    force: bool = False,
    mode: str | None = None,
    encoding: str = "utf-8",
) -> Iterator[Any]:
    """Write ``path`` through a temporary file that replaces it at the end.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    force : bool, default False
        Replace ``path`` if it exists; otherwise an existing ``path`` is an error.
    mode : {None, "w", "wt", "wb"}, default None
        None yields the temporary file's path (for writers that take a file name; it
        ends with the same suffix as ``path`` so they pick the same format); otherwise
        the temporary file opened in this mode.
    encoding : str, default "utf-8"
        Encoding in text mode.

    Yields
    ------
    pathlib.Path or file object
        Where to write.

    Raises
    ------
    DataError
        If ``path`` exists and ``force`` is False, or the folder is missing or cannot
        be written.

    Notes
    -----
    The temporary file is hidden (``.name.XXXX.tmp.ext``) in the folder of ``path``, so
    the final ``os.replace`` is atomic. It is flushed to disk before the rename. If the
    block raises (KeyboardInterrupt included) the temporary file is removed and any old
    ``path`` is untouched.

    Examples
    --------
    >>> with atomic_write("summary.json", mode="w", force=True) as fh:  # doctest: +SKIP
    ...     json.dump(summary, fh)
    """
    if mode is not None and mode not in _WRITE_MODES:
        raise ValueError(f"mode must be None or one of {_WRITE_MODES}, not {mode!r}")
    target = check_target(path, force=force)
    name = os.fspath(path)
    tmp: Path | None = None
    try:
        # Created and remembered with SIGINT/SIGTERM held back: a signal between the two
        # would leave a temporary no clean-up knows of. It is raised right after, here.
        with held_signals():
            try:
                fd, tmp_name = tempfile.mkstemp(
                    dir=target.parent, prefix=f".{target.name}.", suffix=f".tmp{target.suffix}"
                )
            except OSError as err:
                message = f"cannot create a file in '{target.parent}': {err.strerror}"
                raise DataError(message, name) from None
            os.close(fd)
            tmp = Path(tmp_name)
        if mode is None:
            yield tmp
        else:
            with open(tmp, mode, encoding=None if "b" in mode else encoding) as fh:
                yield fh
        _fsync(tmp)
        # Checked again: the target may have appeared while we were writing.
        if target.exists() and not force:
            raise DataError("exists; use --force to overwrite", name)
        os.chmod(tmp, _file_mode(target))
        os.replace(tmp, target)
    except BaseException as exc:
        if tmp is not None:
            with held_signals(), contextlib.suppress(OSError):
                tmp.unlink()
            if isinstance(exc, OSError) and exc.filename is not None and Path(exc.filename) == tmp:
                # Said of the file the caller asked for, not of its hidden temporary.
                raise OSError(exc.errno, exc.strerror, name) from None
        raise
    _fsync_dir(target.parent)


_HELD = (signal.SIGINT, signal.SIGTERM)
# The hold in force: how deep, the handlers it replaced, the first signal it kept back.
_HOLD: dict[str, Any] = {"depth": 0, "previous": {}, "pending": None}


@contextlib.contextmanager
def held_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back for the block; the first is delivered when it ends.

    For the few steps that must not be split (a temporary created and registered, the
    renames of a commit, a clean-up): a signal during them takes effect right after,
    through the handler that was there before.

    Notes
    -----
    A signal mask (``pthread_sigmask``) holds only in the thread that sets it: the kernel
    gives a process-directed signal to any thread that does not block it (a BLAS, Arrow
    or numba pool's), and Python then runs the handler in the main thread at its next
    instruction, inside the block (the red-team's H1: a fleet's commit stopped after 37
    of 800 renames). Python handlers run only in the main thread, so there the block
    replaces them with one that records the signal, in every thread alike; the
    signal is raised again when the outermost block ends. Another thread cannot change
    handlers: it blocks the signals for itself (the main thread's handler, which runs
    them, is then not held back by this block).
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        old = signal.pthread_sigmask(signal.SIG_BLOCK, set(_HELD))
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        return
    if _HOLD["depth"] == 0:
        _HOLD["pending"] = None
        _HOLD["previous"] = {s: signal.signal(s, _keep_back) for s in _HELD}
    _HOLD["depth"] += 1
    try:
        yield
    finally:
        _HOLD["depth"] -= 1
        if _HOLD["depth"] == 0:
            for s, handler in _HOLD["previous"].items():
                signal.signal(s, handler if handler is not None else signal.SIG_DFL)
            pending, _HOLD["pending"] = _HOLD["pending"], None
            if pending is not None:
                # Runs the handler put back, here and now (raise_signal checks for it).
                signal.raise_signal(pending)


def _keep_back(signum, frame) -> None:
    # The first signal in a hold is delivered at its end; a second is one too many.
    if _HOLD["pending"] is None:
        _HOLD["pending"] = signum


def write_groups(attrs: dict, groups: dict, path: str | os.PathLike[str]) -> None:
    """Write a fit's NetCDF: the file's attributes and its groups (``xarray.Dataset``).

    The file is built in memory, then written by a plain Python write: a full disk or a
    file-size limit is then an ``OSError`` naming ``path``. HDF5 writing to the file
    itself met them inside its C calls, printed about a hundred lines of tracebacks
    from h5py's finalisers and crashed the process (segmentation fault, exit 139) when
    the half-closed file's objects were freed (the red-team's H2). The groups (as
    ``Posterior._groups`` builds them without ArviZ, ``io/idata.py``), their order and the
    attributes are written as ``InferenceData.to_netcdf`` (ArviZ 0.23) writes them.

    SIGINT and SIGTERM are held back while the file is built (in memory, milliseconds):
    an interrupt inside h5netcdf's ``File`` constructor left an object whose finaliser
    printed an ``AttributeError`` traceback ("Exception ignored in File.close") under
    the CLI's one-line message (a fleet's --netcdf-dir interrupted on a loaded machine).
    """
    import io

    import xarray as xr

    buf = io.BytesIO()
    mode = "w"
    with held_signals(), _local_write_lock():
        if attrs:
            xr.Dataset(attrs=attrs).to_netcdf(buf, mode=mode, engine="h5netcdf", group="/")
            mode = "a"
        for group, data in groups.items():
            data.to_netcdf(buf, mode=mode, group=f"//{group}", engine="h5netcdf")
            mode = "a"
    name = os.fspath(path)
    try:
        with open(name, "wb") as fh:
            fh.write(buf.getbuffer())
    except OSError as err:  # a failed write(2) names no file: name it
        raise OSError(err.errno, err.strerror, name) from None


def _local_write_lock() -> contextlib.AbstractContextManager:
    # xarray picks its write lock from the dask scheduler in force: on a Dask worker (a
    # fleet's --workers) a distributed lock named by the target, which for an in-memory
    # buffer is unknown to the scheduler ("Semaphore or Lock <_io.BytesIO> not known").
    # The buffer is this thread's alone, so a local (threaded) lock is the right one.
    try:
        import dask
    except ImportError:  # the cluster extra is not installed: no scheduler to override
        return contextlib.nullcontext()
    if "distributed" in sys.modules:
        return dask.config.set(scheduler="threads")
    return _threads_without_distributed(dask)


@contextlib.contextmanager
def _threads_without_distributed(dask: Any) -> Iterator[None]:
    # Where distributed was never imported no Client exists, but xarray's scheduler
    # check imports it to ask (``from dask.distributed import Client``; dask's own check
    # does too for a scheduler given by name): about 0.4-1 CPU s in every process that
    # writes a NetCDF. The threads scheduler given as its function, and that one import
    # answered "not installed" for the write, give xarray's answer without it: "threaded",
    # the same lock and the same bytes (sha256 checked).
    import dask.threaded

    with dask.config.set(scheduler=dask.threaded.get):
        sys.modules["dask.distributed"] = None  # type: ignore[assignment]
        try:
            yield
        finally:
            if sys.modules.get("dask.distributed", 0) is None:
                del sys.modules["dask.distributed"]


def _fsync(path: Path) -> None:
    # Without it a crash soon after the rename can leave an empty file on some
    # filesystems (ext4 delayed allocation): the old data lost, the new not yet there.
    with open(path, "rb") as fh:
        os.fsync(fh.fileno())


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _file_mode(target: Path) -> int:
    # mkstemp creates the file 0600; give it the permissions a plain open() would have
    # given it, or those of the file it replaces.
    with contextlib.suppress(OSError):
        return target.stat().st_mode & 0o7777
    return 0o666 & ~_umask()


def _umask() -> int:
    # Read it without os.umask(), which sets it and races with other threads.
    with contextlib.suppress(OSError, ValueError), open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    return 0o022
