"""The motor study's files: what :func:`write` puts under ``OUT/im/`` and in the report."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from loadbayes.studies.im_paper.charts import figures
from loadbayes.studies.im_paper.html import html_section
from loadbayes.studies.im_paper.study import (
    _MARK,
    METHODS,
    PAPER_TABLE1,
    PAPER_TABLE3,
    ImStudy,
)
from loadbayes.studies.im_paper.tables import physical_table, table1, table3
from loadbayes.studies.report import png_bytes, refuse_existing, write_bytes, write_text


def output_paths(root: str | Path, motors: Sequence[str]) -> list[Path]:
    """Files :func:`write` creates under ``root/im`` (``report.html`` aside)."""
    d = Path(root) / "im"
    out = []
    for m in motors:
        out += [d / f"data_{m}.csv", d / f"data_{m}.json"]
    out += [d / n for n in ("summary.json", "table1.csv", "table3.csv", "physical.csv")]
    out += [d / n for n in ("eiv.csv", "fig6_coefficients.png", "physical.png", "eiv.png")]
    out.append(d / "section.html")
    return out


def update_report(path: str | Path, section: str) -> Path:
    """Put ``section`` into the report between the IM markers (see ``update_section``)."""
    from loadbayes.studies.report import update_section

    return update_section(path, section, mark=_MARK)


def write(study: ImStudy, root: str | Path, *, force: bool = False) -> list[Path]:
    """Write ``root/im/`` (data, summary.json, tables, figures) and the report section.

    Returns
    -------
    list of Path
        Every file written.
    """
    from loadbayes.cases.motor_sim import write_csv

    root = Path(root)
    d = root / "im"
    d.mkdir(parents=True, exist_ok=True)
    if not force:
        refuse_existing(output_paths(root, list(study.runs)))
    written: list[Path] = []
    for name, run_ in study.runs.items():
        written += list(write_csv(run_.data, d / f"data_{name}.csv"))
    summary = {
        "study": study.settings,
        "paper": {"table1": PAPER_TABLE1, "table3": PAPER_TABLE3},
        "motors": {
            name: {
                "params": run_.params.to_dict(),
                "true": run_.truth,
                "fits": {m: run_.fits[m].to_dict(hdi_prob=0.95) for m in METHODS},
            }
            for name, run_ in study.runs.items()
        },
    }
    path = d / "summary.json"
    write_text(path, json.dumps(summary, indent=2, allow_nan=False, default=float) + "\n", force)
    written.append(path)
    for fname, df in (
        ("table1.csv", table1(study)),
        ("table3.csv", table3(study)),
        ("physical.csv", physical_table(study)),
        ("eiv.csv", study.eiv),
    ):
        write_text(d / fname, df.to_csv(index=False), force)
        written.append(d / fname)
    pngs = {k: png_bytes(f) for k, f in figures(study).items()}
    for name, data in pngs.items():
        write_bytes(d / f"{name}.png", data, force)
        written.append(d / f"{name}.png")
    section = html_section(study, pngs)
    write_text(d / "section.html", section + "\n", force)
    written.append(d / "section.html")
    written.append(update_report(root / "report.html", section))
    return written
