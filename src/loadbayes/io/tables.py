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
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import gzip
import io
import math
import operator
import os
import re
import sys
import zlib
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from loadbayes.io.atomic import atomic_write
from loadbayes.io.errors import DataError

__all__ = [
    "CSV_SUFFIXES",
    "PARQUET_SUFFIXES",
    "Chunk",
    "iter_chunks",
    "read_columns",
    "write_table",
]

CSV_SUFFIXES = (".csv", ".csv.gz", ".txt", ".txt.gz")
PARQUET_SUFFIXES = (".parquet", ".pq")
STDIN = "-"

# CSV bytes per Arrow batch and Parquet rows per batch: what is validated at a time,
# independent of ``chunk_rows`` so the same first bad row is found for any chunk size.
_CSV_BLOCK_BYTES = 1 << 20
_PARQUET_BATCH_ROWS = 1 << 16
_HEADER_MAX_BYTES = 1 << 20
_SHOW_CHARS = 20

# Cells that mean "no value": pandas' default NA strings.
_NULL_TOKENS = (
    "", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND",
    "1.#QNAN", "<NA>", "N/A", "NA", "NULL", "NaN", "None", "n/a", "nan", "null",
)  # fmt: skip
_NULL_SET = frozenset(_NULL_TOKENS)
_NULL_ARRAY = pa.array(_NULL_TOKENS, pa.string())
# Exactly what Arrow's string-to-float64 cast accepts (checked against it cell by cell
# in the tests), so the slow path below never refuses a cell the fast path took.
_NUMBER = re.compile(
    r"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
    r"|inf(?:inity)?|nan(?:\([0-9A-Za-z_]*\))?)",
    re.IGNORECASE | re.ASCII,
)
_SPACE = " \t\n\v\f\r"
_FLOAT64 = pa.float64()


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


class _Piece(NamedTuple):
    """Validated rows of one Arrow batch, before cutting into chunks."""

    start_row: int
    n_read: int
    data: dict[str, np.ndarray]
    dropped: np.ndarray


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


# --- arguments and file types ---------------------------------------------------------

_SUPPORTED = "expected " + ", ".join(CSV_SUFFIXES + PARQUET_SUFFIXES) + ", or '-' for stdin"


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


# --- CSV ------------------------------------------------------------------------------


def _open_binary(path: str | os.PathLike[str], name: str) -> contextlib.AbstractContextManager:
    if os.fspath(path) == STDIN:
        return contextlib.nullcontext(sys.stdin.buffer)
    try:
        if name.lower().endswith(".gz"):
            return gzip.open(path, "rb")
        return open(path, "rb")
    except OSError as err:
        raise DataError(f"cannot open: {err.strerror or err}", name) from None


def _read_header(fh: Any, name: str) -> tuple[list[str], str]:
    """Read and split the first line; leave ``fh`` at the first data row."""
    try:
        line = fh.readline(_HEADER_MAX_BYTES + 1)
    except (OSError, EOFError, zlib.error) as err:
        raise DataError(f"cannot read: {_one_line(err)}", name) from None
    if not line:
        raise DataError("empty file", name)
    if len(line) > _HEADER_MAX_BYTES:
        raise DataError("first line longer than 1 MiB: not a CSV file?", name)
    if b"\0" in line:
        raise DataError("header contains NUL bytes: a binary file, not CSV text?", name)
    try:
        text = line.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise DataError(
            f"header is not UTF-8 text (byte {line[err.start]:#04x}): "
            "a binary file, or saved in another encoding?",
            name,
        ) from None
    text = text.rstrip("\r\n")
    if not text.strip():
        raise DataError("first line is empty; expected a header with the column names", name)
    if "\r" in text:
        raise DataError("lines end in a bare CR; save the file with LF or CRLF endings", name)
    sep = next((c for c in ",\t;" if c in text), ",")
    try:
        header = next(csv.reader([text], delimiter=sep))
    except csv.Error as err:
        raise DataError(f"cannot parse the header: {err}", name) from None
    return header, sep


