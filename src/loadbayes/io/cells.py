"""Cells to float64, and the checks and messages of every read.

The column selection (a missing or doubled column, with a hint at the one meant), the
conversion of a batch of cells to float64 (fast in Arrow, cell by cell only to find the
first bad one), the finite and positive checks, ``drop_invalid``, and the one-line
messages that name the row and column. Used by the CSV and the Parquet readers alike.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from loadbayes.io.errors import DataError

_SHOW_CHARS = 20
#: The remedy an invalid cell's message names; a reader that never drops rows (events,
#: read whole) puts its own in its place.
DROP_HINT = " (--drop-invalid, or drop_invalid=True, drops such rows)"

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
# A number written with a decimal comma ('1,0234', '-0,5'): said, not guessed (in a
# comma-separated file '1,5' could as well be two fields).
_COMMA_NUMBER = re.compile(r"[+-]?[0-9]*,[0-9]+(?:[eE][+-]?[0-9]+)?", re.ASCII)
_FLOAT64 = pa.float64()


class _Piece(NamedTuple):
    """Validated rows of one Arrow batch, before cutting into chunks."""

    start_row: int
    n_read: int
    data: dict[str, np.ndarray]
    dropped: np.ndarray


def select_columns(
    header: list[str], required: list[str], extra: list[str], name: str
) -> dict[str, int]:
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
            found = f"not found; {columns_named(col, header)}"
            raise DataError(found, name, col)
    return present


def columns_named(col: str, header: Sequence[str]) -> str:
    """'the columns are 'a', 'b' (did you mean 'b'?)': added to a missing column's message."""
    return f"the columns are {_list(header)}{_hint(col, header)}"


def _list(header: Sequence[str], limit: int = 12) -> str:
    shown = ", ".join(repr(h) for h in header[:limit])
    return shown + (f" and {len(header) - limit} more" if len(header) > limit else "")


def _hint(col: str, header: Sequence[str]) -> str:
    def norm(s: str) -> str:
        return s.strip(_SPACE + "\ufeff\"'").casefold()

    same = [h for h in header if norm(h) == norm(col)]
    close = same or difflib.get_close_matches(col, list(header), n=1, cutoff=0.75)
    return f" (did you mean {close[0]!r}?)" if close else ""


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


def validate_batch(
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
            hint = ""
            if _COMMA_NUMBER.fullmatch(cell.strip(_SPACE)):
                hint = " (a decimal comma: save the file with '.' as the decimal mark)"
            return vals, (i, f"non-numeric value {_show(cell)}{hint}")
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
    hint = DROP_HINT
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
