"""Read and write measurement tables (CSV, Parquet), in chunks, with strict validation.

Files of any length are read in chunks of rows, so memory does not grow with the file.
Every column read comes out as float64. Rows are numbered from 1, the first row after
the header being row 1 (blank lines are skipped and not counted).

Bad input is refused with a one-line :class:`~loadbayes.io.errors.DataError` naming the
file, and the column and the row where there is one. Refused:

- a file that does not exist, is a directory, cannot be opened, or whose name ends in
  none of ``.csv``, ``.csv.gz``, ``.txt``, ``.txt.gz``, ``.parquet``, ``.pq`` (``"-"``
  reads CSV from standard input);
- an empty file, an empty first line, a header with no data rows after it;
- what is not text or not a table: a header or cell that is not UTF-8, NUL bytes in the
  header (a binary file), a corrupt or truncated gzip or Parquet file, a CSV row with
  more or fewer fields than the header;
- a missing required column (the error lists the columns found, and suggests the one
  meant when only case or spaces differ: ``'V'`` or ``' v'`` for ``'v'``);
- a column read that is named twice in the header (pandas would silently rename the
  second to ``v.1``); columns not read may repeat;
- a cell that is not a number (the first one, with its value shortened to 20
  characters); a Parquet column of a non-numeric type (bool, timestamp, nested...).
  Integer and decimal Parquet columns are cast; text Parquet columns are parsed as CSV
  cells are;
- in any column read, a missing value (empty cell, ``NA``, ``null``, ``NaN`` ...), an
  infinite one (``inf``, or a number beyond the float64 range such as ``1e999``), and in
  a column that must be positive a value <= 0. These are errors, or with
  ``drop_invalid=True`` their rows are dropped and counted; if no row is left, that is
  an error.

The error names the first offending row of the file, whatever the chunk size.

A cell is a number if, once spaces and tabs around it are removed, it reads as
``[+-]digits[.digits][e[+-]digits]``, ``inf``, ``infinity`` or ``nan`` (any case).
Thousands separators, decimal commas, hexadecimal and non-ASCII digits are not numbers.

The work is split by job: :mod:`loadbayes.io.sources` (file types, opening),
:mod:`loadbayes.io.csv_reader`, :mod:`loadbayes.io.parquet_reader`, and
:mod:`loadbayes.io.cells` (cells to float64, the checks and the messages). This module
holds the public functions and cuts the readers' pieces into chunks.

Its length is one idea: the reading contract above, documented once, with the public
read and write functions that keep it.
"""

from __future__ import annotations

import csv
import io
import operator
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from loadbayes.io.atomic import atomic_write
from loadbayes.io.cells import _Piece
from loadbayes.io.csv_reader import _csv_pieces
from loadbayes.io.errors import DataError, NoDataRows
from loadbayes.io.parquet_reader import _parquet_pieces
from loadbayes.io.sources import (
    _SUPPORTED,
    CSV_SUFFIXES,
    PARQUET_SUFFIXES,
    _display_name,
    _format_by_name,
    _format_of,
)

__all__ = [
    "CSV_SUFFIXES",
    "PARQUET_SUFFIXES",
    "Chunk",
    "iter_chunks",
    "read_columns",
    "write_table",
]


@dataclass(frozen=True, eq=False)
class Chunk:
    """A block of consecutive data rows, validated.

    Parameters
    ----------
    data : dict of str to numpy.ndarray
        The requested columns present in the file, required first, as contiguous
        float64 arrays holding the rows kept (all finite; > 0 where asked).
    start_row : int
        1-based data row number of the first row read into this chunk.
    n_rows_read : int
        Rows read into this chunk, kept or dropped.
    dropped_rows : numpy.ndarray
        1-based row numbers of the rows dropped (int64, increasing; empty unless
        ``drop_invalid``).
    """

    data: dict[str, np.ndarray]
    start_row: int
    n_rows_read: int
    dropped_rows: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))

    @property
    def n_dropped(self) -> int:
        """Number of rows dropped."""
        return len(self.dropped_rows)

    @property
    def n_rows(self) -> int:
        """Number of rows kept: the length of the arrays in :attr:`data`."""
        return self.n_rows_read - self.n_dropped

    @property
    def rows(self) -> np.ndarray:
        """1-based row numbers of the rows kept (computed on access)."""
        read = np.arange(self.start_row, self.start_row + self.n_rows_read, dtype=np.int64)
        return np.delete(read, self.dropped_rows - self.start_row)

    def row_of(self, i: int) -> int:
        """Return the 1-based row number of the ``i``-th kept row, without :attr:`rows`.

        Parameters
        ----------
        i : int
            0-based index into the arrays of :attr:`data`.

        Returns
        -------
        int
            The data row number, for error messages.
        """
        if not 0 <= i < self.n_rows:
            raise IndexError(f"row index {i} out of range for a chunk of {self.n_rows} rows")
        # Kept rows before the k-th dropped row: its offset minus k. Non-decreasing.
        kept_before = self.dropped_rows - self.start_row - np.arange(self.n_dropped)
        return self.start_row + i + int(np.searchsorted(kept_before, i, side="right"))