def _csv_pieces(
    path: str | os.PathLike[str],
    name: str,
    required: list[str],
    extra: list[str],
    positive: frozenset[str],
    drop_invalid: bool,
) -> Iterator[_Piece]:
    with _open_binary(path, name) as fh:
        header, sep = _read_header(fh, name)
        present = _select(header, required, extra, name)
        arrow_names = [f"f{i}" for i in range(len(header))]
        start = 1
        try:
            # Cells come as raw bytes: decoding and parsing them here is what lets an
            # error name its row (Arrow's own conversion errors do not, when streaming).
            reader = pacsv.open_csv(
                fh,
                read_options=pacsv.ReadOptions(
                    column_names=arrow_names, block_size=_CSV_BLOCK_BYTES, use_threads=False
                ),
                parse_options=pacsv.ParseOptions(delimiter=sep),
                convert_options=pacsv.ConvertOptions(
                    include_columns=[arrow_names[i] for i in present.values()],
                    column_types={arrow_names[i]: pa.binary() for i in present.values()},
                    null_values=[],
                    strings_can_be_null=False,
                    quoted_strings_can_be_null=False,
                ),
            )
            while True:
                try:
                    batch = reader.read_next_batch()
                except StopIteration:
                    break
                if batch.num_rows:
                    columns = {c: batch.column(arrow_names[i]) for c, i in present.items()}
                    yield _validate(columns, start, positive, drop_invalid, name)
                    start += batch.num_rows
        except (pa.ArrowException, OSError, EOFError, zlib.error) as err:
            if isinstance(err, pa.ArrowInvalid) and "Empty CSV file" in str(err):
                return
            raise _csv_read_error(err, start, name) from None


# Arrow's message for a row with too many or too few fields. Not an invalid_row_handler:
# Arrow decodes the row for it, and a row that is not UTF-8 then raises inside Arrow.
# Single-threaded reading is what puts the row number (counted from the first data row,
# blank lines skipped) in the message.
_RAGGED = re.compile(r"Row #(\d+): Expected (\d+) columns, got (\d+): (.*)", re.DOTALL)


def _csv_read_error(err: BaseException, start: int, name: str) -> DataError:
    ragged = _RAGGED.search(str(err)) if isinstance(err, pa.ArrowInvalid) else None
    if ragged:
        row, expected, found, text = ragged.groups()
        fields = "field" if found == "1" else "fields"
        message = f"{found} {fields} where the header has {expected}: {_show(text)}"
        return DataError(message, name, row=int(row))
    if isinstance(err, EOFError | zlib.error | gzip.BadGzipFile):
        return DataError(f"corrupt or truncated gzip file, read up to row {start - 1}", name)
    return DataError(f"cannot read as CSV past row {start - 1}: {_one_line(err)}", name)


def _select(header: list[str], required: list[str], extra: list[str], name: str) -> dict[str, int]:
    """Map each requested column present to its position in the header."""
    present = {}
    for col in required + extra:
        where = [i for i, h in enumerate(header) if h == col]
        if len(where) > 1:
            at = ", ".join(str(i + 1) for i in where)
            raise DataError(f"named {len(where)} times in the header (columns {at})", name, col)
        if where:
            present[col] = where[0]
        elif col in required:
            found = f"not found; the columns are {_list(header)}{_hint(col, header)}"
            raise DataError(found, name, col)
    return present


def _list(header: Sequence[str], limit: int = 12) -> str:
    shown = ", ".join(repr(h) for h in header[:limit])
    return shown + (f" and {len(header) - limit} more" if len(header) > limit else "")


def _hint(col: str, header: Sequence[str]) -> str:
    def norm(s: str) -> str:
        return s.strip(_SPACE + "\ufeff\"'").casefold()

    same = [h for h in header if norm(h) == norm(col)]
    close = same or difflib.get_close_matches(col, list(header), n=1, cutoff=0.75)
    return f" (did you mean {close[0]!r}?)" if close else ""


