"""Fleets fitted bus by bus from their rows: the drifting level and the CVR factor.

The static ZIP fleet (:mod:`loadbayes.fleet.run`) reduces each bus to sums in one pass;
a level that drifts in time and an on/off test need every row of a bus, in time order.
Here the files (one table, a folder with hive keys, or a glob:
:func:`loadbayes.fleet.partitions.find_partitions`) are read whole, split by the bus
column, and each bus's table is handed to its fit on the fleet's engine
(:class:`loadbayes.fleet.engine.Engine`: in process, or Dask with ``--workers`` /
``--scheduler``). Each bus draws from its own child of the run's seed, taken in the
order of the sorted bus ids, so the draws do not depend on the engine or the number of
workers. With ``--pool class`` the buses' estimates are then pooled within their class
(:func:`pool_table`, the model of :mod:`loadbayes.fleet.pool`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from loadbayes.core.convergence import summarize
from loadbayes.fleet.partitions import display, find_partitions
from loadbayes.fleet.pool import SPREAD_SCALE, pool_class
from loadbayes.fleet.summary import STATS, concat, stat_rows
from loadbayes.io.errors import DataError

__all__ = ["BusTable", "RowsResult", "bus_tables", "files_of", "pool_table"]

#: Columns added while reading: each row's file and 1-based data row there.
_FILE, _ROW = "\0loadbayes-file", "\0loadbayes-row"
#: Exact draws of a class's pooled model (two halves, as two chains, for R-hat).
POOL_DRAWS = 4_000


@dataclass(frozen=True)
class BusTable:
    """One bus's rows, its class, its fit's seed, and each row's file and 1-based data row."""

    bus: str
    cls: str | None
    frame: pd.DataFrame
    seed: np.random.SeedSequence
    files: np.ndarray | None = None
    rows: np.ndarray | None = None

    def located(self, exc: DataError) -> DataError | None:
        """A bad cell of the bus's table, named by its file and row there; None otherwise.

        A bad cell stops the fleet, as a file that cannot be read stops the static one
        (:mod:`loadbayes.fleet.run`); what the bus's data as a whole cannot give (too few
        rows, no voltage steps) leaves the bus unfitted, with the reason, and the rest go on.
        """
        if exc.row is None or self.rows is None or not 1 <= exc.row <= self.rows.size:
            return None
        import re

        def file_row(m: re.Match) -> str:  # "at row 191" of the bus's table, as the file counts
            k = int(m.group(1))
            return f"at row {int(self.rows[k - 1])}" if 1 <= k <= self.rows.size else m.group(0)

        msg = re.sub(r"at row (\d+)", file_row, exc.message).replace(
            ", or fit each bus apart (--by)", " within each bus"
        )
        i = exc.row - 1
        return DataError(msg, str(self.files[i]), exc.column, int(self.rows[i]))


def _read(path: str, key_cols: Sequence[str]) -> pd.DataFrame:
    text = {c: str for c in key_cols}
    low = path.lower()
    try:
        if low.endswith((".parquet", ".pq")):
            df = pd.read_parquet(path)
            for c in key_cols:
                if c in df:
                    df[c] = df[c].astype(str)
            return df
        return pd.read_csv(path, dtype=text)
    except (OSError, ValueError) as exc:
        raise DataError(f"cannot be read ({str(exc).splitlines()[0]})", path) from None


def bus_tables(
    data: str | pd.DataFrame, *, by: str, class_col: str | None = None, seed=0
) -> list[BusTable]:
    """The rows of each bus of ``data``, sorted by bus id (module notes).

    A bus's rows from several files are joined in the files' order (sorted by path). A
    missing bus column, or a bus given two classes, is a one-line :class:`DataError`
    naming the file.
    """
    keys = [by] + ([class_col] if class_col else [])
    if isinstance(data, pd.DataFrame):
        frames = [(data.assign(**{c: data[c].astype(str) for c in keys if c in data}), "data")]
        frames[0][0][_FILE], frames[0][0][_ROW] = "data", np.arange(1, len(data) + 1)
    else:
        frames = []
        for part in find_partitions(str(data)):
            df = _read(part.path, keys)
            for k, val in part.hive.items():
                if k not in df:
                    df[k] = val
            df[_FILE], df[_ROW] = part.path, np.arange(1, len(df) + 1)
            frames.append((df, part.path))
    for df, where in frames:
        for c in keys:
            if c not in df:
                what = "bus" if c == by else "class"
                raise DataError(f"no {what} column {c!r} (columns: {', '.join(map(str, df))})",
                                where if where == "data" else display(where))  # fmt: skip
    whole = pd.concat([df for df, _ in frames], ignore_index=True)
    groups = sorted(whole.groupby(by, sort=False), key=lambda g: str(g[0]))
    seeds = np.random.SeedSequence(seed).spawn(len(groups))
    out = []
    for ss, (bus, rows) in zip(seeds, groups, strict=True):
        cls = None
        if class_col:
            found = rows[class_col].unique()
            if found.size > 1:
                where = "data" if isinstance(data, pd.DataFrame) else str(data)
                shown = ", ".join(map(str, found[:3]))
                raise DataError(f"bus {bus!r} is given {found.size} classes in column "
                                f"{class_col!r} ({shown})", where)  # fmt: skip
            cls = str(found[0])
        where = rows[[_FILE, _ROW]].to_numpy().T
        table = rows.drop(columns=[_FILE, _ROW]).reset_index(drop=True)
        out.append(BusTable(str(bus), cls, table, ss, where[0], where[1].astype(np.int64)))
    return out


