"""The fleet's result: one table, a row per (bus, parameter), and class rows.

Columns (:data:`COLUMNS`): ``level`` ("bus" or "class"), ``bus``, ``class``,
``parameter``, ``mean``, ``sd``, ``hdi_low``, ``hdi_high``, ``r_hat``, ``ess_bulk``,
``n`` (rows of the bus; buses of the class on class rows), ``warnings`` (plain words,
joined by " | "; empty when none) and ``shrinkage`` (pooled fits only, see
:mod:`loadbayes.fleet.hierarchical`).

A bus that cannot be fitted (too few rows, no voltage spread without pooling, values in
the wrong units) gets one row with ``parameter`` null, NaN statistics and the reason in
``warnings``; the rest of the fleet is fitted as usual.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["COLUMNS", "STATS", "concat", "failed_rows", "stat_rows", "write_parquet"]

STATS = ("mean", "sd", "hdi_low", "hdi_high", "r_hat", "ess_bulk")
COLUMNS = ("level", "bus", "class", "parameter", *STATS, "n", "warnings", "shrinkage")


def stat_rows(
    level: str,
    buses: Sequence[object],
    classes: Sequence[object],
    n: Sequence[int],
    stats: Mapping[str, Mapping[str, np.ndarray]],
    *,
    warnings: Sequence[str] | None = None,
    shrinkage: Mapping[str, np.ndarray] | None = None,
) -> pd.DataFrame:
    """Rows for ``m`` units (buses or classes) and the parameters in ``stats``.

    Parameters
    ----------
    level : {"bus", "class"}
    buses, classes, n : sequences of length m
    stats : mapping of parameter name to the dict returned by
        :func:`loadbayes.fleet.diagnostics.summarize` (arrays of length m)
    warnings : sequence of str, optional
        One string per unit.
    shrinkage : mapping of parameter name to array of length m, optional
    """
    m = len(buses)
    names = list(stats)
    rep = len(names)
    cols: dict[str, object] = {
        "level": np.full(m * rep, level, dtype=object),
        "bus": np.tile(np.asarray(buses, dtype=object), rep),
        "class": np.tile(np.asarray(classes, dtype=object), rep),
        "parameter": np.repeat(np.asarray(names, dtype=object), m),
    }
    for s in STATS:
        cols[s] = np.concatenate([np.asarray(stats[p][s], dtype=float) for p in names])
    cols["n"] = np.tile(np.asarray(n, dtype=np.int64), rep)
    cols["warnings"] = np.tile(np.asarray(warnings if warnings else [""] * m, dtype=object), rep)
    nan = np.full(m, np.nan)
    cols["shrinkage"] = np.concatenate(
        [np.asarray((shrinkage or {}).get(p, nan), dtype=float) for p in names]
    )
    df = pd.DataFrame(cols, columns=list(COLUMNS))
    # bus-major order: the rows of one bus together, parameters in model order
    order = np.lexsort((np.repeat(np.arange(rep), m), np.tile(np.arange(m), rep)))
    return df.iloc[order].reset_index(drop=True)


def failed_rows(
    buses: Sequence[object], classes: Sequence[object], n: Sequence[int], reasons: Sequence[str]
) -> pd.DataFrame:
    """One warning row per bus that could not be fitted."""
    m = len(buses)
    nan = np.full(m, np.nan)
    cols: dict[str, object] = {
        "level": np.full(m, "bus", dtype=object),
        "bus": np.asarray(buses, dtype=object),
        "class": np.asarray(classes, dtype=object),
        "parameter": np.full(m, None, dtype=object),
    }
    cols.update({s: nan.copy() for s in STATS})
    cols["n"] = np.asarray(n, dtype=np.int64)
    cols["warnings"] = np.asarray(reasons, dtype=object)
    cols["shrinkage"] = nan.copy()
    return pd.DataFrame(cols, columns=list(COLUMNS))


def concat(frames: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """Join row blocks; class rows first, then buses sorted by id (a stable order)."""
    frames = [f for f in frames if len(f)]
    if not frames:
        return pd.DataFrame({c: [] for c in COLUMNS})
    df = pd.concat(frames, ignore_index=True)
    key = np.where(df["level"].to_numpy() == "class", 0, 1)
    bus = df["bus"].astype(str).to_numpy()
    cls = df["class"].astype(str).to_numpy()
    order = np.lexsort((np.arange(len(df)), bus, cls * (key == 0), key))
    return df.iloc[order].reset_index(drop=True)


def write_parquet(
    df: pd.DataFrame, path: str | Path, *, force: bool = False, atomic: bool = True
) -> Path:
    """Write the table atomically (never overwrites without ``force``).

    ``atomic=False`` writes straight into ``path``, a temporary the caller renames (an
    :class:`~loadbayes.io.transaction.OutputSet`'s).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from loadbayes.io.atomic import atomic_write

    table = pa.Table.from_pandas(df, preserve_index=False)
    if not atomic:
        pq.write_table(table, path)
        return Path(path)
    with atomic_write(path, force=force) as tmp:
        pq.write_table(table, tmp)
    return Path(path)
