"""In-memory tables checked exactly as files are: the Python API's one reader.

A DataFrame or a mapping of arrays goes through the same column selection and cell
checks as a CSV file (:mod:`loadbayes.io.cells`), so ``fit_zip(df)`` and
``loadbayes fit zip file.csv`` refuse the same data with the same one-line
:class:`~loadbayes.io.errors.DataError` (column and 1-based row), and columns not asked
for (a timestamp, a label) are ignored.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Table", "is_path", "read_frame", "time_span"]

#: The name errors give an in-memory table.
NAME = "data"


@dataclass
class Table:
    """Validated columns of an in-memory table, with the 1-based rows kept."""

    data: dict[str, np.ndarray]
    rows: np.ndarray
    n_dropped: int = 0
    time: dict[str, Any] = field(default_factory=dict)


def is_path(data: Any) -> bool:
    """True for a file name (str or path-like), which the API reads like the CLI."""
    return isinstance(data, (str, os.PathLike))


def read_frame(
    data: Any,
    required: Sequence[str],
    *,
    optional: Sequence[str] = (),
    positive: Sequence[str] = (),
    drop_invalid: bool = False,
    t_col: str | None = None,
) -> Table:
    """Select and check columns of a DataFrame or a mapping of arrays.

    Parameters
    ----------
    data : DataFrame or mapping
        The table; other columns are ignored.
    required, optional : sequence of str
        Columns that must be there / are read when present.
    positive : sequence of str
        Columns whose values must be > 0 (voltages).
    drop_invalid : bool
        Drop rows with NaN, inf or a non-positive voltage instead of refusing the data.
    t_col : str, optional
        A timestamp column (or the DataFrame's DatetimeIndex when absent): its first and
        last values are recorded, it is not fitted.

    Returns
    -------
    Table

    Raises
    ------
    DataError
        A missing column (with the columns there and a close name), a non-numeric,
        missing, infinite or non-positive value (column and row), or no rows.
    """
    import pyarrow as pa

    from loadbayes.io.cells import select_columns, validate_batch
    from loadbayes.io.errors import DataError

    if hasattr(data, "columns") and hasattr(data, "iloc"):
        header = [str(c) for c in data.columns]
        get = {str(c): data[c] for c in data.columns}
    elif hasattr(data, "keys"):
        header = [str(k) for k in data.keys()]
        get = {str(k): data[k] for k in data.keys()}
    else:
        raise DataError(
            f"expected a file name, a pandas DataFrame or a mapping of columns; got "
            f"{type(data).__name__}",
            NAME,
        )
    present = select_columns(header, list(required), [c for c in optional if c], NAME)
    arrays = {}
    for col in present:
        values = get[col]
        try:
            arr = pa.array(np.asarray(values) if not hasattr(values, "dtype") else values)
        except (pa.ArrowException, TypeError, ValueError):
            arr = pa.array([str(x) for x in np.asarray(values, dtype=object)])
        if pa.types.is_timestamp(arr.type) or pa.types.is_date(arr.type):
            raise DataError("holds timestamps, expected numbers", NAME, col)
        arrays[col] = arr
    sizes = {len(a) for a in arrays.values()}
    if len(sizes) > 1:
        raise DataError(f"columns differ in length ({', '.join(map(str, sorted(sizes)))})", NAME)
    if not sizes or sizes == {0}:
        raise DataError("no data rows", NAME)
    piece = validate_batch(arrays, 1, frozenset(positive), drop_invalid, NAME)
    rows = np.delete(np.arange(1, piece.n_read + 1), piece.dropped - 1)
    if rows.size == 0:
        raise DataError(f"no valid rows: all {piece.n_read} data rows were dropped", NAME)
    return Table(piece.data, rows, int(piece.dropped.size), time_span(data, t_col, rows))


def time_span(data: Any, t_col: str | None, rows: np.ndarray) -> dict[str, Any]:
    """First and last timestamp of the kept rows, as ISO text (empty without a time)."""
    import pandas as pd

    values = None
    name = t_col
    if t_col is not None and hasattr(data, "keys") and t_col in data.keys():
        values = data[t_col]
    elif isinstance(getattr(data, "index", None), pd.DatetimeIndex):
        values, name = data.index, str(data.index.name or "index")
    if values is None or rows.size == 0:
        return {}
    vals = np.asarray(values)
    first, last = vals[rows[0] - 1], vals[rows[-1] - 1]
    return {
        "time_column": name,
        "time_start": str(pd.Timestamp(first)) if _is_time(first) else str(first),
        "time_end": str(pd.Timestamp(last)) if _is_time(last) else str(last),
    }


def _is_time(x: Any) -> bool:
    return isinstance(x, np.datetime64) or hasattr(x, "isoformat")