def pool_table(
    table: pd.DataFrame, params: Sequence[str], *, seed=0, hdi_prob: float = 0.95
) -> tuple[pd.DataFrame, list[str]]:
    """``table`` with the bus rows of ``params`` pooled within each class, and class rows.

    A class row ``mu`` of each parameter (its class mean) and ``sd_<parameter>`` (the
    spread between its buses), with their intervals; each fitted bus's row of the
    parameter is its pooled estimate, with ``shrinkage`` the class's weight in it. Buses
    with no estimate are left out of the pooling. Returns the table and the warnings.
    """
    bus_rows = table[(table["level"] == "bus") & table["parameter"].isin(params)]
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    new_rows, class_frames, warnings = [], [], []
    replaced = np.zeros(len(table), dtype=bool)
    for cls in sorted(bus_rows["class"].dropna().unique(), key=str):
        stats_c, names_c = {}, []
        for k in params:
            rows = bus_rows[(bus_rows["class"] == cls) & (bus_rows["parameter"] == k)]
            rows = rows[np.isfinite(rows["sd"]) & (rows["sd"] > 0)]
            if rows.empty:
                continue
            res = pool_class(rows["mean"].to_numpy(), rows["sd"].to_numpy(),
                             scale=SPREAD_SCALE.get(k, 1.0), draws=POOL_DRAWS, rng=rng)  # fmt: skip
            halves = lambda d: d.reshape(2, -1)  # noqa: E731 - exact draws as two chains
            theta = summarize(np.stack([halves(res["theta"][:, i]) for i in range(len(rows))]),
                              hdi_prob=hdi_prob, tail=False)  # fmt: skip
            for i, idx in enumerate(rows.index):
                r = table.loc[idx].copy()
                for s in STATS:
                    r[s] = float(theta[s][i])
                r["shrinkage"] = float(res["shrinkage"][i])
                new_rows.append(r)
                replaced[table.index.get_loc(idx)] = True
            for name, d in ((k, res["mu"]), (f"sd_{k}", res["sd"])):
                stats_c[name] = summarize(halves(d)[None], hdi_prob=hdi_prob, tail=False)
                names_c.append(name)
            if len(rows) < 3:
                warnings.append(
                    f"only {len(rows)} bus(es) of class {cls!r} with {k}: its spread "
                    "sd_" + k + " is mostly the prior's, not a measured variation"
                )
        if stats_c:
            n_cls = int(bus_rows[bus_rows["class"] == cls]["bus"].nunique())
            class_frames.append(stat_rows("class", [None], [cls], [n_cls], stats_c))
    kept = table[~replaced]
    pooled = pd.DataFrame(new_rows, columns=table.columns) if new_rows else kept.iloc[:0]
    out = concat([*class_frames, kept, pooled])
    # the bus rows back in model order within each bus
    order = {p: i for i, p in enumerate(dict.fromkeys(table["parameter"].astype(str)))}
    rank = out["parameter"].astype(str).map(order).fillna(len(order)).to_numpy()
    lvl = np.where(out["level"].to_numpy() == "class", 0, 1)
    idx = np.lexsort((rank, out["bus"].astype(str).to_numpy(), out["class"].astype(str).to_numpy()
                      * (lvl == 0), lvl))  # fmt: skip
    return out.iloc[idx].reset_index(drop=True), warnings


@dataclass
class RowsResult:
    """A fleet fitted bus by bus: its long table (:mod:`loadbayes.fleet.summary`'s columns)."""

    table: pd.DataFrame
    files: int
    engine: str
    settings: dict


def files_of(data) -> int:
    """How many files ``data`` names (1 for a table in memory)."""
    return 1 if isinstance(data, pd.DataFrame) else len(find_partitions(str(data)))
