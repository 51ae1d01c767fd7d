"""Several output files written as one: all of them, or none.

:func:`loadbayes.io.atomic.atomic_write` makes each file whole or absent. A run writes
several (the JSON summary, the NetCDF draws, the figure); an error or a signal between
two of them used to leave a JSON without its NetCDF. :class:`OutputSet` writes each to
a hidden temporary file beside its target and renames them all at the end, with SIGINT
and SIGTERM held back during the renames, so that a run leaves every output or none, and
no temporary file in either case.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from loadbayes.io.atomic import _file_mode, _fsync, _fsync_dir, check_target, held_signals
from loadbayes.io.errors import DataError

__all__ = ["OutputSet"]


class OutputSet:
    """Temporary files for a set of outputs, renamed onto their targets together.

    Parameters
    ----------
    targets : mapping of str to path
        A label for each output (the option that named it, e.g. ``"--json"``) and its
        path.
    force : bool
        Replace existing targets.

    Examples
    --------
    >>> with OutputSet({"--json": "a.json", "--plot": "a.png"}) as out:  # doctest: +SKIP
    ...     write_json(out.temp("--json"))
    ...     save_png(out.temp("--plot"))
    ...     out.commit()

    Notes
    -----
    Leaving the ``with`` block without :meth:`commit` (an exception, KeyboardInterrupt)
    removes every temporary file and leaves the targets as they were. During
    :meth:`commit` SIGINT and SIGTERM are held back in every thread
    (:func:`loadbayes.io.atomic.held_signals`), so a signal cannot split the renames; it
    is delivered right after them.
    """

    def __init__(self, targets: dict[str, str | os.PathLike[str]], *, force: bool = False):
        self.targets = {k: Path(v) for k, v in targets.items()}
        self.force = force
        self._temps: dict[str, Path] = {}
        self.committed = False
        for label, path in self.targets.items():
            try:
                check_target(path, force=force)
            except DataError as exc:
                raise DataError(f"{label}: {exc.message}", path=str(path)) from None

    def temp(self, label: str) -> Path:
        """The temporary file for ``label`` (created empty; same folder and suffix)."""
        if label in self._temps:
            return self._temps[label]
        target = self.targets[label]
        # Created and registered with the signals held back, so that abort() knows of
        # every temporary there is.
        with held_signals():
            try:
                fd, name = tempfile.mkstemp(
                    dir=target.parent, prefix=f".{target.name}.", suffix=f".tmp{target.suffix}"
                )
            except OSError as err:
                raise DataError(
                    f"cannot create a file in '{target.parent}': {err.strerror}",
                    path=str(target),
                ) from None
            os.close(fd)
            self._temps[label] = Path(name)
        return self._temps[label]

    def commit(self) -> list[Path]:
        """Rename every written temporary onto its target; return the targets written."""
        missing = [k for k in self.targets if k not in self._temps]
        if missing:
            raise RuntimeError(f"outputs never written: {', '.join(missing)}")
        for label, tmp in self._temps.items():
            _fsync(tmp)
            target = self.targets[label]
            # Checked again: a target may have appeared while we were working.
            if target.exists() and not self.force:
                raise DataError("exists; use --force to overwrite", path=str(target))
        with held_signals():
            for label, tmp in self._temps.items():
                target = self.targets[label]
                os.chmod(tmp, _file_mode(target))
                os.replace(tmp, target)
            self.committed = True
            for folder in {t.parent for t in self.targets.values()}:
                _fsync_dir(folder)
        return list(self.targets.values())

    def abort(self) -> None:
        """Remove every temporary file (the targets are untouched)."""
        if self.committed:
            return
        # Held back here too: a signal must not stop the clean-up half way.
        with held_signals():
            for tmp in self._temps.values():
                with contextlib.suppress(OSError):
                    tmp.unlink()

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, *exc) -> None:
        self.abort()
