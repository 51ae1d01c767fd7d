"""Figures of a fit: load curves with their bands, marginals, pair plots, traces.

Each ``draw_*`` function draws one panel on an axis given to it, so that ``--plot``
(:func:`plot_fit`, one figure) and the HTML report (:mod:`loadbayes.report.figures`, one
figure per subject) show the same pictures. Every axis carries its unit; P(V) and Q(V)
are in the data's units (the bases undone) with the data behind the curve, the band of
the curve itself and the wider band of a new measurement.

matplotlib is imported lazily and always with the non-interactive Agg backend, so the
CLI works on machines with no display.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from loadbayes.posterior import Posterior
from loadbayes.predictive import curves, data_units, model_of, param_unit

__all__ = [
    "correlated_pairs",
    "draw_curve",
    "draw_marginal",
    "draw_pair",
    "draw_trace",
    "plot_fit",
    "pyplot",
    "save_figure",
]

#: Colours: data grey, curve and bands blue, chains from a qualitative map.
DATA, CURVE, BAND = "0.55", "#1f4e8c", "#4c72b0"


def pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, path: str | Path, *, force: bool = False, dpi: int = 110) -> Path:
    """Save a figure atomically (PNG, SVG or PDF by extension) and close it."""
    from loadbayes.io.atomic import atomic_write

    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_write(path, force=force) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi, bbox_inches="tight")
    pyplot().close(fig)
    return path


def _ticks(ax: Any) -> None:
    """At most 4 ticks a side, no offset notation: labels that never overlap."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(4))
    ax.yaxis.set_major_locator(MaxNLocator(5))
    ax.ticklabel_format(axis="both", style="plain", useOffset=False)


def label(name: str, post: Posterior) -> str:
    """Axis label of a parameter: its name and unit."""
    if post.model == "composite":  # the composite's units live with its names
        from loadbayes.report.composite_names import describe

        unit = describe(name)[0]
        if unit:
            return f"{name} [{unit}]"
    return f"{name} [{param_unit(name, post)}]"


# ----------------------------------------------------------------- panels
def draw_marginal(
    ax: Any, post: Posterior, name: str, *, hdi_prob: float = 0.95, truth: float | None = None
) -> None:
    """Histogram of one parameter with its mean, its HDI and, if given, the true value."""
    x = post.draws[name].reshape(-1)
    x = x[np.isfinite(x)]
    ax.hist(x, bins=50, density=True, color=BAND, alpha=0.75)
    if x.size:
        lo, hi = _hdi(x, hdi_prob)
        ax.axvspan(lo, hi, color=BAND, alpha=0.12, lw=0)
        ax.axvline(float(x.mean()), color="k", lw=1.2)
    if truth is not None:
        ax.axvline(truth, color="#c0392b", lw=1.5, ls="--")
    ax.set_xlabel(label(name, post), fontsize=9)
    ax.set_ylabel("density", fontsize=9)
    _ticks(ax)