# --- Parquet --------------------------------------------------------------------------


def _parquet_pieces(
    path: str | os.PathLike[str],
    name: str,
    required: list[str],
    extra: list[str],
    positive: frozenset[str],
    drop_invalid: bool,
) -> Iterator[_Piece]:
    try:
        with open(path, "rb") as probe:
            if not probe.read(1):
                raise DataError("empty file", name)
        # pre_buffer (Arrow's default) would read all the columns asked for into memory
        # before the first batch; without it memory stays at about one row group.
        parquet = pq.ParquetFile(path, pre_buffer=False)
    except OSError as err:
        raise DataError(f"cannot open: {err.strerror or _one_line(err)}", name) from None
    except pa.ArrowException as err:
        raise DataError(f"not a readable Parquet file: {_one_line(err)}", name) from None
    with parquet:
        schema = parquet.schema_arrow
        present = _select(schema.names, required, extra, name)
        for col, i in present.items():
            _check_arrow_type(schema.field(i).type, name, col)
        start = 1
        batches = parquet.iter_batches(batch_size=_PARQUET_BATCH_ROWS, columns=list(present))
        while True:
            try:
                batch = next(batches)
            except StopIteration:
                break
            except (pa.ArrowException, OSError) as err:
                raise DataError(
                    f"corrupt Parquet file, read up to row {start - 1}: {_one_line(err)}", name
                ) from None
            if batch.num_rows:
                columns = {col: batch.column(col) for col in present}
                yield _validate(columns, start, positive, drop_invalid, name)
                start += batch.num_rows


def _check_arrow_type(kind: pa.DataType, name: str, col: str) -> None:
    value = kind.value_type if pa.types.is_dictionary(kind) else kind
    if not (_is_numeric(value) or _is_text(value)):
        raise DataError(f"has type {kind}, expected numbers", name, col)


def _is_numeric(kind: pa.DataType) -> bool:
    t = pa.types
    return t.is_integer(kind) or t.is_floating(kind) or t.is_decimal(kind) or t.is_null(kind)


def _is_text(kind: pa.DataType) -> bool:
    t = pa.types
    return (
        t.is_string(kind)
        or t.is_large_string(kind)
        or t.is_string_view(kind)
        or t.is_binary(kind)
        or t.is_large_binary(kind)
        or t.is_binary_view(kind)
        or t.is_fixed_size_binary(kind)
    )


# --- cells to float64, and validation ----------------------------------------------------


def _validate(
    columns: Mapping[str, pa.Array],
    start: int,
    positive: frozenset[str],
    drop_invalid: bool,
    name: str,
) -> _Piece:
    """Convert one batch and check it; raise at its first bad cell (row, then column)."""
    n = len(next(iter(columns.values())))
    values: dict[str, np.ndarray] = {}
    invalid = np.zeros(n, dtype=bool) if drop_invalid else None
    first: tuple[int, int, str, str] | None = None
    for j, (col, arr) in enumerate(columns.items()):
        vals, bad = _to_float(arr, name, col)
        limit = n
        if bad is not None:
            limit = bad[0]
            first = _earlier(first, (bad[0], j, col, bad[1]))
        mask = ~np.isfinite(vals[:limit])
        if col in positive:
            mask |= vals[:limit] <= 0
        if invalid is not None:
            invalid[:limit] |= mask
        elif mask.any():
            i = int(np.argmax(mask))
            first = _earlier(first, (i, j, col, _describe(arr, vals[i], i)))
        values[col] = vals
    if first is not None:
        raise DataError(first[3], name, first[2], start + first[0])
    if invalid is None or not invalid.any():
        return _Piece(start, n, values, np.empty(0, np.int64))
    keep = ~invalid
    dropped = start + np.flatnonzero(invalid).astype(np.int64)
    return _Piece(start, n, {col: v[keep] for col, v in values.items()}, dropped)


