"""The ZIP study's matplotlib figures: the paper's Figs. 2, 3, 4, 5, 8, the ridge, the sweep."""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.studies.zip_paper.study import (
    PAPER_MEANS,
    PAPER_TABLE2,
    PAPER_VALIDATION,
    SD_TARGETS,
    TABLE2_ROWS,
    TRUE_ZIP,
    ZipStudy,
)


def figures(study: ZipStudy) -> dict[str, Any]:
    """Matplotlib figures, by file stem.

    ``fig2_posterior``, ``fig3_voltage``, ``fig4_dv_dp``, ``fig5_burn_in``,
    ``fig8_errors``, ``pair_a1_a2``, ``sweep``.
    """
    from loadbayes.plots.fit import pyplot

    plt = pyplot()
    out: dict[str, Any] = {}
    gs, single = study.fits["gs"], study.fits["gs_single"]
    n_used = study.settings["n_used"]

    # Fig. 2: posterior histograms.
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.2), constrained_layout=True)
    paper = {**PAPER_MEANS, "a3": 1 - PAPER_MEANS["a1"] - PAPER_MEANS["a2"]}
    for ax, k, true in zip(axes, ("a1", "a2", "a3"), TRUE_ZIP, strict=True):
        x, y = gs.draws[k].reshape(-1), single.draws[k].reshape(-1)
        bins = np.linspace(min(x.min(), y.min()), max(x.max(), y.max()), 100)
        ax.hist(x, bins=bins, density=True, color="#4c72b0", alpha=0.85, label="GS blocked")
        ax.hist(y, bins=bins, density=True, histtype="step", color="#dd8452", label="single-site")
        ax.axvline(true, color="k", ls="--", lw=1, label="true")
        ax.axvline(paper[k], color="#c44e52", ls=":", lw=1.5, label="paper's mean")
        ax.set_title(f"{k}: mean {x.mean():.3f}, sd {x.std():.3f}", fontsize=9)
        ax.set_yticks([])
    axes[0].legend(fontsize=7)
    fig.suptitle(f"Posterior of the P shares (paper Fig. 2), n = {n_used}", fontsize=10)
    out["fig2_posterior"] = fig

    # Fig. 3: V at bus 18, true vs estimated ZIP, and the posterior-predictive band.
    val = study.validation
    e = val.experiment.to_numpy()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True, constrained_layout=True)
    axes[0].plot(e, val.v_true_pu, "--^", ms=4, color="k", lw=0.8, label="true ZIP")
    axes[0].plot(e, val.v_gs_pu, "-", color="#4c72b0", lw=1.2, label="GS estimate")
    axes[0].set_ylabel("V at bus 18 (p.u.)")
    axes[0].legend(fontsize=7)
    sub = val[val.n_draws_ok >= 0]
    for ax, x, unit in ((axes[1], "v", "dV"), (axes[2], "p", "dP")):
        t = sub[f"{x}_true_pu"]
        ax.fill_between(
            sub.experiment,
            sub[f"{x}_pred_q2.5_pu"] - t,
            sub[f"{x}_pred_q97.5_pu"] - t,
            step="mid",
            color="#4c72b0",
            alpha=0.25,
            label="95% posterior-predictive band",
        )
        for m, c, mk, ms in (
            ("gs", "#4c72b0", "o", 5),
            ("ls", "#55a868", "s", 3),
            ("kf", "#c44e52", "x", 3),
        ):
            ax.plot(e, val[f"d{x}_{m}_pu"], mk, ms=ms, mfc="none", color=c, label=TABLE2_ROWS[m])
        ax.axhline(0, color="k", lw=0.6)
        ax.set_ylabel(f"{unit} = est - true (p.u.)")
        ax.legend(fontsize=7, ncol=4)
    axes[2].set_xlabel("validation experiment")
    fig.suptitle(
        "Bus 18 over the validation experiments (paper Fig. 3), with the predictive band",
        fontsize=10,
    )
    out["fig3_voltage"] = fig

    # Fig. 4: |dV| and |dP| distributions (GS).
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.2), constrained_layout=True)
    for ax, x, ref in ((axes[0], "dv", "dv"), (axes[1], "dp", "dp")):
        d = np.abs(val[f"{x}_gs_pu"].to_numpy(dtype=float))
        d = d[np.isfinite(d) & (d > 0)]
        if d.size:
            bins = np.logspace(np.log10(d.min()) - 0.1, np.log10(d.max()) + 0.1, 30)
            ax.hist(d, bins=bins, color="#4c72b0")
        ax.set_xscale("log")
        ax.axvline(PAPER_VALIDATION[ref], color="#c44e52", ls=":", lw=1.5, label="paper, if p.u.")
        if x == "dp":
            # The paper gives no unit for dP; 1e-3 MW is another reading.
            p0 = float(study.settings["p0_mw"])
            ax.axvline(1e-3 / p0, color="#8172b2", ls="--", lw=1.2, label="paper, if MW")
        ax.set_xlabel(f"|{'dV' if x == 'dv' else 'dP'}| (p.u.)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("experiments")
    fig.suptitle("|dV| and |dP| at bus 18, GS estimate (paper Fig. 4)", fontsize=10)
    out["fig4_dv_dp"] = fig

    # Fig. 5: burn-in, single-site against blocked.
    burn = study.settings["sampler"]["burn"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 5.5), constrained_layout=True)
    for col, scheme in enumerate(("single-site", "blocked")):
        tr = study.traces[scheme]
        for row, stop in enumerate((tr.shape[1], min(2_000, tr.shape[1]))):
            ax = axes[row][col]
            for c in range(tr.shape[0]):
                ax.plot(np.arange(stop), tr[c, :stop], lw=0.4, alpha=0.8)
            ax.axhline(TRUE_ZIP[0], color="k", ls="--", lw=0.8)
            if burn < stop:
                ax.axvline(burn, color="0.4", ls=":", lw=1)
            ax.set_title(
                f"{scheme}: a1, {'all' if row == 0 else 'first'} {stop} iterations", fontsize=9
            )
    axes[1][0].set_xlabel("iteration")
    axes[1][1].set_xlabel("iteration")
    fig.suptitle("Burn-in of a1 from a prior draw (paper Fig. 5); dotted: burn-in end", fontsize=10)
    out["fig5_burn_in"] = fig

    # Fig. 8: error distributions of GS, LS, KF.
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), constrained_layout=True)
    for ax, x, name in ((axes[0], "v", "voltage"), (axes[1], "p", "active power")):
        data, labels = [], []
        for m in TABLE2_ROWS:
            rel = 100 * np.abs(val[f"{x}_{m}_pu"] - val[f"{x}_true_pu"]) / val[f"{x}_true_pu"]
            data.append(rel.dropna().to_numpy())
            labels.append(TABLE2_ROWS[m])
        ax.boxplot(data, showfliers=True, showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels)
        for i, m in enumerate(TABLE2_ROWS, start=1):
            v_p = PAPER_TABLE2[TABLE2_ROWS[m]][0 if x == "v" else 1]
            ax.plot([i - 0.3, i + 0.3], [v_p, v_p], color="#c44e52", lw=1.5)
        ax.set_yscale("log")
        ax.set_ylabel(f"|{name} error| (%)")
    axes[1].plot([], [], color="#c44e52", label="paper's mean")
    axes[1].legend(fontsize=7)
    fig.suptitle("Absolute error distributions of GS, LS and KF (paper Fig. 8)", fontsize=10)
    out["fig8_errors"] = fig

    # The a1-a2 ridge.
    fig, ax = plt.subplots(figsize=(5.5, 4.5), constrained_layout=True)
    a1, a2 = gs.draws["a1"].reshape(-1), gs.draws["a2"].reshape(-1)
    idx = np.linspace(0, a1.size - 1, min(a1.size, 4000)).astype(int)
    ax.plot(a1[idx], a2[idx], ".", ms=1.5, alpha=0.4, color="#4c72b0", label="GS draws")
    s1, s2 = single.draws["a1"].reshape(-1), single.draws["a2"].reshape(-1)
    j = np.linspace(0, s1.size - 1, min(s1.size, 4000)).astype(int)
    ax.plot(s1[j], s2[j], ".", ms=1, alpha=0.25, color="#dd8452", label="single-site draws")
    for m, mk in (("ls", "s"), ("kf", "D")):
        est = study.estimate(m)
        ax.plot(est["a1"], est["a2"], mk, ms=6, mfc="none", color="k", label=TABLE2_ROWS[m])
    ax.plot(a1.mean(), a2.mean(), "o", ms=7, mfc="none", color="#4c72b0", label="GS mean")
    ax.plot(*TRUE_ZIP[:2], "k+", ms=12, mew=2, label="true")
    ax.plot(PAPER_MEANS["a1"], PAPER_MEANS["a2"], "x", color="#c44e52", ms=9, label="paper")
    r = np.corrcoef(a1, a2)[0, 1]
    ax.set_xlabel("a1 (Z share)")
    ax.set_ylabel("a2 (I share)")
    ax.set_title(f"The a1-a2 ridge: posterior correlation {r:+.4f}", fontsize=9)
    ax.legend(fontsize=7)
    out["pair_a1_a2"] = fig

    # The sweep.
    sw = study.sweep
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for ax, k in zip(axes, ("a1", "a2"), strict=True):
        for s, grp in sw.groupby("noise"):
            grp = grp.sort_values("n")
            (line,) = ax.plot(grp.n, grp[f"{k}_sd"], "o", label=f"noise {100 * s:g}% (Gibbs)")
            last = grp.iloc[-1]
            nn = np.logspace(np.log10(grp.n.min()), 9, 50)
            ax.plot(
                nn,
                last[f"{k}_sd_ls"] * np.sqrt(last.n_used / nn),
                "-",
                lw=0.8,
                color=line.get_color(),
            )
        for t in SD_TARGETS:
            ax.axhline(t, color="0.5", ls=":", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("experiments n")
        ax.set_ylabel(f"posterior sd of {k}")
        ax.set_title(f"sd of {k}: points Gibbs, lines LS standard error ~ 1/sqrt(n)", fontsize=9)
    axes[0].legend(fontsize=7)
    fig.suptitle(
        "How much data the paper's precision takes (dotted: sd 0.01 and 0.001)", fontsize=10
    )
    out["sweep"] = fig
    return out
