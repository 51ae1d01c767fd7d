"""Numba's on-disk cache kept true to the package's compiled sources.

Numba keys a cached function by the time stamp of its own file only. A cached caller thus
keeps the old machine code of a function it calls from another file after that file
changes: seen here when a merge changed the motor's steady state and a cached caller in
another module went on integrating the old one, with no error. At import the package hashes
every one of its sources that uses numba; when the hash differs from the one its caches were
built from, it deletes those caches (numba recompiles on first call) and records the new
hash. The check reads about 30 files (a few ms). It covers the caches numba writes beside
the sources and, with ``NUMBA_CACHE_DIR`` set, their mirror there. Caches that cannot be
written or deleted are left alone: a tree numba cannot write to is an installed one, whose
files an upgrade rewrites, time stamps and all.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
STAMP_NAME = "numba-sources.sha256"
_IMPORTS_NUMBA = re.compile(rb"^\s*(?:import|from) numba\b", re.MULTILINE)


def sources_hash(root: Path = PACKAGE) -> str:
    """SHA-256 of every source under ``root`` that imports numba, with its relative path.

    An import, not the word: ``cli.py`` and others only name numba in their docstrings,
    and an edit of theirs threw away every compiled kernel (55-60 s to compile again).
    """
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if _IMPORTS_NUMBA.search(text):
            h.update(path.relative_to(root).as_posix().encode() + b"\0" + text + b"\0")
    return h.hexdigest()


def cache_dirs(root: Path = PACKAGE) -> list[Path]:
    """Where numba keeps this package's caches.

    Each source folder's ``__pycache__`` and, with ``NUMBA_CACHE_DIR`` set, the folder numba
    names after it there (``<folder name>_<sha1 of its absolute path>``, as numba's cache
    locator does).
    """
    folders = sorted({p.parent for p in root.rglob("*.py")})
    dirs = [f / "__pycache__" for f in folders]
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        for f in folders:
            sub = os.path.abspath(f)
            name = f"{os.path.basename(sub)}_{hashlib.sha1(sub.encode()).hexdigest()}"
            dirs.append(Path(user).absolute() / name)
    return dirs


def purge_stale(root: Path = PACKAGE) -> bool:
    """Delete this package's numba caches if its compiled sources changed; True if it did.

    Safe beside other processes: a cache file deleted under one that reads it is a cache miss
    to numba, which then compiles.
    """
    digest = sources_hash(root)
    stamp = root / "__pycache__" / STAMP_NAME
    try:
        if stamp.read_text().strip() == digest:
            return False
    except OSError:
        pass
    purged = False
    for folder in cache_dirs(root):
        if not folder.is_dir():
            continue
        for pattern in ("*.nbi", "*.nbc"):
            for path in folder.glob(pattern):
                try:
                    path.unlink()
                    purged = True
                except OSError:
                    pass
    try:
        stamp.parent.mkdir(exist_ok=True)
        tmp = stamp.with_name(f"{STAMP_NAME}.{os.getpid()}.tmp")
        tmp.write_text(digest + "\n")
        os.replace(tmp, stamp)
    except OSError:
        pass  # a tree numba cannot write to: see the module's docstring
    return purged
