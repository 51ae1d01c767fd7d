"""The ZIP study's tables: Table II and its error measure, the comparison, the sweep's n.

Plain pandas frames from a :class:`~loadbayes.studies.zip_paper.study.ZipStudy`, and the
plain-text version the CLI prints.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.studies.zip_paper.study import (
    METHODS,
    PAPER_TABLE2,
    SD_TARGETS,
    TABLE2_ROWS,
    TRUE_ZIP,
    ZipStudy,
)


def error_pct(est: Any, true: Any) -> float:
    """Mean absolute relative error in %: ``100 * mean |est - true| / |true|``.

    Pairs where either value is NaN (a power flow that did not converge) are left out;
    NaN if none is left.
    """
    e = np.asarray(est, dtype=float)
    t = np.asarray(true, dtype=float)
    ok = np.isfinite(e) & np.isfinite(t)
    if not ok.any():
        return float("nan")
    return float(100.0 * np.mean(np.abs(e[ok] - t[ok]) / np.abs(t[ok])))


def required_n(sd_at_n: float, n: int, target_sd: float) -> float:
    """Experiments needed for a posterior sd of ``target_sd``, from sd ~ 1 / sqrt(n).

    With a weak prior the posterior sd of a coefficient is its least-squares standard
    error, ``sigma sqrt([(Z'Z)^-1]_11)``, and ``Z'Z / n`` settles to a constant for i.i.d.
    experiments: so ``sd(n') = sd(n) sqrt(n / n')``.
    """
    if not (sd_at_n > 0 and target_sd > 0 and n > 0):
        raise ValueError("sd_at_n, n and target_sd must be positive")
    return float(n * (sd_at_n / target_sd) ** 2)


def table2(validation: pd.DataFrame, estimates: Mapping[str, Mapping[str, float]]) -> pd.DataFrame:
    """Table II from the validation frame: errors in % and coefficient errors, per method.

    Parameters
    ----------
    validation : pandas.DataFrame
        Columns ``v_true_pu``, ``p_true_pu`` and, per method ``m``, ``v_{m}_pu``,
        ``p_{m}_pu``.
    estimates : mapping
        ``{method: {"a1": .., "a2": .., "a3": ..}}``; keys of :data:`TABLE2_ROWS` give
        the paper's rows (GS, LS, KF), others are kept under their own name.

    Returns
    -------
    pandas.DataFrame
        Indexed by method; ``voltage_error_pct``, ``power_error_pct``, the paper's
        values beside them (NaN where the paper has none), ``a1, a2, a3``, their errors
        ``a1_err`` .. (estimate - truth), and the largest ``|dV|`` and ``|dP|`` (p.u.).
    """
    rows = []
    for m, est in estimates.items():
        name = TABLE2_ROWS.get(m, m)
        paper_v, paper_p = PAPER_TABLE2.get(name, (np.nan, np.nan))
        v, p = validation[f"v_{m}_pu"], validation[f"p_{m}_pu"]
        row: dict[str, Any] = {
            "method": name,
            "voltage_error_pct": error_pct(v, validation.v_true_pu),
            "paper_voltage_error_pct": paper_v,
            "power_error_pct": error_pct(p, validation.p_true_pu),
            "paper_power_error_pct": paper_p,
        }
        for i, k in enumerate(("a1", "a2", "a3")):
            row[k] = float(est[k])
            row[f"{k}_err"] = float(est[k]) - TRUE_ZIP[i]
        row["max_abs_dv_pu"] = float(np.nanmax(np.abs(v - validation.v_true_pu)))
        row["max_abs_dp_pu"] = float(np.nanmax(np.abs(p - validation.p_true_pu)))
        row["n_failed"] = int((~np.isfinite(v.to_numpy(dtype=float))).sum())
        rows.append(row)
    return pd.DataFrame(rows).set_index("method")


def needed_n(sweep: pd.DataFrame, targets: Sequence[float] = SD_TARGETS) -> pd.DataFrame:
    """Experiments needed for each sd target at each noise, from the largest n swept."""
    rows = []
    for s, grp in sweep.groupby("noise"):
        last = grp.sort_values("n").iloc[-1]
        row: dict[str, Any] = {"noise": float(s), "from_n": int(last.n_used)}
        for t in targets:
            row[f"n_for_sd_{t:g}"] = required_n(last.a1_sd_ls, int(last.n_used), t)
        rows.append(row)
    return pd.DataFrame(rows)


def study_table2(study: ZipStudy) -> pd.DataFrame:
    """Table II of the study (rows GS, LS, KF), with the paper's values beside."""
    return table2(study.validation, {m: study.estimate(m) for m in TABLE2_ROWS})


def comparison(study: ZipStudy) -> pd.DataFrame:
    """Every estimator: Table II's measures, a1..a6, and the sd of a1, a2 where it has one."""
    est = {m: study.estimate(m) for m in METHODS}
    t = table2(study.validation, est)
    t.index = list(METHODS)
    t.insert(0, "label", list(METHODS.values()))
    for m in METHODS:
        post = study.fits[m]
        for k in ("a4", "a5", "a6"):
            t.loc[m, k] = est[m][k]
        for k in ("a1", "a2"):
            t.loc[m, f"{k}_sd"] = float(np.std(post.draws[k]))
    t.index.name = "key"
    return t


def sampler_table(study: ZipStudy) -> pd.DataFrame:
    """Single-site against blocked Gibbs on the same data: mean, sd, ESS, R-hat."""
    rows = []
    for m in ("gs_single", "gs"):
        s = study.summary(m)
        for k, r in s.iterrows():
            rows.append(
                {
                    "scheme": "single-site" if m == "gs_single" else "blocked",
                    "parameter": k,
                    "mean": r["mean"],
                    "sd": r["sd"],
                    "hdi_low": r["hdi_low"],
                    "hdi_high": r["hdi_high"],
                    "ess_bulk": r["ess_bulk"],
                    "r_hat": r["r_hat"],
                }
            )
    return pd.DataFrame(rows)


def validation_summary(study: ZipStudy) -> pd.DataFrame:
    """|dV| and |dP| (p.u.; P also in kW) per method: median, mean, 95th percentile, max."""
    val = study.validation
    p0_kw = 1e3 * float(study.settings["p0_mw"])
    rows = []
    for m in METHODS:
        dv = np.abs(val[f"dv_{m}_pu"].to_numpy(dtype=float))
        dp = np.abs(val[f"dp_{m}_pu"].to_numpy(dtype=float))
        rows.append(
            {
                "method": m,
                "dv_median_pu": float(np.nanmedian(dv)),
                "dv_mean_pu": float(np.nanmean(dv)),
                "dv_p95_pu": float(np.nanpercentile(dv, 95)),
                "dv_max_pu": float(np.nanmax(dv)),
                "dp_median_pu": float(np.nanmedian(dp)),
                "dp_mean_pu": float(np.nanmean(dp)),
                "dp_p95_pu": float(np.nanpercentile(dp, 95)),
                "dp_max_pu": float(np.nanmax(dp)),
                "dp_mean_kw": float(np.nanmean(dp)) * p0_kw,
            }
        )
    return pd.DataFrame(rows).set_index("method")


def predictive_summary(study: ZipStudy) -> dict[str, float]:
    """Width of the 95% posterior-predictive band and how often it holds the truth."""
    val = study.validation
    sub = val[val.n_draws_ok >= 0]
    out: dict[str, float] = {"experiments": float(len(sub))}
    for x in ("v", "p"):
        lo, hi = sub[f"{x}_pred_q2.5_pu"], sub[f"{x}_pred_q97.5_pu"]
        t = sub[f"{x}_true_pu"]
        out[f"{x}_width_median_pu"] = float(np.nanmedian(hi - lo))
        out[f"{x}_covers"] = float(((lo <= t) & (t <= hi)).mean())
    return out


def text_tables(study: ZipStudy) -> str:
    """Table II, the coefficients and the sweep as plain text (what the CLI prints)."""
    t2 = study_table2(study)
    cols = [
        "voltage_error_pct",
        "paper_voltage_error_pct",
        "power_error_pct",
        "paper_power_error_pct",
        "a1",
        "a2",
        "a3",
    ]
    st = study.settings
    vs = validation_summary(study).loc[["gs", "ls", "kf"]]
    fmt = {"float_format": lambda x: f"{x:.4g}"}
    need = needed_n(study.sweep)
    return (
        f"ZIP study: n = {st['n_used']} experiments, noise sd {st['noise_sd_pu']:g} p.u., "
        f"seed {st['data_seed']}; validation on {st['n_validation']} fresh experiments\n"
        "Table II (mean |X_est - X_true| / X_true over the validation, %; paper beside)\n"
        + t2[cols].to_string(**fmt)
        + "\n\n|dV| and |dP| at bus 18 (p.u.; paper: about 1e-4 and 1e-3)\n"
        + vs[["dv_median_pu", "dv_max_pu", "dp_median_pu", "dp_max_pu"]].to_string(**fmt)
        + "\n\nSweep: posterior sd of a1 (blocked Gibbs)\n"
        + study.sweep.pivot(index="n", columns="noise", values="a1_sd").to_string(**fmt)
        + "\n\nExperiments needed for sd(a1) = target\n"
        + need.to_string(index=False, float_format=lambda x: f"{x:.3g}")
    )
