"""Figures of a fit: marginals, the pair plot that shows a ridge, traces, and P(V) bands.

matplotlib is imported lazily and always with the non-interactive Agg backend, so the
CLI works on machines with no display.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from loadbayes.posterior import Posterior

__all__ = ["pyplot", "plot_fit", "save_figure"]


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


def plot_fit(
    post: Posterior,
    *,
    model: Any = None,
    params: Sequence[str] | None = None,
    hdi_prob: float = 0.95,
) -> Any:
    """One figure summarising a fit.

    Top row: the marginal posterior of each free coefficient. Bottom row: the pair plot
    of the first two (the ZIP a1-a2 ridge), the trace of the first one per chain, and,
    when ``model`` can predict and observed data are kept, the data with the posterior
    P(V) curve and its band.
    """
    plt = pyplot()
    params = list(params or getattr(post, "free", None) or post.coefficients)
    params = [p for p in params if p in post.draws][:4]
    ncol = max(len(params), 3)
    fig, axes = plt.subplots(2, ncol, figsize=(3.2 * ncol, 6.0), squeeze=False)
    for ax, name in zip(axes[0], params, strict=False):
        x = post.draws[name].reshape(-1)
        ax.hist(x, bins=60, density=True, color="#4c72b0", alpha=0.8)
        ax.axvline(float(x.mean()), color="k", lw=1)
        ax.set_title(name)
    for ax in axes[0][len(params) :]:
        ax.axis("off")
    bottom = axes[1]
    if len(params) >= 2:
        a, b = post.draws[params[0]].reshape(-1), post.draws[params[1]].reshape(-1)
        idx = np.linspace(0, a.size - 1, min(a.size, 4000)).astype(int)
        bottom[0].plot(a[idx], b[idx], ".", ms=1.5, alpha=0.4)
        r = np.corrcoef(a, b)[0, 1]
        bottom[0].set_xlabel(params[0])
        bottom[0].set_ylabel(params[1])
        bottom[0].set_title(f"joint draws, corr {r:+.3f}")
    else:
        bottom[0].axis("off")
    if params:
        for c in range(post.n_chains):
            bottom[1].plot(post.draws[params[0]][c], lw=0.3, alpha=0.7)
        bottom[1].set_title(f"trace of {params[0]}")
        bottom[1].set_xlabel("draw (after burn-in)")
    obs = post.observed
    if model is not None and hasattr(model, "predict") and "v" in obs and "p" in obs:
        v = obs["v"]
        grid = np.linspace(v.min(), v.max(), 100)
        pred = model.predict(post.draws, grid, hdi_prob=hdi_prob, rng=0)
        idx = np.linspace(0, v.size - 1, min(v.size, 3000)).astype(int)
        ax = bottom[2]
        ax.plot(v[idx], obs["p"][idx], ".", ms=2, color="0.6", label="measured P")
        ax.fill_between(
            grid, pred["p_low"], pred["p_high"], alpha=0.35, label=f"{hdi_prob:.0%} band"
        )
        ax.plot(grid, pred["p_mean"], "k-", lw=1, label="posterior mean")
        ax.set_xlabel("V")
        ax.set_ylabel("P")
        ax.legend(fontsize=7)
        ax.set_title("P(V)")
    else:
        bottom[2].axis("off")
    for ax in bottom[3:]:
        ax.axis("off")
    fig.suptitle(f"{post.model} — {post.method}", fontsize=10)
    fig.tight_layout()
    return fig