def draw_pair(ax: Any, post: Posterior, a: str, b: str, *, max_points: int = 3000) -> None:
    """Joint draws of two parameters (thinned evenly), with their correlation."""
    x, y = post.draws[a].reshape(-1), post.draws[b].reshape(-1)
    idx = np.linspace(0, x.size - 1, min(x.size, max_points)).astype(int)
    ax.plot(x[idx], y[idx], ".", ms=2, alpha=0.35, color=BAND, rasterized=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = float(np.corrcoef(x, y)[0, 1])
    ax.set_xlabel(label(a, post), fontsize=9)
    ax.set_ylabel(label(b, post), fontsize=9)
    ax.set_title(f"{a} vs {b}: correlation {r:+.3f}", fontsize=9)
    _ticks(ax)


def draw_trace(ax: Any, post: Posterior, name: str, *, max_points: int = 400) -> int:
    """Thinned trace of one parameter, one line per chain; returns the thinning step."""
    n = post.n_draws
    step = max(1, int(np.ceil(n / max_points)))
    it = np.arange(0, n, step)
    for c in range(post.n_chains):
        ax.plot(it, post.draws[name][c, ::step], lw=0.8, alpha=0.8, label=f"chain {c + 1}")
    ax.set_xlabel(f"kept draw (every {step}th shown)" if step > 1 else "kept draw", fontsize=9)
    ax.set_ylabel(label(name, post), fontsize=9)
    _ticks(ax)
    return step


def draw_curve(
    ax: Any,
    post: Posterior,
    channel: str = "p",
    *,
    hdi_prob: float = 0.95,
    max_points: int = 4000,
    max_draws: int = 1000,
) -> bool:
    """P(V) or Q(V) in the data's units: data, the curve's band and a new measurement's.

    Returns False (and draws nothing) when the fit has no such curve or kept no data.
    """
    model = model_of(post)
    obs = post.observed
    if model is None or "v" not in obs or channel not in obs or f"tau_{channel}" not in post.draws:
        return False
    st = post.settings
    vb, sb = float(st.get("v_base") or 1.0), float(st.get("s_base") or 1.0)
    v, y = np.asarray(obs["v"]), np.asarray(obs[channel])
    grid = np.linspace(v.min(), v.max(), 120)
    n = post.n_chains * post.n_draws
    pick = np.linspace(0, n - 1, min(n, max_draws)).astype(int)
    flat = {k: a.reshape(-1)[pick] for k, a in post.draws.items()}
    extra = {"f": np.full(grid.size, model.f0)} if getattr(model, "with_f", False) else {}
    mean, sd = curves(model, flat, {"v": grid, **extra})
    m, s = mean[channel], sd[channel][:, None]
    rng = np.random.default_rng(0)
    if getattr(model, "noise", "additive") == "multiplicative":
        new = m * np.exp(s * rng.standard_normal(m.shape))
    else:
        new = m + s * rng.standard_normal(m.shape)
    q = ((1 - hdi_prob) / 2, 1 - (1 - hdi_prob) / 2)
    lo, hi = np.quantile(m, q, axis=0)
    nlo, nhi = np.quantile(new, q, axis=0)
    idx = np.linspace(0, v.size - 1, min(v.size, max_points)).astype(int)
    ax.plot(v[idx] * vb, y[idx] * sb, ".", ms=2.5, color=DATA, alpha=0.6, zorder=1,
            label="measured", rasterized=True)  # fmt: skip
    ax.fill_between(grid * vb, nlo * sb, nhi * sb, color=BAND, alpha=0.18, lw=0, zorder=2,
                    label=f"{hdi_prob:.0%} band of a new measurement")  # fmt: skip
    ax.fill_between(grid * vb, lo * sb, hi * sb, color=BAND, alpha=0.55, lw=0, zorder=3,
                    label=f"{hdi_prob:.0%} band of the curve")  # fmt: skip
    ax.plot(grid * vb, m.mean(axis=0) * sb, color=CURVE, lw=1.4, zorder=4, label="posterior mean")
    units = data_units(post)
    ax.set_xlabel(f"V [{units['v']}]", fontsize=9)
    ax.set_ylabel(f"{channel.upper()} [{units[channel]}]", fontsize=9)
    ax.legend(fontsize=7, loc="best", framealpha=0.85)
    _ticks(ax)
    return True


def correlated_pairs(post: Posterior, k: int = 3) -> list[tuple[str, str, float]]:
    """The ``k`` pairs of free coefficients with the largest |posterior correlation|."""
    names = [n for n in post.free if n in post.draws]
    if len(names) < 2:
        return []
    c = post.correlation(names).to_numpy()
    pairs = [
        (names[i], names[j], float(c[i, j]))
        for i in range(len(names))
        for j in range(i + 1, len(names))
        if np.isfinite(c[i, j])
    ]
    return sorted(pairs, key=lambda t: -abs(t[2]))[:k]


def _hdi(x: np.ndarray, prob: float) -> tuple[float, float]:
    s = np.sort(x)
    k = max(1, int(np.floor(prob * s.size)))
    if k >= s.size:
        return float(s[0]), float(s[-1])
    widths = s[k:] - s[: s.size - k]
    i = int(np.argmin(widths))
    return float(s[i]), float(s[i + k])


# ----------------------------------------------------------------- figure
def plot_fit(
    post: Posterior,
    *,
    model: Any = None,
    params: Sequence[str] | None = None,
    hdi_prob: float = 0.95,
) -> Any:
    """One figure summarising a fit (``--plot``).

    Rows of four panels: the marginal of every coefficient (derived ones such as a3 and
    a6 included), then P(V) and Q(V) with their bands when the model has them, then the
    pair plot of the two most correlated free coefficients and the thinned trace of the
    first coefficient. ``model`` is accepted for compatibility; the curves are rebuilt
    from the fit's settings.
    """
    plt = pyplot()
    params = [p for p in (params or post.coefficients) if p in post.draws]
    ncol = 4
    rows_m = max(1, int(np.ceil(len(params) / ncol)))
    chans = [c for c in ("p", "q") if c in post.observed and f"tau_{c}" in post.draws]
    has_curve = model_of(post) is not None and "v" in post.observed and bool(chans)
    nrows = rows_m + 1 + (1 if has_curve else 0)
    fig = plt.figure(figsize=(13.0, 2.9 * nrows), layout="constrained")
    gs = fig.add_gridspec(nrows, ncol)
    for i, name in enumerate(params):
        draw_marginal(fig.add_subplot(gs[i // ncol, i % ncol]), post, name, hdi_prob=hdi_prob)
    row = rows_m
    if has_curve:
        for j, ch in enumerate(chans):
            draw_curve(fig.add_subplot(gs[row, 2 * j : 2 * j + 2]), post, ch, hdi_prob=hdi_prob)
        row += 1
    pairs = correlated_pairs(post, 1)
    if pairs:
        draw_pair(fig.add_subplot(gs[row, 0:2]), post, pairs[0][0], pairs[0][1])
    if params:
        ax = fig.add_subplot(gs[row, 2:4])
        draw_trace(ax, post, params[0])
        ax.set_title(f"trace of {params[0]}, one line per chain", fontsize=9)
    fig.suptitle(
        f"{post.model} fit ({post.method}), n = {post.settings.get('n', '?')}: black line = "
        f"posterior mean, shaded = {hdi_prob:.0%} HDI",
        fontsize=10,
    )
    return fig