def iter_chunks(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    *,
    optional: Iterable[str] = (),
    positive: Iterable[str] = (),
    chunk_rows: int = 1_000_000,
    drop_invalid: bool = False,
) -> Iterator[Chunk]:
    """Read the named columns of a CSV or Parquet file, a chunk of rows at a time.

    Parameters
    ----------
    path : str or os.PathLike
        ``.csv``, ``.txt`` (optionally ``.gz``), ``.parquet`` or ``.pq``; ``"-"`` reads
        CSV from standard input. CSV is comma separated, or tab or semicolon separated
        when the header holds no comma.
    columns : sequence of str
        Required columns.
    optional : iterable of str, default ()
        Columns read when present, and then checked like the required ones.
    positive : iterable of str, default ()
        Columns (among the above) whose values must be > 0.
    chunk_rows : int, default 1_000_000
        Rows read per chunk (the last may have fewer). The data do not depend on it.
    drop_invalid : bool, default False
        Drop rows with a missing or infinite value, or a value <= 0 where positive is
        required, instead of raising. Non-numeric cells are always an error.

    Yields
    ------
    Chunk
        Consecutive chunks; chunks whose rows were all dropped are yielded too.

    Raises
    ------
    DataError
        While iterating, for any of the bad inputs listed in this module's docstring.
    ValueError
        If the arguments themselves are wrong (a positive column not asked for...).

    Notes
    -----
    Rows are parsed and checked in blocks of about 1 MiB of CSV text (65,536 Parquet
    rows), ahead of the chunks: an error can come before all the chunks preceding its
    row have been yielded.

    Examples
    --------
    >>> for chunk in iter_chunks("bus18.csv", ["v", "p", "q"], positive=["v"]):  # doctest: +SKIP
    ...     stats.update(chunk.data["v"], chunk.data["p"])
    """
    if operator.index(chunk_rows) < 1:
        raise ValueError(f"chunk_rows must be >= 1, not {chunk_rows}")
    yield from _rechunk(_read_pieces(path, columns, optional, positive, drop_invalid), chunk_rows)


def read_columns(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    *,
    optional: Iterable[str] = (),
    positive: Iterable[str] = (),
    drop_invalid: bool = False,
) -> tuple[dict[str, np.ndarray], int]:
    """Read the named columns of a whole CSV or Parquet file.

    Parameters
    ----------
    path, columns, optional, positive, drop_invalid
        As in :func:`iter_chunks`.

    Returns
    -------
    data : dict of str to numpy.ndarray
        The columns present, as float64 arrays of the rows kept.
    n_dropped : int
        Rows dropped (0 unless ``drop_invalid``).

    Raises
    ------
    DataError
        For any of the bad inputs listed in this module's docstring.

    Notes
    -----
    Holds the whole columns in memory, twice for a moment while the batches read are
    joined; use :func:`iter_chunks` for files larger than that.
    """
    # Joins the validated batches once, not chunks of them: one copy of the data.
    parts: dict[str, list[np.ndarray]] = {}
    n_dropped = 0
    for piece in _read_pieces(path, columns, optional, positive, drop_invalid):
        for col, values in piece.data.items():
            parts.setdefault(col, []).append(values)
        n_dropped += len(piece.dropped)
    return {col: np.concatenate(arrays) for col, arrays in parts.items()}, n_dropped


def write_table(
    data: Any,
    path: str | os.PathLike[str],
    *,
    force: bool = False,
) -> Path:
    """Write a table to CSV or Parquet (by the extension of ``path``), atomically.

    Parameters
    ----------
    data : pandas.DataFrame, pyarrow.Table or mapping of str to array-like
        The columns; a DataFrame's index is not written.
    path : str or os.PathLike
        Output file: ``.csv``, ``.txt`` (optionally ``.gz``), ``.parquet`` or ``.pq``.
    force : bool, default False
        Replace an existing file.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    DataError
        If ``path`` exists and ``force`` is False, has an unsupported extension, or its
        folder is missing.

    Notes
    -----
    Floats are written in their shortest round-trip form, so reading the file back
    gives the same float64 values. Missing values are written as empty CSV cells.
    """
    name = os.fspath(path)
    kind = _format_by_name(name)
    if kind is None:
        raise DataError(f"unsupported file type; {_SUPPORTED}", name)
    table = _to_arrow(data)
    with atomic_write(path, force=force) as tmp:
        if kind == "parquet":
            pq.write_table(table, tmp)
        else:
            _write_csv(table, tmp, compress=name.lower().endswith(".gz"))
    return Path(path)


