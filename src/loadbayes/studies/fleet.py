"""The demo's fleet section: a synthetic fleet fitted bus by bus and pooled by class.

A fleet from :func:`loadbayes.fleet.generate.fleet_truth` (three classes with different
ZIP mixes, per-bus scatter, 20 to 20,000 samples per bus, a tenth of the buses with
almost no voltage spread) is written as Parquet files and fitted twice through the same
pipeline as ``loadbayes fit zip DIR --by bus_id``: ``--pool none`` and ``--pool class``.
The section shows each class's estimated mix against the truth, how much each bus was
shrunk towards its class against its number of samples, and the error of a1 on thin and
on data-rich buses for both fits.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["FleetStudy", "html_section", "run"]


@dataclass
class FleetStudy:
    """Tables of the study: truth, per-bus table, pooled table, error summary."""

    truth: pd.DataFrame
    own: pd.DataFrame
    pooled: pd.DataFrame
    errors: pd.DataFrame
    settings: dict[str, Any]


def run(*, quick: bool = True, seed: int = 0, smoke: bool = False) -> FleetStudy:
    """Run the study (quick: 60 buses, about 20 s; full: 300 buses).

    ``smoke``: 20 buses and 300 draws (100 burn-in), a check of the pipeline, not a result.
    """
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fleet.generate import fleet_truth, write_fleet
    from loadbayes.fleet.partitions import ReadSpec
    from loadbayes.fleet.run import fit_fleet, fleet_statistics

    n_buses = 20 if smoke else 60 if quick else 300
    draws, burn = (300, 100) if smoke else (1000, 250) if quick else (2500, 500)
    sampler = SamplerSettings(draws=draws, burn=burn, seed=seed)
    truth = fleet_truth(n_buses, seed=seed)
    with tempfile.TemporaryDirectory() as tmp:
        write_fleet(truth, tmp, buses_per_file=20)
        stats, model, _ = fleet_statistics(tmp, ReadSpec(class_col="customer_class"))
    own = fit_fleet(stats, model, pool="none", sampler=sampler)
    pooled = fit_fleet(stats, model, pool="class", sampler=sampler)
    t = truth.set_index("bus_id")
    rows = []
    for label, table in (("per bus", own), ("pooled", pooled)):
        b = table[(table.level == "bus") & (table.parameter == "a1")].set_index("bus")
        b = b.reindex(t.index)
        err = (b["mean"] - t["a1"]).abs()
        inside = (b.hdi_low <= t["a1"]) & (t["a1"] <= b.hdi_high)
        for group, mask in (
            ("< 200 samples", t["rows"] < 200),
            ("> 5,000 samples", t["rows"] > 5000),
        ):  # noqa: E501
            ok = mask & b["mean"].notna()
            rows.append(
                {
                    "fit": label,
                    "buses": group,
                    "fitted": int(ok.sum()),
                    "of": int(mask.sum()),
                    "a1 median |error|": float(err[ok].median()) if ok.any() else np.nan,
                    "a1 95% HDI coverage": float(inside[ok].mean()) if ok.any() else np.nan,
                }
            )
    return FleetStudy(
        truth,
        own,
        pooled,
        pd.DataFrame(rows),
        {
            "buses": n_buses,
            "seed": seed,
            "chains": sampler.chains,
            "draws": sampler.draws,
            "burn": sampler.burn,
        },  # fmt: skip
    )


def figures(study: FleetStudy) -> list[Any]:
    """Class mixes against the truth, and shrinkage against samples per bus."""
    from loadbayes.fleet.generate import CLASS_MIXES
    from loadbayes.plots.fit import pyplot

    plt = pyplot()
    cls = study.pooled[study.pooled.level == "class"]
    names = sorted(cls["class"].unique())
    fig1, ax = plt.subplots(figsize=(7, 3.2))
    width = 0.25
    for j, par in enumerate(("a1", "a2", "a3")):
        sub = cls[cls.parameter == par].set_index("class").loc[names]
        x = np.arange(len(names)) + (j - 1) * width
        ax.bar(x, sub["mean"], width, label=par, alpha=0.8)
        ax.errorbar(x, sub["mean"], yerr=[sub["mean"] - sub.hdi_low, sub.hdi_high - sub["mean"]],
                    fmt="none", color="k", lw=1)  # fmt: skip
        true = [CLASS_MIXES[n][0] if par == "a1" else CLASS_MIXES[n][1] if par == "a2"
                else 1 - CLASS_MIXES[n][0] - CLASS_MIXES[n][1] for n in names]  # fmt: skip
        ax.scatter(x, true, marker="_", s=300, color="k", zorder=3)
    ax.set_xticks(np.arange(len(names)), names)
    ax.set_ylabel("P share")
    ax.set_title("Class mean mix (bars, 95% HDI) and the truth (black dashes)")
    ax.legend(ncol=3, fontsize=8)
    fig1.tight_layout()
    bus = study.pooled[(study.pooled.level == "bus") & (study.pooled.parameter == "a1")]
    fig2, ax2 = plt.subplots(figsize=(7, 3.2))
    for name in names:
        sub = bus[bus["class"] == name]
        ax2.scatter(sub["n"], sub["shrinkage"], s=12, label=name)
    ax2.set_xscale("log")
    ax2.set_xlabel("samples of the bus")
    ax2.set_ylabel("shrinkage to class mean")
    ax2.set_ylim(-0.05, 1.05)
    ax2.set_title("Thin buses lean on their class; data-rich buses keep their own fit")
    ax2.legend(fontsize=8)
    fig2.tight_layout()
    return [fig1, fig2]


def html_section(study: FleetStudy) -> str:
    """The fleet section of the report (an HTML ``<section>``)."""
    from loadbayes.studies.report import figure_html, table_html

    st = study.settings
    f1, f2 = figures(study)
    cls = study.pooled[study.pooled.level == "class"]
    mix = cls.pivot(index="class", columns="parameter", values="mean")
    failed = study.own[(study.own.level == "bus") & study.own.parameter.isna()]
    parts = [
        '<section id="fleet">',
        "<h2>A fleet of buses: per-bus fits and a model pooled by class</h2>",
        f"<p>{st['buses']} synthetic buses in three classes, 20 to 20,000 samples each, a "
        "tenth with almost no voltage spread; Gibbs "
        f"{st['chains']} chains x {st['draws']} iterations ({st['burn']} burn-in), seed "
        f"{st['seed']}. Per-bus fits could not fit {failed['bus'].nunique()} buses (no "
        "voltage spread); the pooled model fits them from their class.</p>",
        figure_html(f1, "Class mean mix of P from the pooled model."),
        figure_html(f2, "Shrinkage of each bus towards its class mean (pooled model)."),
        table_html(study.errors.set_index(["fit", "buses"]), caption="a1 on thin and rich buses"),
        table_html(mix, caption="Class mean mix (posterior means; a4..a6 are Q)"),
        "</section>",
    ]
    return "\n".join(parts)
