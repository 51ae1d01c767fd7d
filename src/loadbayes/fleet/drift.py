"""``fit zip --level drift --by BUS``: a drifting-level ZIP fit for every bus of a fleet.

Each bus's rows go, in time order, to the one-bus fit
(:func:`loadbayes.fit.zip.api.fit_zip` with ``level="drift"``, and ``v_noise`` when given:
:mod:`loadbayes.fit.drift_eiv`) on the fleet's engine (:mod:`loadbayes.fleet.rows`). The
table has the static fleet's columns (:mod:`loadbayes.fleet.summary`); a bus's
parameters are a1..a3 (a4..a6), tau_p (tau_q), drift_p (drift_q: the sd of the level's
change over an hour) and dp_dv (dq_dv): dP/dV at v0 **per unit of the level** P0(t), the
drifting fit's sensitivity (the static fleet's dp_dv is in the data's units, per its
fixed P0). A bus that cannot be fitted gets one row with the reason in ``warnings``;
the fit's own warnings (a voltage that answers to the load, a negative dP/dV) are in its
rows' ``warnings``. ``pool="class"`` pools dp_dv and dq_dv within each class
(:func:`loadbayes.fleet.rows.pool_table`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.core.convergence import summarize
from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fleet.engine import Engine
from loadbayes.fleet.rows import BusTable, RowsResult, bus_tables, files_of, pool_table
from loadbayes.fleet.summary import concat, failed_rows, stat_rows
from loadbayes.io.errors import DataError, LoadbayesError, OptionError

__all__ = ["SENSITIVITIES", "fit_drift_bus", "fit_drift_fleet"]

#: The derived quantities, under their fleet names (pooled with ``pool="class"``).
SENSITIVITIES = {"dP/dV": "dp_dv", "dQ/dV": "dq_dv"}


def fit_drift_bus(
    item: BusTable,
    spec: DataSpec,
    sampler: SamplerSettings,
    *,
    hdi_prob: float = 0.95,
    v_noise: float | None = None,
) -> pd.DataFrame:
    """One bus's rows of the fleet table (a failed row with the reason if it cannot be fitted)."""
    from loadbayes.fit.zip.api import fit_zip

    n = len(item.frame)
    try:
        post = fit_zip(item.frame, spec=spec, sampler=sampler.with_(seed=item.seed),
                       level="drift", v_noise=v_noise, warn=False)  # fmt: skip
    except LoadbayesError as exc:
        bad = item.located(exc) if isinstance(exc, DataError) else None
        if bad is not None:
            raise bad from None
        return failed_rows([item.bus], [item.cls], [n], [str(exc)])
    series = dict(post.draws)
    series.update({SENSITIVITIES[k]: d for k, d in post.derived.items() if k in SENSITIVITIES})
    stats = summarize(np.stack(list(series.values())), hdi_prob=hdi_prob, tail=False)
    per = {name: {s: v[i : i + 1] for s, v in stats.items()} for i, name in enumerate(series)}
    return stat_rows("bus", [item.bus], [item.cls], [n], per, warnings=[" | ".join(post.warnings)])


def fit_drift_fleet(
    data: Any,
    *,
    by: str,
    class_col: str | None = None,
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    pool: str = "none",
    engine: Engine | None = None,
    hdi_prob: float = 0.95,
    v_noise: float | None = None,
    progress: Callable[[int], None] | None = None,
    on_buses: Callable[[int], None] | None = None,
) -> RowsResult:
    """The drifting-level ZIP of every bus of ``data`` (module notes).

    Parameters
    ----------
    data : str or DataFrame
        A table with a bus column, a folder of CSV/Parquet files (hive keys too) or a glob.
    by, class_col : str
        The bus column; the class column (needed by ``pool="class"``).
    spec : DataSpec
        Columns, bases, ``t_col`` (needed), as for one bus.
    sampler : SamplerSettings, optional
        Each bus's chains (:data:`loadbayes.fit.drift.DRIFT_DEFAULTS`); its ``seed`` is
        the run's, each bus drawing from its own child.
    pool : {"none", "class"}
    engine : Engine, optional
        In process when not given.
    v_noise : float, optional
        The sd of the noise on V (per unit of v0): errors in variables.

    progress, on_buses : callable, optional
        Called with 1 as each bus is done; with the number of buses before the fits.

    Returns
    -------
    RowsResult
    """
    from loadbayes.fit.drift import DRIFT_DEFAULTS

    spec = spec or DataSpec()
    sampler = sampler or DRIFT_DEFAULTS
    if spec.t_col is None:
        raise OptionError("a drifting level needs the time of each sample: give the time column")
    if pool not in ("none", "class"):
        raise OptionError(f"pool must be 'none' or 'class', got {pool!r}")
    if pool == "class" and not class_col:
        raise OptionError("pool='class' needs the class column (--class-col)")
    seed = sampler.seed if isinstance(sampler.seed, int) else 0
    items = bus_tables(data, by=by, class_col=class_col, seed=seed)
    if on_buses is not None:
        on_buses(len(items))
    eng = engine or Engine()
    done = (lambda i, r: progress(1)) if progress else None
    parts = eng.map(fit_drift_bus, items, spec, sampler.with_(seed=None), hdi_prob=hdi_prob,
                    v_noise=v_noise, done=done)  # fmt: skip
    table = concat(parts)
    warnings: list[str] = []
    if pool == "class":
        table, warnings = pool_table(table, list(SENSITIVITIES.values()), seed=seed,
                                     hdi_prob=hdi_prob)  # fmt: skip
    settings = {
        "kind": "fleet", "model": "zip", "level": "drift", "pool": pool, "by": by,
        "class_col": class_col, "v0": spec.v0, "chains": sampler.chains, "draws": sampler.draws,
        "burn": sampler.burn, "thin": sampler.thin, "seed": seed, "hdi_prob": hdi_prob,
        "engine": eng.name, "files": files_of(data), "buses": len(items), "v_noise": v_noise,
        "dp_dv_unit": "per unit of the level P0(t) per unit of v0, at V = v0",
        "pooled": list(SENSITIVITIES.values()) if pool == "class" else [],
        "pool_model": "normal-normal per class on each bus's posterior mean and sd "
        "(loadbayes.fleet.pool)" if pool == "class" else None, "warnings": warnings,
    }  # fmt: skip
    return RowsResult(table, settings["files"], eng.name, settings)
