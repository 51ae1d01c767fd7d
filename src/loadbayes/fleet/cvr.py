"""``loadbayes cvr DATA --by FEEDER``: the CVR factors of every feeder of a fleet.

Python: :func:`cvr_fleet` (``loadbayes.cvr_fleet``), the fleet twin of
:func:`loadbayes.fit.cvr.cvr`. Each feeder's rows go to the one-feeder fit on the fleet's
engine (:mod:`loadbayes.fleet.rows`). The result is the fleets' long table
(:mod:`loadbayes.fleet.summary`'s columns), a row per feeder (``bus``) and parameter:

* ``cvr_p``, ``cvr_q``: the energy CVR factors (%dE/%dV), from the daily regression on
  the on/off switching;
* ``dp_dv``, ``dq_dv``: the instantaneous factors from the voltage steps, per unit of the
  level at the steps' median voltage;

each with its mean, sd and 95% highest-density interval (the one-feeder JSON gives central
intervals; they differ in the last digit for these near-normal draws). A feeder's flags
are in its rows' ``warnings``, first in a fixed wording a reader can count: ``head
voltage answers to the load``, ``reverse flow``, ``glitches left out``; then its fit's own
warnings. ``settings["feeders"]`` holds, per feeder, the figures behind the flags (the
head's sensitivity to the load, reverse-flow samples and days, glitches, days used, the
schedule's source, why the two factors differ). With ``pool="class"`` the four factors are
pooled within each class (:func:`loadbayes.fleet.rows.pool_table`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.core.convergence import summarize
from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.engine import Engine
from loadbayes.fleet.rows import BusTable, RowsResult, bus_tables, files_of, pool_table
from loadbayes.fleet.summary import concat, failed_rows, stat_rows
from loadbayes.io.errors import DataError, LoadbayesError, OptionError

__all__ = ["FACTORS", "FLAGS", "cvr_feeder", "cvr_fleet"]

#: The parameters of a feeder's rows: name -> (draws group, channel).
FACTORS = {"cvr_p": ("energy", "p"), "cvr_q": ("energy", "q"),
           "dp_dv": ("instantaneous", "dP/dV"), "dq_dv": ("instantaneous", "dQ/dV")}  # fmt: skip
#: The flags' fixed words (the start of a warning).
FLAGS = ("head voltage answers to the load", "reverse flow", "glitches left out")


def _flags(res: dict[str, Any]) -> tuple[list[str], dict[str, Any]]:
    imp = res.get("source_impedance") or {}
    rev, gl = res["reverse_flow"], res["glitches"]
    answers = bool(imp) and imp.get("low", 0.0) > 0
    n_gl = int(gl.get("spikes_v", 0) + gl.get("spikes_p", 0) + gl.get("stuck", 0))
    words = []
    if answers:
        words.append(f"{FLAGS[0]}: it falls by {imp['z']:.3g} [{imp['low']:.3g}, "
                     f"{imp['high']:.3g}] p.u. per unit of P; the factors are fitted from "
                     f"{res['outside_cause']} and the voltage steps only")  # fmt: skip
    if rev["samples"]:
        words.append(f"{FLAGS[1]}: {rev['samples']} samples on {rev['days']} day(s)")
    if n_gl:
        words.append(f"{FLAGS[2]}: {gl.get('spikes_v', 0)} V spike(s), {gl.get('spikes_p', 0)} "
                     f"P spike(s), {gl.get('stuck', 0)} stuck sample(s)")  # fmt: skip
    facts = {
        "head_answers_to_load": answers, "head_sensitivity": imp or None,
        "reverse_flow_samples": int(rev["samples"]), "reverse_flow_days": int(rev["days"]),
        "glitches": gl, "days_used": int(res["days"]["kept"]),
        "schedule": res["schedule"]["source"], "why": (res.get("why") or {}).get("words"),
        "days_needed": res["power"]["days_needed"],
    }  # fmt: skip
    return words, facts


def cvr_feeder(
    item: BusTable,
    options: dict[str, Any],
    sampler: SamplerSettings,
    step_draws: int,
    hdi_prob: float = 0.95,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """One feeder's rows of the table and its facts (a failed row if it cannot be fitted)."""
    from loadbayes.fit.cvr import cvr
    from loadbayes.fit.steps import STEP_DEFAULTS

    n = len(item.frame)
    s_energy, s_step = item.seed.spawn(2)
    try:
        res = cvr(item.frame, sampler=sampler.with_(seed=s_energy),
                  step_sampler=STEP_DEFAULTS.with_(draws=step_draws, burn=step_draws // 6,
                                                   seed=s_step), **options)  # fmt: skip
    except LoadbayesError as exc:
        bad = item.located(exc) if isinstance(exc, DataError) else None
        if bad is not None:
            raise bad from None
        return failed_rows([item.bus], [item.cls], [n], [str(exc)]), {"error": str(exc)}
    draws = res.pop("draws")
    series = {k: draws[g][ch] for k, (g, ch) in FACTORS.items() if ch in draws[g]}
    words, facts = _flags(res)
    warned = [" | ".join(words + list(res["warnings"]))]
    if not series:
        return failed_rows([item.bus], [item.cls], [n], warned), facts
    per = {}
    for name, d in series.items():  # the energy's and the steps' draws differ in shape
        d = np.asarray(d, float)
        one = summarize((d.reshape(2, -1) if d.ndim == 1 else d)[None], hdi_prob=hdi_prob,
                        tail=False)  # fmt: skip
        per[name] = one
    return stat_rows("bus", [item.bus], [item.cls], [n], per, warnings=warned), facts


