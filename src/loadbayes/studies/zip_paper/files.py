"""The ZIP study's files: what :func:`write` puts under ``OUT/zip/`` and in the report."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.studies.report import png_bytes, refuse_existing, write_bytes, write_text
from loadbayes.studies.zip_paper.charts import figures
from loadbayes.studies.zip_paper.html import html_section
from loadbayes.studies.zip_paper.study import (
    _MARK,
    METHODS,
    PAPER_MEANS,
    PAPER_TABLE2,
    PAPER_VALIDATION,
    ZipStudy,
)
from loadbayes.studies.zip_paper.tables import (
    comparison,
    needed_n,
    predictive_summary,
    sampler_table,
    study_table2,
)

FIGURES = (
    "fig2_posterior",
    "fig3_voltage",
    "fig4_dv_dp",
    "fig5_burn_in",
    "fig8_errors",
    "pair_a1_a2",
    "sweep",
)
TABLES = ("table2.csv", "comparison.csv", "validation.csv", "sweep.csv", "sampler.csv")


def output_paths(root: str | Path) -> list[Path]:
    """Files :func:`write` creates under ``root/zip`` (``report.html`` aside)."""
    d = Path(root) / "zip"
    names = ["experiments.csv", "summary.json", "posterior.nc", "study.json", *TABLES]
    names += [f"{f}.png" for f in FIGURES]
    names.append("section.html")
    return [d / n for n in names]


def marked(section: str, mark: str = _MARK) -> str:
    """``section`` between the begin and end markers of ``mark``."""
    from loadbayes.studies.report import marked as _marked

    return _marked(section, mark)


def update_report(path: str | Path, section: str, *, mark: str = _MARK) -> Path:
    """Put ``section`` into the report between the markers of ``mark`` (``update_section``)."""
    from loadbayes.studies.report import update_section

    return update_section(path, section, mark=mark)


def _experiments_csv(study: ZipStudy) -> str:
    d = study.data
    out = pd.DataFrame(
        {
            "experiment": d.experiment,
            "v_pu": d.v_pu,
            "p_true_pu": d.p_true_pu,
            "q_true_pu": d.q_true_pu,
            "p_meas_pu": d.p_meas_pu,
            "q_meas_pu": d.q_meas_pu,
            "converged": d.converged,
            # The load factors of row i are ieee33.draw_factors(N, seed=factor_seed)[i].
            "factor_seed": int(study.settings["data_seed"]),
        }
    )
    return out.to_csv(index=False, float_format="%.17g")


def write(study: ZipStudy, root: str | Path, *, force: bool = False) -> list[Path]:
    """Write ``root/zip/`` (data, summary.json, posterior.nc, tables, figures) and the section.

    Returns
    -------
    list of Path
        Every file written, ``root/report.html`` last.
    """
    root = Path(root)
    d = root / "zip"
    d.mkdir(parents=True, exist_ok=True)
    if not force:
        refuse_existing(output_paths(root))
    written: list[Path] = []
    path = d / "experiments.csv"
    write_text(path, _experiments_csv(study), force)
    written.append(path)
    written.append(study.fits["gs"].to_json(d / "summary.json", force=force))
    # Every draw (the study compares them); no pointwise groups, which would thin them.
    written.append(study.fits["gs"].to_netcdf(d / "posterior.nc", force=force, pointwise=False))
    info = {
        "settings": study.settings,
        "timings_s": study.timings,
        "paper": {
            "means": PAPER_MEANS,
            "table2": PAPER_TABLE2,
            "validation": PAPER_VALIDATION,
        },
        "methods": METHODS,
        "estimates": {m: study.estimate(m) for m in METHODS},
        "needed_n": needed_n(study.sweep).to_dict(orient="records"),
        "predictive": predictive_summary(study),
        "error_definition": (
            "voltage_error_pct = 100 * mean_i |V_est,i - V_true,i| / V_true,i over the "
            "validation experiments; power_error_pct likewise with P at bus 18"
        ),
    }
    path = d / "study.json"
    write_text(path, json.dumps(info, indent=2, allow_nan=False, default=_json) + "\n", force)
    written.append(path)
    tables = {
        "table2.csv": study_table2(study).reset_index(),
        "comparison.csv": comparison(study).reset_index(),
        "validation.csv": study.validation,
        "sweep.csv": study.sweep,
        "sampler.csv": sampler_table(study),
    }
    for name, df in tables.items():
        write_text(d / name, df.to_csv(index=False), force)
        written.append(d / name)
    pngs = {k: png_bytes(f) for k, f in figures(study).items()}
    for name, data in pngs.items():
        write_bytes(d / f"{name}.png", data, force)
        written.append(d / f"{name}.png")
    section = html_section(study, pngs)
    write_text(d / "section.html", section + "\n", force)
    written.append(d / "section.html")
    written.append(update_report(root / "report.html", section))
    return written


def _json(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
