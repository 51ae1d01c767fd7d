"""The fleet report's figures, as :class:`~loadbayes.report.figures.Figure` (PNG bytes).

Each function takes the checked table (:class:`~loadbayes.report.fleet_table.FleetTable`)
and returns a figure, or None when the table has nothing to show. A fleet may have 10^4
buses: scatter plots draw every bus (small markers), interval bars only up to
:data:`MAX_BARS` buses.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from loadbayes.report.figures import Figure, png
from loadbayes.report.fleet_table import FleetTable

__all__ = ["class_mix_figure", "sensitivity_figure", "shrinkage_figure"]

MAX_BARS = 400
SHARES = {"P": ("a1", "a2", "a3"), "Q": ("a4", "a5", "a6")}


def _colours(classes: list[str]) -> dict[str, str]:
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return {c: cmap(i % 10) for i, c in enumerate(classes)}


def class_mix_figure(ft: FleetTable, *, hdi_prob: float = 0.95) -> Figure | None:
    """Each class's ZIP shares: the pooled class means with their intervals.

    Without pooling there are no class estimates; the figure then shows the spread of the
    buses' own means in each class (box: quartiles; whiskers: 5% and 95%).
    """
    from loadbayes.plots.fit import pyplot

    cls_rows = ft.class_rows
    wide = ft.wide()
    have = set(cls_rows["parameter"]) if ft.pooled else set(wide.columns)
    shares = {c: [n for n in names if n in have] for c, names in SHARES.items()}
    chans = [c for c, names in shares.items() if names]
    if not chans:
        return None
    classes = sorted(set(cls_rows["class"]) if ft.pooled else set(ft.bus_rows["class"]))
    colour = _colours(classes)
    plt = pyplot()
    fig, axes = plt.subplots(1, len(chans), figsize=(5.5 * len(chans), 3.8), squeeze=False,
                             layout="constrained")  # fmt: skip
    width = 0.8 / max(len(classes), 1)
    bus_class = ft.bus_rows.groupby("bus", sort=False)["class"].first()
    for ax, ch in zip(axes[0], chans, strict=True):
        names = shares[ch]
        for k, c in enumerate(classes):
            xs = np.arange(len(names)) - 0.4 + width * (k + 0.5)
            if ft.pooled:
                r = cls_rows[cls_rows["class"] == c].set_index("parameter")
                r = r.reindex(list(names))
                m = r["mean"].to_numpy(float)
                err = np.abs(np.vstack([m - r["hdi_low"].to_numpy(float),
                                        r["hdi_high"].to_numpy(float) - m]))  # fmt: skip
                ax.errorbar(xs, m, yerr=err, fmt="o", ms=5, capsize=3, color=colour[c],
                            label=f"{c} ({int(r['n'].max())} buses)")  # fmt: skip
            else:
                buses = bus_class[bus_class == c].index
                sub = wide.reindex(buses)[list(names)].dropna()
                if not len(sub):
                    continue
                ax.boxplot([sub[n].to_numpy() for n in names], positions=xs, widths=width * 0.8,
                           whis=(5, 95), showfliers=False, patch_artist=True,
                           boxprops={"facecolor": colour[c], "alpha": 0.6},
                           medianprops={"color": "black"})  # fmt: skip
                ax.plot([], [], "s", color=colour[c], label=f"{c} ({len(sub)} buses)")
        kind = dict(zip(SHARES[ch], ("Z", "I", "P"), strict=True))
        ax.set_xticks(np.arange(len(names)), [f"{n} ({kind[n]})" for n in names])
        ax.axhline(0.0, color="0.7", lw=0.8)
        ax.set_ylabel(f"share of {ch}0 (per unit)")
        ax.set_title(f"{ch}: class mixes", fontsize=10)
        ax.legend(fontsize=7, loc="best")
    if ft.pooled:
        cap = (f"The pooled class means of the ZIP shares (dots) with their {hdi_prob:.0%} "
               "intervals (bars), one colour a class; a bus's shares add up to 1.")  # fmt: skip
        alt = "Class mean ZIP shares with interval bars, one colour per class."
    else:
        cap = ("No pooling in this run, so no class estimate: the boxes show how the buses' "
               "own posterior means spread within each class (quartiles; whiskers at 5% and "
               "95%). Fit with --pool class for class means with intervals.")  # fmt: skip
        alt = "Box plots of the per-bus mean ZIP shares by class."
    return Figure("Class mixes", png(fig), cap, alt)


def shrinkage_figure(ft: FleetTable, unpooled: pd.DataFrame | None, source: str) -> Figure | None:
    """Pooled against unpooled bus means (when known), and the shrinkage by class."""
    from loadbayes.plots.fit import pyplot

    has_s = "shrinkage" in ft.table.columns and ft.bus_rows["shrinkage"].notna().any()
    pooled = ft.wide()
    params = [p for p in ("a1", "a4") if p in pooled.columns]
    pairs = bool(ft.pooled and unpooled is not None and params)
    if not pairs and not has_s:
        return None
    panels = (len(params) if pairs else 0) + (1 if has_s else 0)
    plt = pyplot()
    fig, axes = plt.subplots(1, panels, figsize=(4.2 * panels, 3.9), squeeze=False,
                             layout="constrained")  # fmt: skip
    bus_class = ft.bus_rows.groupby("bus", sort=False)["class"].first()
    classes = sorted(set(bus_class))
    colour = _colours(classes)
    k = 0
    if pairs:
        cls_mean = ft.class_rows.pivot_table(index="class", columns="parameter", values="mean")
        for p in params:
            ax = axes[0, k]
            k += 1
            both = pd.DataFrame({"own": unpooled.get(p), "pooled": pooled[p]}).dropna()
            for c in classes:
                sub = both[bus_class.reindex(both.index).to_numpy() == c]
                ax.scatter(sub["own"], sub["pooled"], s=10, color=colour[c], alpha=0.8, label=c)
                if c in cls_mean.index and p in cls_mean.columns:
                    ax.axhline(cls_mean.loc[c, p], color=colour[c], lw=1, ls="--")
            lo = float(np.nanmin(both.to_numpy())) if len(both) else 0.0
            hi = float(np.nanmax(both.to_numpy())) if len(both) else 1.0
            ax.plot([lo, hi], [lo, hi], color="0.5", lw=0.8)
            ax.set_xlabel(f"{p}: bus's own estimate (no pooling)")
            ax.set_ylabel(f"{p}: pooled estimate")
            ax.set_title(f"{p}: pooled against own", fontsize=10)
            ax.legend(fontsize=7, loc="best")
    if has_s:
        ax = axes[0, k]
        s = ft.bus_rows.dropna(subset=["parameter"]).groupby("bus", sort=False)["shrinkage"]
        s = s.first()
        data = [s[bus_class.reindex(s.index).to_numpy() == c].dropna().to_numpy() for c in classes]
        gen = np.random.default_rng(0)  # jitter only: fixed, so the page is reproducible
        for i, (c, v) in enumerate(zip(classes, data, strict=True)):
            ax.scatter(i + gen.uniform(-0.2, 0.2, v.size), v, s=8, color=colour[c], alpha=0.7)
            if v.size:
                ax.plot([i - 0.3, i + 0.3], [np.median(v)] * 2, color="black", lw=1.5)
        ax.set_xticks(np.arange(len(classes)), classes, rotation=20)
        ax.set_ylim(-0.05, 1.05)
        ax.set_ylabel("shrinkage (0 = own data, 1 = class mean)")
        ax.set_title("Shrinkage by class", fontsize=10)
    parts = []
    if pairs:
        parts.append(
            f"Left: each bus's pooled posterior mean against its own estimate without pooling "
            f"(from {source}); the grey line is 'no change', the dashed lines the class means. "
            "Points pulled from the line towards their class's dashed line are shrunk."
        )
    if has_s:
        parts.append(
            "Shrinkage of each bus (dots, one column a class; black bar: the median): 0 where "
            "the bus stays where its own data put it, 1 where it sits on its class mean (and "
            "for a bus whose own data cannot identify its shares)."
        )
    return Figure("Shrinkage", png(fig), " ".join(parts),
                  "Shrinkage of the bus estimates towards their class means.")  # fmt: skip


def sensitivity_figure(
    ft: FleetTable,
    sens: dict[str, pd.DataFrame],
    units: dict[str, str],
    coords: pd.DataFrame | None,
    axis_names: tuple[str, str],
    flagged: set[str],
) -> Figure | None:
    """dP/dV and dQ/dV per bus: a map when coordinates exist, else sorted values."""
    from loadbayes.plots.fit import pyplot

    chans = [k for k in ("dp_dv", "dq_dv") if sens.get(k) is not None and len(sens[k])]
    if not chans:
        return None
    label = {"dp_dv": "dP/dV", "dq_dv": "dQ/dV"}
    plt = pyplot()
    fig, axes = plt.subplots(1, len(chans), figsize=(5.5 * len(chans), 4.4), squeeze=False,
                             layout="constrained")  # fmt: skip
    bus_class = ft.bus_rows.groupby("bus", sort=False)["class"].first()
    classes = sorted(set(bus_class))
    colour = _colours(classes)
    for ax, k in zip(axes[0], chans, strict=True):
        s = sens[k].copy()
        s.index = s.index.astype(str)
        if coords is not None:
            at = s.join(coords, how="inner")
            sc = ax.scatter(at["x"], at["y"], c=at["mean"], cmap="viridis", s=28,
                            edgecolors="none")  # fmt: skip
            bad = at[at.index.isin(flagged)]
            ax.scatter(bad["x"], bad["y"], s=70, facecolors="none", edgecolors="red", lw=1)
            fig.colorbar(sc, ax=ax, label=f"{label[k]} ({units[k]})")
            ax.set_xlabel(axis_names[0])
            ax.set_ylabel(axis_names[1])
            if axis_names[1].lower().startswith("lat") and len(at):
                ax.set_aspect(
                    1.0 / max(np.cos(np.deg2rad(float(at["y"].mean()))), 0.1),
                    adjustable="datalim",
                )
            ax.set_title(f"{label[k]} at V0, per bus", fontsize=10)
        else:
            s = s.sort_values("mean")
            pos = np.arange(len(s))
            cls = bus_class.reindex(s.index).to_numpy()
            if len(s) <= MAX_BARS and s["hdi_low"].notna().any():
                err = np.abs(np.vstack([s["mean"] - s["hdi_low"], s["hdi_high"] - s["mean"]]))
                ax.errorbar(pos, s["mean"], yerr=err, fmt="none", ecolor="0.6", lw=0.8)
            for c in classes:
                m = cls == c
                ax.scatter(pos[m], s["mean"].to_numpy()[m], s=10, color=colour[c], label=c)
            bad = np.isin(s.index, list(flagged))
            ax.scatter(pos[bad], s["mean"].to_numpy()[bad], s=50, facecolors="none",
                       edgecolors="red", lw=1)  # fmt: skip
            ax.set_xlabel("buses, sorted by the value")
            ax.set_ylabel(f"{label[k]} at V0\n({units[k]})")
            ax.set_title(f"{label[k]} per bus", fontsize=10)
            ax.legend(fontsize=7, loc="best")
    what = "; ".join(f"{label[k]} in {units[k]}" for k in chans)
    bars = len(s) <= MAX_BARS and s["hdi_low"].notna().any()
    if coords is not None:
        cap = (f"The slope of each bus's P (and Q) against V at V0 ({what}), placed at the "
               f"bus's coordinates ({', '.join(axis_names)}); red rings: flagged buses (see "
               "the table above).")  # fmt: skip
        alt = "Map of the buses coloured by their voltage sensitivity."
    else:
        cap = (f"The slope of each bus's P (and Q) against V at V0 ({what}), buses sorted "
               "by the value, one colour a class"
               + (f"; grey bars: the {len(s):,} buses' intervals" if bars else "")
               + "; red rings: flagged buses. There are no coordinates, so no map.")  # fmt: skip
        alt = "Sorted per-bus voltage sensitivities, one colour per class."
    return Figure("Voltage sensitivity", png(fig), cap, alt)
