"""A fleet result read for its report: the table checked, its optional parts found.

``loadbayes fit zip DATA --by BUS --out fleet.parquet`` writes one row per (bus,
parameter) and, when pooled, class rows (:mod:`loadbayes.fleet.summary`). The report
needs the columns of :data:`REQUIRED`; everything else is optional and looked up by
what it means, so that a table with more columns (a later loadbayes) still reports, and
a table with fewer says which part is "not in this file":

- ``shrinkage`` (pooled fits), and a bus's own, unpooled estimate (a column
  ``unpooled_mean``/``own_mean``, or a second table from a ``--pool none`` run);
- the voltage sensitivities dP/dV and dQ/dV (parameter rows or columns named ``dp_dv``,
  ``dq_dv``, case and punctuation ignored), otherwise their means from ``2 a1 + a2``
  and ``2 a4 + a5`` (the slopes at V0 in per unit of P0, Q0: exact for the means, with
  no interval since the table keeps no joint draws);
- coordinates (``x``/``y`` or ``lat``/``lon``) on the bus rows or in a ``--coords`` file;
- the run's settings, kept as JSON under the key ``loadbayes`` of the Parquet schema's
  metadata by ``fit zip --by``.

Nothing here draws or writes: :mod:`loadbayes.report.fleet_report` builds the page.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.io.errors import DataError

__all__ = [
    "REQUIRED",
    "FleetTable",
    "is_parquet",
    "load_fleet",
    "read_coords",
    "table_coords",
]

#: R-hat above which chains are said not to agree; bulk ESS below which draws are few
#: (as in the report of one fit); fewer rows than THIN_ROWS make a bus "thin".
RHAT_LIMIT, ESS_LIMIT, THIN_ROWS = 1.01, 400, 50
#: Warnings that say a bus's voltage hardly moved.
FLAT_WORDS = ("voltage has no spread", "voltage spans only", "too few distinct voltage")
#: Warnings (of a later fleet run) about convergence, listed as reasons as they stand.
_CONVERGENCE = re.compile(r"r-hat|\bess\b|converge", re.IGNORECASE)

#: Columns without which a table is not a fleet result.
REQUIRED = ("level", "bus", "class", "parameter", "mean", "sd", "hdi_low", "hdi_high",
            "r_hat", "ess_bulk", "n", "warnings")  # fmt: skip
NUMERIC = ("mean", "sd", "hdi_low", "hdi_high", "r_hat", "ess_bulk", "n")
#: Names (lower case, letters and digits only) of the sensitivities and their columns.
SENSITIVITY = {"dp_dv": ("dpdv", "dpdvpu", "slopep"), "dq_dv": ("dqdv", "dqdvpu", "slopeq")}
#: The pair of ZIP shares whose ``2 a + b`` is the slope at V0 of each channel.
SLOPE_PAIRS = {"dp_dv": ("a1", "a2"), "dq_dv": ("a4", "a5")}
#: The share row that names each channel's pair when its split is the class's.
SPLIT_PAIRS = {"a1": "a1, a2", "a4": "a4, a5"}
UNPOOLED = ("unpooledmean", "ownmean", "lsmean", "unpooled")
COORDS = (("x", "y"), ("lon", "lat"), ("longitude", "latitude"))


def _key(name: object) -> str:
    return re.sub(r"[^a-z0-9]", "", str(name).lower())


def is_parquet(path: str | Path) -> bool:
    """True when ``path`` starts with Parquet's magic bytes, or is named ``.parquet``/``.pq``.

    By name too, so that a damaged or empty ``fleet.parquet`` is reported as a Parquet
    file that cannot be read, not as "not a JSON result".
    """
    p = Path(path)
    if p.suffix.lower() in (".parquet", ".pq") and p.is_file():
        return True
    try:
        with open(p, "rb") as fh:
            return fh.read(4) == b"PAR1"
    except OSError:
        return False


@dataclass
class FleetTable:
    """A checked fleet table and what the report found in it."""

    path: str
    table: pd.DataFrame
    settings: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # Ids as text (a map's ids are text too), no null class, warnings as text.
        df = self.table.copy()
        df["warnings"] = df["warnings"].fillna("").astype(str)
        df["bus"] = [None if pd.isna(b) else str(b) for b in df["bus"]]
        df["class"] = ["all" if pd.isna(c) else str(c) for c in df["class"]]
        self.table = df

    @property
    def bus_rows(self) -> pd.DataFrame:
        """Rows of level ``bus`` (a null parameter: a bus not fitted)."""
        return self.table[self.table["level"] == "bus"]

    @property
    def class_rows(self) -> pd.DataFrame:
        """Rows of level ``class`` (pooled fits only)."""
        return self.table[self.table["level"] == "class"]

    @property
    def pooled(self) -> bool:
        """True for a ``--pool class`` result (it has class rows)."""
        return bool(len(self.class_rows))

    def wide(self, stat: str = "mean") -> pd.DataFrame:
        """One row per fitted bus, a column per parameter (``stat`` of each)."""
        b = self.bus_rows.dropna(subset=["parameter"])
        return b.pivot_table(index="bus", columns="parameter", values=stat, aggfunc="first",
                             sort=False)  # fmt: skip

    def flagged(self) -> pd.DataFrame:
        """Buses with something to say, a row each: bus, class, n, reasons (list of str).

        Not fitted (a null parameter), chains that disagree (R-hat above
        :data:`RHAT_LIMIT`), few effective draws (bulk ESS below :data:`ESS_LIMIT`), thin
        (fewer than :data:`THIN_ROWS` rows), flat voltage (the warnings say so), shares
        whose split is the class's (a pooled table's ``prior_driven``: a1, a2 or a4, a5
        not determined separately by the bus's data).
        """
        b = self.bus_rows
        first = b.groupby("bus", sort=False).agg(
            cls=("class", "first"), n=("n", "first"), text=("warnings", "first")
        )
        fitted = b[b["parameter"].notna()]
        # A later table's own verdict per row (R-hat < 1.01 and ESS >= 400), when present.
        if "converged" in b.columns:
            ok = fitted["converged"].map(lambda v: True if pd.isna(v) else bool(v))
            not_ok = set(fitted.loc[~ok.astype(bool), "bus"])
        else:
            not_ok = set()
        # A pooled table's prior_driven rows: the channels whose shares' split is the class's.
        split: dict = {}
        if "prior_driven" in b.columns:
            pd_rows = fitted[fitted["prior_driven"].map(lambda v: False if pd.isna(v) else bool(v))]
            for bus, par in zip(pd_rows["bus"], pd_rows["parameter"], strict=True):
                if par in SPLIT_PAIRS:
                    split.setdefault(bus, []).append(SPLIT_PAIRS[par])
        # The worst parameter of each bus: one sort, not a Python loop over 10^4 buses.
        worst_r = fitted.sort_values("r_hat", ascending=False, na_position="last")
        worst_r = worst_r.drop_duplicates("bus").set_index("bus")
        worst_e = fitted.sort_values("ess_bulk", ascending=True, na_position="last")
        worst_e = worst_e.drop_duplicates("bus").set_index("bus")
        out = []
        for bus, cls, n, text in zip(first.index, first["cls"], first["n"], first["text"],
                                     strict=True):  # fmt: skip
            n = int(n) if np.isfinite(n) else 0
            reasons = []
            if bus not in worst_r.index:
                reasons.append(text or "not fitted")
            else:
                said = [w for w in text.split(" | ") if _CONVERGENCE.search(w)]
                rh, who_r = worst_r.at[bus, "r_hat"], worst_r.at[bus, "parameter"]
                ess, who_e = worst_e.at[bus, "ess_bulk"], worst_e.at[bus, "parameter"]
                if said:  # the run's own words (a later loadbayes) stand for the numbers
                    reasons += said
                else:
                    if np.isfinite(rh) and rh > RHAT_LIMIT:
                        reasons.append(f"unconverged: R-hat {rh:.3f} ({who_r})")
                    if np.isfinite(ess) and ess < ESS_LIMIT:
                        reasons.append(f"few effective draws: ESS {ess:,.0f} ({who_e})")
                    if not reasons and bus in not_ok:
                        reasons.append("unconverged (the table's converged column)")
                if n < THIN_ROWS:
                    reasons.append(f"thin: {n} rows")
                if any(w in text.lower() for w in FLAT_WORDS):
                    reasons.append("flat voltage")
                if bus in split:
                    reasons.append(f"split of {' and '.join(split[bus])} is the class's")
            if reasons:
                out.append({"bus": bus, "class": cls, "n": n,
                            "reasons": list(dict.fromkeys(reasons))})  # fmt: skip
        return pd.DataFrame(out, columns=["bus", "class", "n", "reasons"])

    def column_named(self, names: tuple[str, ...]) -> str | None:
        """The table's column whose key is one of ``names`` (or None)."""
        for c in self.table.columns:
            if _key(c) in names:
                return str(c)
        return None

    def sensitivity(self, which: str) -> tuple[pd.DataFrame | None, str, str]:
        """Per-bus dP/dV or dQ/dV: (frame of mean, low, high by bus, source, unit).

        ``which`` is ``dp_dv`` or ``dq_dv``. The frame is None when neither the value nor
        the shares it follows from are in the table. The table's own values are in its
        P (Q) units per per-unit V (``P0 (2 a1 + a2) / V0``); from the shares alone, the
        slope is per unit of the bus's P0 (Q0).
        """
        ch = "P" if which == "dp_dv" else "Q"
        own = f"the data's {ch} units per p.u. of V"
        if self.settings.get("level") == "drift":  # fleet/drift.py: per unit of the level
            own = f"per unit of the level {ch}0(t) per p.u. of V"
        rel = f"per unit of {ch}0 per p.u. of V"
        keys = (_key(which), *SENSITIVITY[which])
        b = self.bus_rows.dropna(subset=["parameter"])
        rows = b[b["parameter"].map(_key).isin(keys)]
        if len(rows):
            out = rows.set_index("bus")[["mean", "hdi_low", "hdi_high"]]
            src = f"the table's {rows['parameter'].iloc[0]} rows"
            return out[~out.index.duplicated()], src, own
        col = self.column_named(keys)
        if col is not None:
            v = b.groupby("bus", sort=False)[col].first()
            out = pd.DataFrame({"mean": v, "hdi_low": np.nan, "hdi_high": np.nan})
            return out, f"the table's {col!r} column", own
        a, c = SLOPE_PAIRS[which]
        w = self.wide()
        if a in w.columns and c in w.columns:
            out = pd.DataFrame({"mean": 2.0 * w[a] + w[c], "hdi_low": np.nan, "hdi_high": np.nan})
            return out.dropna(subset=["mean"]), f"2 {a} + {c} (the means only)", rel
        return None, "", ""

    def unpooled(self, other: FleetTable | None = None) -> tuple[pd.DataFrame | None, str]:
        """Each bus's own (unpooled) means by parameter, from a column or another table."""
        col = self.column_named(UNPOOLED)
        if col is not None:
            b = self.bus_rows.dropna(subset=["parameter"])
            w = b.pivot_table(index="bus", columns="parameter", values=col, aggfunc="first")
            return w, f"the table's {col!r} column"
        if other is not None:
            return other.wide(), Path(other.path).name
        return None, ""


