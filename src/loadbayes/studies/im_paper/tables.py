"""The motor study's tables: Table I, Table III, the physical parameters, and plain text."""

from __future__ import annotations

from typing import Any

import pandas as pd

from loadbayes.models.motor import COEFFICIENT_NAMES
from loadbayes.studies.im_paper.study import (
    METHODS,
    PAPER_TABLE1,
    PAPER_TABLE3,
    PHYSICAL,
    ImStudy,
    _err,
)


def table1(study: ImStudy) -> pd.DataFrame:
    """The paper's Table I for each motor: true, posterior mean, error %, and more.

    Columns: ``motor, coefficient, true, gs_mean, gs_sd, gs_hdi_low, gs_hdi_high,
    gs_err_pct, gs_covers`` (modelled currents), ``measured_mean, measured_err_pct``
    (the paper's form), and the paper's ``paper_true, paper_mean, paper_err_pct``.
    """
    rows = []
    for run_ in study.runs.values():
        s, truth = run_.summary("gs"), run_.truth
        for k in COEFFICIENT_NAMES:
            m = run_.estimate("gs_measured", k)
            pt, pm, pe = PAPER_TABLE1[k]
            rows.append(
                {
                    "motor": run_.name,
                    "coefficient": k,
                    "true": truth[k],
                    "gs_mean": s.loc[k, "mean"],
                    "gs_sd": s.loc[k, "sd"],
                    "gs_hdi_low": s.loc[k, "hdi_low"],
                    "gs_hdi_high": s.loc[k, "hdi_high"],
                    "gs_err_pct": _err(s.loc[k, "mean"], truth[k]),
                    "gs_covers": bool(s.loc[k, "hdi_low"] <= truth[k] <= s.loc[k, "hdi_high"]),
                    "measured_mean": m,
                    "measured_err_pct": _err(m, truth[k]),
                    "paper_true": pt,
                    "paper_mean": pm,
                    "paper_err_pct": pe,
                }
            )
    return pd.DataFrame(rows)


def table3(study: ImStudy) -> pd.DataFrame:
    """The paper's Table III for each motor: every method's estimate and the truth."""
    rows = []
    for run_ in study.runs.values():
        truth = run_.truth
        for k in COEFFICIENT_NAMES:
            row: dict[str, Any] = {"motor": run_.name, "coefficient": k, "true": truth[k]}
            for method in METHODS:
                row[method] = run_.estimate(method, k)
            for method in METHODS:
                row[f"{method}_err_pct"] = _err(row[method], truth[k])
            gs, ls, kf, real = PAPER_TABLE3[k]
            row.update(paper_gs=gs, paper_ls=ls, paper_kf=kf, paper_true=real)
            rows.append(row)
    return pd.DataFrame(rows)


def physical_table(study: ImStudy) -> pd.DataFrame:
    """Physical parameters (GS, modelled currents): truth, mean, 95% HDI, coverage.

    ``rs, xp, x, tp_s, h_s`` are identified by the data; ``xs, xm, xr, rr`` come from
    the closure Xs = Xr, so their ``reference`` is what the closure gives on the true
    coefficients (the motor's own values only when its Xs = Xr). ``err_pct`` and
    ``covers`` are against ``reference``.
    """
    from loadbayes.models.motor import inverse

    rows = []
    for run_ in study.runs.values():
        s, truth = run_.summary("gs"), run_.truth
        closure = inverse(run_.params.coefficients(), "xs=xr", f_hz=run_.params.f_hz)
        for k in PHYSICAL:
            identified = k in ("rs", "xp", "x", "tp_s", "h_s")
            ref = truth[k] if identified else float(closure[k])
            lo, hi = s.loc[k, "hdi_low"], s.loc[k, "hdi_high"]
            rows.append(
                {
                    "motor": run_.name,
                    "parameter": k,
                    "identified": identified,
                    "true": truth[k],
                    "reference": ref,
                    "mean": s.loc[k, "mean"],
                    "hdi_low": lo,
                    "hdi_high": hi,
                    "err_pct": _err(s.loc[k, "mean"], ref),
                    "covers": bool(lo <= ref <= hi),
                }
            )
    return pd.DataFrame(rows)


def text_tables(study: ImStudy) -> str:
    """Table I and Table III as plain text (what ``reproduce im`` prints)."""
    t1 = table1(study)[
        [
            "motor",
            "coefficient",
            "true",
            "gs_mean",
            "gs_err_pct",
            "measured_mean",
            "measured_err_pct",
        ]
    ]
    t3 = table3(study)[["motor", "coefficient", "true", *METHODS]]
    fmt = {"float_format": lambda x: f"{x:.6g}", "index": False}
    return (
        "Table I (5 coefficients; GS = modelled currents, measured = the paper's form)\n"
        + t1.to_string(**fmt)
        + "\n\nTable III (estimates by method)\n"
        + t3.to_string(**fmt)
    )