def _earlier(
    a: tuple[int, int, str, str] | None, b: tuple[int, int, str, str]
) -> tuple[int, int, str, str]:
    return b if a is None or b[:2] < a[:2] else a


def _to_float(arr: pa.Array, name: str, col: str) -> tuple[np.ndarray, tuple[int, str] | None]:
    """Return float64 values and, if a cell is not a number, (its index, the problem)."""
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    if not _is_text(arr.type):
        try:
            return pc.cast(arr, _FLOAT64, safe=False).to_numpy(zero_copy_only=False), None
        except pa.ArrowException as err:
            raise DataError(
                f"type {arr.type} cannot be read as float64: {_one_line(err)}", name, col
            ) from None
    try:
        text = arr if arr.type == pa.string() else pc.cast(arr, pa.string())  # checks UTF-8
        try:
            floats = pc.cast(text, _FLOAT64)
        except pa.ArrowInvalid:
            # Spaces around numbers, NA tokens: still vectorised.
            text = pc.ascii_trim_whitespace(text)
            null = pa.scalar(None, pa.string())
            text = pc.if_else(pc.is_in(text, value_set=_NULL_ARRAY), null, text)
            floats = pc.cast(text, _FLOAT64)
        return floats.to_numpy(zero_copy_only=False), None
    except pa.ArrowException:
        return _to_float_slowly(arr)


def _to_float_slowly(arr: pa.Array) -> tuple[np.ndarray, tuple[int, str] | None]:
    """Cell by cell, to find the first bad one; only for batches that have one."""
    vals = np.full(len(arr), np.nan)
    for i, cell in enumerate(arr.to_pylist()):
        if cell is None:
            continue
        if isinstance(cell, bytes):
            try:
                cell = cell.decode("utf-8")
            except UnicodeDecodeError:
                return vals, (i, f"not UTF-8 text: {_show(cell)} (saved in another encoding?)")
        x = _parse_cell(cell)
        if x is None:
            return vals, (i, f"non-numeric value {_show(cell)}")
        vals[i] = x
    return vals, None


def _parse_cell(cell: str) -> float | None:
    text = cell.strip(_SPACE)
    if text in _NULL_SET:
        return math.nan
    if _NUMBER.fullmatch(text) is None:
        return None
    if text.lstrip("+-")[:3].lower() == "nan":  # 'nan(123)': float() refuses it, Arrow not
        return math.nan
    return float(text)  # '1e999' -> inf, as in Arrow


def _describe(arr: pa.Array, x: float, i: int) -> str:
    """Say what is wrong with the finite-and-positive check of cell ``i``."""
    cell = arr[i].as_py()
    if isinstance(cell, bytes):
        cell = cell.decode("utf-8", errors="replace")
    hint = " (--drop-invalid, or drop_invalid=True, drops such rows)"
    if cell is None:
        return "missing value (null)" + hint
    # Text cells are shown as written, numbers as Arrow holds them ('-2' for an int).
    shown = _show(cell) if isinstance(cell, str) else str(cell)
    if math.isnan(x):
        blank = isinstance(cell, str) and not cell.strip(_SPACE)
        return ("empty cell" if blank else f"missing value {shown}") + hint
    if math.isinf(x):
        return f"infinite value {shown} (inf, or beyond the float64 range)" + hint
    return f"value {shown} is not > 0" + hint


def _show(cell: str | bytes) -> str:
    return repr(cell[:_SHOW_CHARS]) + ("..." if len(cell) > _SHOW_CHARS else "")


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__


# --- cutting into chunks --------------------------------------------------------------


def _count_rows(pieces: Iterator[_Piece], name: str) -> Iterator[_Piece]:
    n_read = n_kept = 0
    for piece in pieces:
        n_read += piece.n_read
        n_kept += piece.n_read - len(piece.dropped)
        yield piece
    if n_read == 0:
        raise DataError("no data rows", name)
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
