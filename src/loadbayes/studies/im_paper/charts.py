"""The motor study's matplotlib figures: Fig. 6, the physical parameters, errors in variables."""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.models.motor import COEFFICIENT_NAMES
from loadbayes.studies.im_paper.study import (
    PHYSICAL,
    ImStudy,
    _err,
)
from loadbayes.studies.im_paper.tables import physical_table


def figures(study: ImStudy) -> dict[str, Any]:
    """Matplotlib figures: ``fig6_coefficients``, ``physical``, and ``eiv``."""
    from loadbayes.plots.fit import pyplot

    plt = pyplot()
    out = {}
    runs = list(study.runs.values())
    fig, axes = plt.subplots(
        len(runs), 5, figsize=(15, 2.4 * len(runs)), squeeze=False, constrained_layout=True
    )
    for r, run_ in enumerate(runs):
        truth = run_.truth
        for c, k in enumerate(COEFFICIENT_NAMES):
            ax = axes[r][c]
            gs = run_.fits["gs"].draws[k].reshape(-1)
            ms = run_.fits["gs_measured"].draws[k].reshape(-1)
            lo = min(gs.min(), ms.min(), truth[k])
            hi = max(gs.max(), ms.max(), truth[k])
            bins = np.linspace(lo, hi, 120) if hi > lo else 10
            # One filled outline per histogram, not a bar per bin (the same picture: the
            # bars have no edges; 40 x 120 bars took 9 CPU s of the figure's 10).
            ax.hist(gs, bins=bins, density=True, histtype="stepfilled", color="#4c72b0",
                    label="GS, modelled currents")  # fmt: skip
            ax.hist(ms, bins=bins, density=True, histtype="stepfilled", color="#dd8452",
                    alpha=0.6, label="GS, paper's form")  # fmt: skip
            ax.axvline(truth[k], color="k", lw=1, ls="--", label="true")
            ax.set_yticks([])
            ax.tick_params(labelsize=7)
            ax.xaxis.set_major_locator(plt.MaxNLocator(4))
            ax.set_title(f"{run_.name}: {k}", fontsize=8)
    axes[0][0].legend(fontsize=6, loc="upper left")
    fig.suptitle("Posterior of the five coefficients (paper Fig. 6)", fontsize=10)
    out["fig6_coefficients"] = fig

    phys = physical_table(study)
    fig, axes = plt.subplots(3, 3, figsize=(12, 1.2 + 0.45 * len(runs) * 3), squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, k in zip(axes.flat, PHYSICAL, strict=True):
        sub = phys[phys.parameter == k].reset_index(drop=True)
        for i, row in sub.iterrows():
            ref = row["reference"]
            lo = _err(row["hdi_low"], ref)
            hi = _err(row["hdi_high"], ref)
            mid = row["err_pct"]
            err = [[abs(mid - min(lo, hi))], [abs(max(lo, hi) - mid)]]
            ax.errorbar(mid, -i, xerr=err, fmt="o", ms=4, capsize=3, color=colors[i % 10])
        ax.axvline(0, color="k", lw=0.8)
        ax.set_yticks(-np.arange(len(sub)))
        ax.set_yticklabels(sub.motor, fontsize=7)
        ax.set_ylim(-len(sub) + 0.5, 0.5)
        ax.tick_params(axis="x", labelsize=7)
        ax.xaxis.set_major_locator(plt.MaxNLocator(4))
        what = "identified" if sub.identified.all() else "closure Xs = Xr"
        ax.set_title(f"{k} ({what})", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("error vs reference (%)", fontsize=7)
    fig.suptitle(
        "Physical parameters: posterior mean and 95% HDI (GS, modelled currents)", fontsize=10
    )
    fig.tight_layout()
    out["physical"] = fig

    if not study.eiv.empty:
        fig, ax = plt.subplots(figsize=(8, 3.2))
        width = 0.8 / len(study.eiv)
        x = np.arange(len(COEFFICIENT_NAMES))
        for j, (_, row) in enumerate(study.eiv.iterrows()):
            vals = [row[f"{k}_err_pct"] for k in COEFFICIENT_NAMES]
            ax.bar(
                x + j * width, vals, width, label=f"{row['currents']}, noise on {row['noise_on']}"
            )
        ax.set_xticks(x + 0.4 - width / 2)
        ax.set_xticklabels(COEFFICIENT_NAMES)
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel("error of the posterior mean (%)")
        ax.set_title(f"Errors in variables ({study.eiv.motor.iloc[0]})", fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        out["eiv"] = fig
    return out