def _read_pieces(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    optional: Iterable[str],
    positive: Iterable[str],
    drop_invalid: bool,
) -> Iterator[_Piece]:
    required, extra, must_be_positive = _check_arguments(columns, optional, positive)
    name = _display_name(path)
    if _format_of(path, name) == "csv":
        pieces = _csv_pieces(path, name, required, extra, must_be_positive, drop_invalid)
    else:
        pieces = _parquet_pieces(path, name, required, extra, must_be_positive, drop_invalid)
    return _count_rows(pieces, name)


def _check_arguments(
    columns: Sequence[str], optional: Iterable[str], positive: Iterable[str]
) -> tuple[list[str], list[str], frozenset[str]]:
    if isinstance(columns, str) or isinstance(optional, str) or isinstance(positive, str):
        raise TypeError("columns, optional and positive take lists of names, not a string")
    required, extra = list(columns), list(optional)
    if not required:
        raise ValueError("columns must name at least one column")
    names = required + extra
    if not all(isinstance(n, str) for n in names):
        raise TypeError("column names must be strings")
    if len(set(names)) != len(names):
        raise ValueError(f"a column is named twice in columns/optional: {names}")
    must_be_positive = frozenset(positive)
    if not must_be_positive <= set(names):
        raise ValueError(f"positive columns {sorted(must_be_positive - set(names))} not read")
    return required, extra, must_be_positive


# --- cutting into chunks --------------------------------------------------------------


def _count_rows(pieces: Iterator[_Piece], name: str) -> Iterator[_Piece]:
    n_read = n_kept = 0
    for piece in pieces:
        n_read += piece.n_read
        n_kept += piece.n_read - len(piece.dropped)
        yield piece
    if n_read == 0:
        raise NoDataRows("no data rows", name)
    if n_kept == 0:
        raise DataError(f"no valid rows: all {n_read} data rows were dropped", name)


def _rechunk(pieces: Iterator[_Piece], chunk_rows: int) -> Iterator[Chunk]:
    pending: list[_Piece] = []
    filled = 0
    for piece in pieces:
        rest: _Piece | None = piece
        while rest is not None:
            room = chunk_rows - filled
            if rest.n_read <= room:
                head, rest = rest, None
            else:
                head, rest = _split(rest, room)
            pending.append(head)
            filled += head.n_read
            if filled == chunk_rows:
                yield _join(pending)
                pending, filled = [], 0
    if pending:
        yield _join(pending)


def _split(piece: _Piece, n: int) -> tuple[_Piece, _Piece]:
    """Cut after the first ``n`` rows read."""
    cut = piece.start_row + n
    n_dropped = int(np.searchsorted(piece.dropped, cut))
    kept = n - n_dropped
    head = {col: v[:kept] for col, v in piece.data.items()}
    tail = {col: v[kept:] for col, v in piece.data.items()}
    return (
        _Piece(piece.start_row, n, head, piece.dropped[:n_dropped]),
        _Piece(cut, piece.n_read - n, tail, piece.dropped[n_dropped:]),
    )


def _join(pieces: list[_Piece]) -> Chunk:
    # np.concatenate copies even a single piece: contiguous, writeable, and not a view
    # keeping an Arrow batch alive.
    data = {col: np.concatenate([p.data[col] for p in pieces]) for col in pieces[0].data}
    return Chunk(
        data=data,
        start_row=pieces[0].start_row,
        n_rows_read=sum(p.n_read for p in pieces),
        dropped_rows=np.concatenate([p.dropped for p in pieces]),
    )


# --- writing --------------------------------------------------------------------------


def _to_arrow(data: Any) -> pa.Table:
    if isinstance(data, pa.Table):
        return data
    if isinstance(data, Mapping):
        return pa.table({str(col): np.asarray(v) for col, v in data.items()})
    if hasattr(data, "columns") and hasattr(data, "index"):  # a pandas DataFrame
        return pa.Table.from_pandas(data, preserve_index=False)
    raise TypeError(f"expected a DataFrame, a pyarrow Table or a dict, not {type(data)!r}")


def _write_csv(table: pa.Table, tmp: Path, *, compress: bool) -> None:
    # The header is written here: Arrow would quote every name, which other tools show.
    header = io.StringIO()
    csv.writer(header, lineterminator="\n").writerow(table.column_names)
    options = pacsv.WriteOptions(include_header=False, quoting_style="needed")
    sink = pa.CompressedOutputStream(str(tmp), "gzip") if compress else pa.OSFile(str(tmp), "wb")
    with sink:
        sink.write(header.getvalue().encode("utf-8"))
        pacsv.write_csv(table, sink, write_options=options)
