"""Measurements read from a table: V, P, Q (f, t) in per unit, with their file rows.

The one reader every command of a load model uses: the user's column names, the bases
that turn data units into per unit, rows dropped or refused, and errors from in-memory
arrays relocated to the file's column and row.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["PowerColumns", "power_chunks", "read_power_columns", "relocate"]


@dataclass
class PowerColumns:
    """Columns read for a load model, in per unit, with their 1-based data row numbers."""

    cols: dict[str, np.ndarray]
    rows: np.ndarray
    n_dropped: int = 0
    extra: dict[str, np.ndarray] = field(default_factory=dict)


def power_chunks(
    path: str,
    *,
    v_col: str,
    p_col: str,
    q_col: str | None,
    q_required: bool,
    f_col: str | None = None,
    t_col: str | None = None,
    extra: tuple[str, ...] = (),
    v_base: float | None = None,
    s_base: float | None = None,
    drop_invalid: bool = False,
    chunk_rows: int = 1 << 18,
) -> Iterator[PowerColumns]:
    """Read ``v``, ``p`` (``q``, ``f``, ``t`` and optional ``extra`` columns) in chunks.

    Column names are the user's; the chunks use ``v, p, q, f, t``. A Q column named by
    default (``q``) is optional, a Q column named by the user is required, ``None``
    skips it; ``f_col`` and ``t_col`` are read when given (``t_col`` only if present).
    Voltages are divided by ``v_base``, powers by ``s_base``.
    """
    from loadbayes.io.tables import iter_chunks

    for name, base in (("--v-base", v_base), ("--s-base", s_base)):
        if base is not None and not (np.isfinite(base) and base > 0):
            raise ValueError(f"{name} must be positive, got {base}")
    vs, ss = v_base or 1.0, s_base or 1.0
    required = (
        [v_col, p_col] + ([q_col] if q_col and q_required else []) + ([f_col] if f_col else [])
    )
    optional = ([q_col] if q_col and not q_required else []) + ([t_col] if t_col else [])
    optional += [c for c in extra if c not in required + optional]
    for chunk in iter_chunks(
        path,
        required,
        optional=optional,
        positive=[v_col],
        chunk_rows=chunk_rows,
        drop_invalid=drop_invalid,
    ):
        d = chunk.data
        cols = {"v": d[v_col], "p": d[p_col]}
        if q_col and q_col in d:
            cols["q"] = d[q_col]
        # Divide only when a base is given: each division copies the chunk (x / 1.0 is x).
        if v_base is not None:
            cols["v"] = cols["v"] / vs
        if s_base is not None:
            for key in ("p", "q"):
                if key in cols:
                    cols[key] = cols[key] / ss
        if f_col:
            cols["f"] = d[f_col]
        if t_col and t_col in d:
            cols["t"] = d[t_col]
        ext = {c: d[c] for c in extra if c in d}
        yield PowerColumns(cols, chunk.rows, chunk.n_dropped, ext)


def read_power_columns(path: str, *, progress=None, **kw: Any) -> PowerColumns:
    """All of :func:`power_chunks` in memory (for samplers that visit every sample)."""
    from loadbayes.io.errors import DataError

    parts = []
    for part in power_chunks(path, **kw):
        parts.append(part)
        if progress is not None:
            progress(part.rows.size)
    if not parts or sum(p.rows.size for p in parts) == 0:
        raise DataError("no valid rows", path=str(path))
    cols = {k: np.concatenate([p.cols[k] for p in parts]) for k in parts[0].cols}
    extra = {k: np.concatenate([p.extra[k] for p in parts]) for k in parts[0].extra}
    rows = np.concatenate([p.rows for p in parts])
    return PowerColumns(cols, rows, sum(p.n_dropped for p in parts), extra)


def relocate(exc: Exception, path: str, rows: np.ndarray, names: dict[str, str | None]):
    """A DataError from in-memory arrays, re-located to the file's column and row."""
    from loadbayes.io.errors import DataError

    row = exc.row  # type: ignore[attr-defined]
    if row is not None and 1 <= row <= rows.size:
        row = int(rows[row - 1])
    column = names.get(exc.column or "", exc.column)  # type: ignore[attr-defined]
    return DataError(exc.message, path=str(path), column=column, row=row)  # type: ignore[attr-defined]