def load_fleet(path: str | Path) -> FleetTable:
    """Read and check a fleet table (Parquet).

    Raises
    ------
    DataError
        A missing or unreadable file, or a table that is not a fleet result: the file,
        the column and (for a bad value) the row, in one line.
    """
    import pyarrow.parquet as pq

    name = str(path)
    p = Path(path)
    if not p.is_file():
        raise DataError("file not found" if not p.exists() else "is not a file", name)
    try:
        table = pq.read_table(p)
    except Exception as exc:  # pyarrow raises several types; say it in one line
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DataError(f"not a readable Parquet file ({msg})", name) from None
    have = table.column_names
    for col in REQUIRED:
        if col not in have:
            shown = ", ".join(have[:8]) + (", ..." if len(have) > 8 else "")
            raise DataError(
                f"not a loadbayes fleet table: no such column (it has {shown or 'none'}); "
                "write one with loadbayes fit zip DATA --by BUS --out fleet.parquet",
                name,
                column=col,
            )
    df = table.to_pandas()
    for col in NUMERIC:
        if not (pd.api.types.is_numeric_dtype(df[col]) or df[col].isna().all()):
            bad = pd.to_numeric(df[col], errors="coerce").isna() & df[col].notna()
            row = int(np.flatnonzero(bad.to_numpy())[0]) + 1 if bad.any() else None
            raise DataError("not a number: a fleet table's statistics are numbers", name,
                            column=col, row=row)  # fmt: skip
        df[col] = pd.to_numeric(df[col])
    levels = df["level"].astype(str)
    bad = ~levels.isin(["bus", "class"])
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        raise DataError(f"level {df['level'].iloc[row]!r}: expected 'bus' or 'class'", name,
                        column="level", row=row + 1)  # fmt: skip
    if not (levels == "bus").any():
        raise DataError("no bus rows: not a fleet result", name, column="level")
    _check_statistics(df, name)
    _check_unique(df, name)
    settings: dict[str, Any] = {}
    meta = table.schema.metadata or {}
    if b"loadbayes" in meta:
        try:
            settings = json.loads(meta[b"loadbayes"].decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError):
            settings = {}
        if not isinstance(settings, dict):
            settings = {}
    return FleetTable(name, df, settings)


