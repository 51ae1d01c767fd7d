"""The fleet's result: one table, a row per (bus, parameter), and class rows.

Columns (:data:`COLUMNS`): ``level`` ("bus" or "class"), ``bus``, ``class``,
``parameter``, ``mean``, ``sd``, ``hdi_low``, ``hdi_high``, ``r_hat``, ``ess_bulk``,
``n`` (rows of the bus; buses of the class on class rows), ``warnings`` (plain words,
joined by " | "; empty when none), ``shrinkage`` (pooled fits only, see
:mod:`loadbayes.fleet.hierarchical`), ``converged`` (R-hat < 1.01 and bulk ESS >= 400
on that row; a unit with a row that is not says so in its ``warnings``), and, pooled fits
only, ``prior_sd_ratio`` and ``prior_driven`` on the share rows a1..a3 (a4..a6): along
the curvature ``a1 - 2 a2 + a3``, the posterior sd the bus's own data leave of its class
spread's (``s_d / sqrt(s_d^2 + s_c^2)``, :mod:`loadbayes.fleet.hierarchical`), and
whether it exceeds :data:`PRIOR_DRIVEN` (the split of the shares is then the class's,
not the bus's data's).

A bus that cannot be fitted (too few rows, no voltage spread without pooling, values in
the wrong units) gets one row with ``parameter`` null, NaN statistics and the reason in
``warnings``; the rest of the fleet is fitted as usual.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from loadbayes.diagnostics import ESS_MIN, RHAT_MAX

__all__ = [
    "COLUMNS",
    "PRIOR_DRIVEN",
    "STATS",
    "concat",
    "convergence_note",
    "failed_rows",
    "read_fleet",
    "stat_rows",
    "write_parquet",
]


def convergence_note(stats: Mapping[str, Mapping[str, np.ndarray]], j: int) -> str:
    """Plain words for unit ``j`` of ``stats`` when some parameter has not converged ("" if none).

    Names the worst R-hat and the lowest bulk ESS among the parameters that miss
    R-hat < 1.01 or ESS >= 400 (Vehtari et al. 2021).
    """
    rh = {p: float(v["r_hat"][j]) for p, v in stats.items()}
    es = {p: float(v["ess_bulk"][j]) for p, v in stats.items()}
    bad_r = {p: r for p, r in rh.items() if np.isfinite(r) and r >= RHAT_MAX}
    bad_e = {p: e for p, e in es.items() if np.isfinite(e) and e < ESS_MIN}
    if not bad_r and not bad_e:
        return ""
    parts = []
    if bad_r:
        p = max(bad_r, key=bad_r.get)
        parts.append(f"R-hat {bad_r[p]:.3f} on {p}")
    if bad_e:
        p = min(bad_e, key=bad_e.get)
        parts.append(f"ESS {bad_e[p]:.0f} on {p}")
    return (
        f"not converged: {', '.join(parts)} (R-hat < {RHAT_MAX} and ESS >= {ESS_MIN} wanted; "
        "run longer: --draws, --max-seconds)"
    )


STATS = ("mean", "sd", "hdi_low", "hdi_high", "r_hat", "ess_bulk")
COLUMNS = ("level", "bus", "class", "parameter", *STATS, "n", "warnings", "shrinkage", "converged",
           "prior_sd_ratio", "prior_driven")  # fmt: skip

#: Above this ratio of a bus's posterior sd to its class spread's (along the same
#: direction) the prior gives more than half the precision: the rule of the composite
#: fit's ``PRIOR_DRIVEN`` (:mod:`loadbayes.fit.composite.identifiability`).
PRIOR_DRIVEN = 0.7


def stat_rows(
    level: str,
    buses: Sequence[object],
    classes: Sequence[object],
    n: Sequence[int],
    stats: Mapping[str, Mapping[str, np.ndarray]],
    *,
    warnings: Sequence[str] | None = None,
    shrinkage: Mapping[str, np.ndarray] | None = None,
    prior_ratio: Mapping[str, np.ndarray] | None = None,
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
    prior_ratio : mapping of parameter name to array of length m, optional
        The ``prior_sd_ratio`` column; ``prior_driven`` is it above :data:`PRIOR_DRIVEN`.
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
    given = list(warnings) if warnings else [""] * m
    notes = [convergence_note(stats, j) for j in range(m)]
    joined = [" | ".join(w for w in (a, b) if w) for a, b in zip(given, notes, strict=True)]
    cols["warnings"] = np.tile(np.asarray(joined, dtype=object), rep)
    nan = np.full(m, np.nan)
    cols["shrinkage"] = np.concatenate(
        [np.asarray((shrinkage or {}).get(p, nan), dtype=float) for p in names]
    )
    ratio = np.concatenate([np.asarray((prior_ratio or {}).get(p, nan), dtype=float)
                            for p in names])  # fmt: skip
    r_hat, ess = np.asarray(cols["r_hat"]), np.asarray(cols["ess_bulk"])
    with np.errstate(invalid="ignore"):
        # a constant series (a given P0) has nothing to converge
        cols["converged"] = ((r_hat < RHAT_MAX) & (ess >= ESS_MIN)) | (np.asarray(cols["sd"]) == 0)
        cols["prior_driven"] = ratio > PRIOR_DRIVEN
    cols["prior_sd_ratio"] = ratio
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
    cols["converged"] = np.zeros(m, bool)
    cols["prior_sd_ratio"] = nan.copy()
    cols["prior_driven"] = np.zeros(m, bool)
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
    df: pd.DataFrame,
    path: str | Path,
    *,
    force: bool = False,
    atomic: bool = True,
    settings: Mapping[str, object] | None = None,
) -> Path:
    """Write the table atomically (never overwrites without ``force``).

    ``atomic=False`` writes straight into ``path``, a temporary the caller renames (an
    :class:`~loadbayes.io.transaction.OutputSet`'s). ``settings`` (JSON-able) go into the
    file's key-value metadata under ``loadbayes`` (read back by :func:`read_fleet`).
    """
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from loadbayes.io.atomic import atomic_write

    table = pa.Table.from_pandas(df, preserve_index=False)
    if settings is not None:
        meta = dict(table.schema.metadata or {})
        meta[b"loadbayes"] = json.dumps(settings, default=str).encode()
        table = table.replace_schema_metadata(meta)
    if not atomic:
        pq.write_table(table, path)
        return Path(path)
    with atomic_write(path, force=force) as tmp:
        pq.write_table(table, tmp)
    return Path(path)


def read_fleet(path: str | Path) -> tuple[pd.DataFrame, dict]:
    """A fleet table and its settings (``{}`` for a file written without them)."""
    import json

    import pyarrow.parquet as pq

    table = pq.read_table(path)
    raw = (table.schema.metadata or {}).get(b"loadbayes")
    return table.to_pandas(), (json.loads(raw) if raw else {})
