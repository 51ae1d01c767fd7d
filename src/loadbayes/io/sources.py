"""Where a table comes from: file types by suffix, their checks, and opening the file.

Every file :mod:`loadbayes.io.tables` reads is opened here (the tests refuse ``open``
in this module to check the message of an unreadable file).
"""

from __future__ import annotations

import contextlib
import gzip
import os
import sys
from pathlib import Path
from typing import Any

from loadbayes.io.errors import DataError

CSV_SUFFIXES = (".csv", ".csv.gz", ".txt", ".txt.gz")
PARQUET_SUFFIXES = (".parquet", ".pq")
STDIN = "-"

_SUPPORTED = "expected " + ", ".join(CSV_SUFFIXES + PARQUET_SUFFIXES) + ", or '-' for stdin"


def _display_name(path: str | os.PathLike[str]) -> str:
    name = os.fspath(path)
    return "<stdin>" if name == STDIN else str(name)


def _format_by_name(name: str) -> str | None:
    lower = name.lower()
    if lower.endswith(CSV_SUFFIXES):
        return "csv"
    if lower.endswith(PARQUET_SUFFIXES):
        return "parquet"
    return None


def _format_of(path: str | os.PathLike[str], name: str) -> str:
    if os.fspath(path) == STDIN:
        return "csv"
    target = Path(path)
    if not target.exists():
        raise DataError("file not found", name)
    if target.is_dir():
        raise DataError("is a directory, expected a file", name)
    kind = _format_by_name(target.name)
    if kind is None:
        raise DataError(f"unsupported file type; {_SUPPORTED}", name)
    return kind


def _open_binary(path: str | os.PathLike[str], name: str) -> contextlib.AbstractContextManager:
    if os.fspath(path) == STDIN:
        return contextlib.nullcontext(sys.stdin.buffer)
    try:
        if name.lower().endswith(".gz"):
            return gzip.open(path, "rb")
        return open(path, "rb")
    except OSError as err:
        raise DataError(f"cannot open: {err.strerror or err}", name) from None


def _open_file(path: str | os.PathLike[str]) -> Any:
    """Open a file for binary reading (the Parquet reader's probe for an empty file)."""
    return open(path, "rb")