def cvr_fleet(
    data: Any,
    *,
    by: str,
    class_col: str | None = None,
    pool: str = "none",
    engine: Engine | None = None,
    sampler: SamplerSettings | None = None,
    step_draws: int = 3_000,
    hdi_prob: float = 0.95,
    progress: Callable[[int], None] | None = None,
    on_buses: Callable[[int], None] | None = None,
    **options: Any,
) -> RowsResult:
    """The energy and instantaneous CVR factors of every feeder of ``data`` (module notes).

    Parameters
    ----------
    data : str or DataFrame
        Head telemetry of many feeders: a table with a feeder column, a folder of
        CSV/Parquet files (hive keys too) or a glob.
    by : str
        The feeder column.
    class_col : str, optional
        A class per feeder (needed by ``pool="class"``).
    pool : {"none", "class"}
        Each feeder on its own, or its factors pooled within its class.
    engine : Engine, optional
        In process when not given; Dask with ``Engine(workers=N)``.
    sampler : SamplerSettings, optional
        The energy regression's draws (:data:`loadbayes.fit.cvr.CVR_DEFAULTS`); each
        feeder draws from its own child of its seed.
    step_draws : int
        Iterations of each feeder's voltage-step fit (dP/dV).
    **options
        The options of :func:`loadbayes.fit.cvr.cvr` (columns, bases, schedule, weather,
        ...), the same for every feeder.

    progress, on_buses : callable, optional
        Called with 1 as each bus is done; with the number of buses before the fits.

    Returns
    -------
    RowsResult
        ``table`` (module notes), ``settings`` (with ``feeders``: each feeder's facts).
    """
    from loadbayes.fit.cvr import CVR_DEFAULTS

    sampler = sampler or CVR_DEFAULTS
    if pool not in ("none", "class"):
        raise OptionError(f"pool must be 'none' or 'class', got {pool!r}")
    if pool == "class" and not class_col:
        raise OptionError("pool='class' needs the class column (--class-col)")
    for bad in ("sampler", "step_sampler", "data"):
        if bad in options:
            raise OptionError(f"cvr_fleet takes no {bad}= among the feeders' options")
    seed = sampler.seed if isinstance(sampler.seed, int) else 0
    items = bus_tables(data, by=by, class_col=class_col, seed=seed)
    if on_buses is not None:
        on_buses(len(items))
    eng = engine or Engine()
    done = (lambda i, r: progress(1)) if progress else None
    out = eng.map(cvr_feeder, items, options, sampler, step_draws, hdi_prob, done=done)
    table = concat([rows for rows, _ in out])
    warnings: list[str] = []
    if pool == "class":
        table, warnings = pool_table(table, list(FACTORS), seed=seed, hdi_prob=hdi_prob)
    plain = {k: v for k, v in options.items() if isinstance(v, (str, int, float, bool, type(None)))}
    settings = {
        "kind": "cvr-fleet", "model": "cvr", "pool": pool, "by": by, "class_col": class_col,
        "draws": sampler.draws, "chains": sampler.chains, "step_draws": step_draws,
        "seed": seed, "hdi_prob": hdi_prob, "engine": eng.name, "files": files_of(data),
        "buses": len(items), "options": plain,
        "pooled": list(FACTORS) if pool == "class" else [], "warnings": warnings,
        "feeders": {it.bus: facts for it, (_, facts) in zip(items, out, strict=True)},
    }  # fmt: skip
    return RowsResult(table, settings["files"], eng.name, settings)