def _check_unique(df: pd.DataFrame, name: str) -> None:
    """One row per bus (or class) and parameter (``df`` has a range index).

    A repeated one (a pooled table's class column set to one value) was pandas' "The truth
    value of a Series is ambiguous", with no file nor row.
    """
    for level in ("bus", "class"):
        key = df.loc[(df["level"].astype(str) == level) & df["parameter"].notna(),
                     [level, "parameter"]]  # fmt: skip
        twice = key[key.duplicated(keep=False)]
        if len(twice):
            who, par = twice.iloc[0]
            rows = [
                int(i) + 1 for i in twice.index[(twice[level] == who) & (twice["parameter"] == par)]
            ]
            raise DataError(
                f"{level} {who!r}, parameter {par!r} is on rows {', '.join(map(str, rows[:5]))}: "
                f"a fleet table has one row per {level} and parameter (an edited table?)",
                name, column=level, row=rows[1],
            )  # fmt: skip


#: A statistic beyond this cannot be drawn (its square overflows) and is no fit's.
MAX_STATISTIC = 1e150


def _check_statistics(df: pd.DataFrame, name: str) -> None:
    """A fitted row's mean, sd and interval are finite, drawable numbers; an sd is >= 0.

    NaN and 1e308 made a report with numpy's and matplotlib's warnings (a bus not fitted
    has a null parameter and null statistics: not checked).
    """
    fitted = df["parameter"].notna().to_numpy()
    for col in ("mean", "sd", "hdi_low", "hdi_high"):
        x = df[col].to_numpy(dtype=float)
        bad = fitted & ~(np.abs(x) <= MAX_STATISTIC)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataError(
                f"{x[i]:g} in a fitted row (parameter {df['parameter'].iloc[i]!r}): not a "
                "statistic the report can show (a damaged table?)",
                name, column=col, row=i + 1,
            )  # fmt: skip
        if col == "sd" and (fitted & (x < 0)).any():
            i = int(np.flatnonzero(fitted & (x < 0))[0])
            raise DataError(f"{x[i]:g} is negative: not a posterior sd", name, column=col,
                            row=i + 1)  # fmt: skip


