"""A time column in seconds: numbers of seconds or ISO timestamps, checked increasing.

``fit zip --t-col``, ``track zip --t-col`` and fleets read the time column through here:
the column is read as text (so that ``2026-03-01T00:01:00`` and ``60`` both parse), every
cell is parsed by pandas, and the first cell that is neither a number nor an ISO
timestamp is refused in one line naming the file, the column and the row. Times are
returned as float seconds (timestamps: seconds since the first one).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.io.errors import DataError

__all__ = ["check_increasing", "parse_times", "read_text_column", "read_times", "time_facts"]


def parse_times(values: Any, *, path: str, column: str, rows: np.ndarray | None = None):
    """Seconds from numbers or ISO timestamps (one kind per column); DataError on a bad cell.

    ``rows`` are the 1-based data rows of ``values`` (for the message); default 1..n.
    """
    import pandas as pd

    s = pd.Series(values)
    where = np.arange(1, len(s) + 1) if rows is None else np.asarray(rows)
    if pd.api.types.is_datetime64_any_dtype(s):
        ns = s.astype("int64").to_numpy()
        bad = s.isna().to_numpy()
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError("missing timestamp", path=path, column=column, row=int(where[i]))
        return (ns - ns[0]) / 1e9 if ns.size else ns.astype(float)
    if pd.api.types.is_numeric_dtype(s):
        t = s.to_numpy(dtype=float)
        _refuse_bad(~np.isfinite(t), s, where, path, column)
        return t
    text = s.astype(str).str.strip()
    num = pd.to_numeric(text, errors="coerce")
    if num.notna().all():
        t = num.to_numpy(dtype=float)
        _refuse_bad(~np.isfinite(t), s, where, path, column)
        return t
    if num.notna().any() and num.notna().sum() > len(s) // 2:
        # a column of numbers with a stray text cell: name the cell
        _refuse_bad(num.isna().to_numpy(), s, where, path, column)
    # ISO 8601 allows a comma before the fraction of a second (10:00:00,5).
    text = text.str.replace(r"(\d{2}:\d{2}:\d{2}),(\d)", r"\1.\2", regex=True)
    aware = text.str.contains(r"(?:Z|[+-]\d\d:?\d\d)$", regex=True)
    ts = pd.to_datetime(text, errors="coerce", utc=bool(aware.any()), format="ISO8601")
    _refuse_bad(ts.isna().to_numpy(), s, where, path, column)
    ns = ts.astype("int64").to_numpy()
    return (ns - ns[0]) / 1e9


def _refuse_bad(bad: np.ndarray, s, where, path, column) -> None:
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(
            f"{str(s.iloc[i])!r} is neither a number of seconds nor an ISO timestamp",
            path=path,
            column=column,
            row=int(where[i]),
        )


def read_text_column(path: str, column: str):
    """One column of a CSV or Parquet file as text (pandas Series), every row.

    CSV headers in GB18030 (a Chinese spreadsheet's) are read as the table reader reads
    them (:mod:`loadbayes.io.encoding`).
    """
    import pandas as pd

    if path == "-":
        raise DataError("this column needs a file, not standard input", path="-", column=column)
    from loadbayes.io.encoding import SNIFF_BYTES, detect_encoding
    from loadbayes.io.sources import PARQUET_SUFFIXES

    name = str(path)
    if name.lower().endswith(tuple(PARQUET_SUFFIXES)):
        import pyarrow.parquet as pq

        schema = pq.read_schema(name)
        if column not in schema.names:
            raise DataError(f"no column {column!r} (columns: {', '.join(schema.names)})", path=name)
        return pq.read_table(name, columns=[column]).column(0).to_pandas()
    with open(name, "rb") as fh:
        sample = fh.read(SNIFF_BYTES)
    found = detect_encoding(sample, complete=len(sample) < SNIFF_BYTES)
    encoding = "gb18030" if found == "gb18030" else "utf-8-sig"
    head = sample.split(b"\n", 1)[0].decode(encoding, errors="replace").rstrip("\r\n")
    sep = next((c for c in ",\t;" if c in head), ",")
    header = [h.strip().strip('"') for h in head.split(sep)]
    if column not in header:
        raise DataError(f"no column {column!r} (columns: {', '.join(header)})", path=name)
    return pd.read_csv(
        name,
        sep=sep,
        usecols=[column],
        dtype=str,
        keep_default_na=False,
        engine="c",
        encoding=encoding,
        encoding_errors="replace",
    )[column]


def read_times(path: str, t_col: str, rows: np.ndarray | None = None) -> np.ndarray:
    """The time column of a CSV or Parquet file in seconds, at the 1-based data ``rows``.

    The whole column is parsed (a bad cell is refused even in a row dropped later), then
    cut to ``rows`` (the rows the V, P, Q reader kept).
    """
    if path == "-":
        raise DataError("a time column needs a file, not standard input", path="-", column=t_col)
    name = str(path)
    t = parse_times(read_text_column(name, t_col), path=name, column=t_col)
    return t if rows is None else t[np.asarray(rows) - 1]


def check_increasing(t: np.ndarray, rows: np.ndarray, *, path: str, column: str) -> None:
    """Refuse a time that does not increase (row named); ``rows`` are the data rows of ``t``."""
    if t.size < 2:
        return
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0])
        raise DataError(
            f"time does not increase ({t[i + 1]:g} s after {t[i]:g} s at row {int(rows[i])}); "
            "sort the rows by time, or fit each bus apart (--by)",
            path=path,
            column=column,
            row=int(rows[i + 1]),
        )


def time_facts(t: np.ndarray) -> dict[str, Any]:
    """What a fit records about its time column: span, typical step, gaps."""
    if t.size < 2:
        return {"t_span_s": 0.0, "dt_median_s": None, "gaps": 0}
    dt = np.diff(t)
    med = float(np.median(dt))
    return {
        "t_span_s": float(t[-1] - t[0]),
        "dt_median_s": med,
        "gaps": int(np.sum(dt > 5 * med)),
        "longest_gap_s": float(dt.max()),
    }