def _read_any(path: str | Path) -> pd.DataFrame:
    p = Path(path)
    if not p.exists():
        raise DataError("file not found", str(path))
    try:
        if p.is_dir() or is_parquet(p):
            return pd.read_parquet(p)
        return pd.read_csv(p, sep=None, engine="python")
    except Exception as exc:  # readers raise many types; one line
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DataError(f"cannot be read as a table ({msg})", str(path)) from None


def read_coords(path: str | Path, *, by: str | None = None) -> tuple[pd.DataFrame, tuple[str, str]]:
    """Bus coordinates from a CSV or Parquet file (the fleet's input itself will do).

    The bus column is ``by`` (the fleet's ``--by``), else ``bus`` or ``bus_id``; the
    coordinates are ``x``/``y`` or ``lon``/``lat`` (``longitude``/``latitude``). A bus
    on several rows (a meter file) takes its first row.

    Returns
    -------
    (DataFrame indexed by bus with columns ``x``, ``y``; (x name, y name))
    """
    df = _read_any(path)
    lower = {str(c).lower(): c for c in df.columns}
    bus = next((lower[c] for c in ([by.lower()] if by else []) + ["bus", "bus_id"]
                if c in lower), None)  # fmt: skip
    if bus is None:
        raise DataError(f"no bus column (expected {by or 'bus'!r} or 'bus_id')", str(path),
                        column=by or "bus")  # fmt: skip
    for xn, yn in COORDS:
        if xn in lower and yn in lower:
            xs, ys = lower[xn], lower[yn]
            break
    else:
        raise DataError("no coordinates: expected columns x and y, or lat and lon", str(path),
                        column="x")  # fmt: skip
    out = pd.DataFrame({"x": pd.to_numeric(df[xs], errors="coerce"),
                        "y": pd.to_numeric(df[ys], errors="coerce")})  # fmt: skip
    for c, orig in (("x", xs), ("y", ys)):
        bad = out[c].isna() & df[orig].notna()
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise DataError(f"non-numeric value {df[orig].iloc[row]!r}", str(path),
                            column=str(orig), row=row + 1)  # fmt: skip
    out.index = df[bus].astype(str)
    out = out[~out.index.duplicated()].dropna()
    return out, (str(xs), str(ys))


def table_coords(ft: FleetTable) -> tuple[pd.DataFrame | None, tuple[str, str]]:
    """Coordinates carried by the fleet table's bus rows, if any."""
    lower = {str(c).lower(): c for c in ft.table.columns}
    for xn, yn in COORDS:
        if xn in lower and yn in lower:
            b = ft.bus_rows
            out = pd.DataFrame({"x": pd.to_numeric(b[lower[xn]], errors="coerce").to_numpy(),
                                "y": pd.to_numeric(b[lower[yn]], errors="coerce").to_numpy()},
                               index=b["bus"].astype(str).to_numpy())  # fmt: skip
            out = out[~out.index.duplicated()].dropna()
            if len(out):
                return out, (str(lower[xn]), str(lower[yn]))
    return None, ("", "")
