"""The figures of a CVR fit: daily energy against voltage, and the on/off days in pairs."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plot_cvr"]


def plot_cvr(result: dict[str, Any]) -> Any:
    """Two panels from :func:`loadbayes.fit.cvr.fit_cvr`'s result (with its ``draws``).

    Left: each day's energy with the calendar, weather and drifting level taken out (at
    the posterior mean), against the day's mean voltage, on and off days apart, with the
    energy factor's line. Right: the daily energy in time, on days filled and off days
    open, each on/off pair of neighbouring days joined.
    """
    from loadbayes.plots.fit import pyplot

    plt = pyplot()
    days = result["draws"]["days"]
    adj = result["draws"].get("adjusted_log_energy")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    on = days.on.astype(bool)
    lv = np.log(days.v)
    if adj is not None:
        rel = 100 * (np.exp(adj - adj[~on].mean()) - 1)
        vrel = 100 * (np.exp(lv - lv[~on].mean()) - 1)
        ax1.plot(vrel[~on], rel[~on], "o", mfc="none", color="C0", label="reduction off")
        ax1.plot(vrel[on], rel[on], "o", color="C3", label="reduction on")
        e = result["energy"]["p"]
        xs = np.linspace(vrel.min(), vrel.max(), 2)
        ax1.plot(xs, e["mean"] * xs, "k-",
                 label=f"energy CVR {e['mean']:.2f} [{e['low']:.2f}, {e['high']:.2f}]")  # fmt: skip
        ax1.set_xlabel("day's mean voltage, % from the off days")
        ax1.set_ylabel("day's energy, % (calendar, weather, level out)")
        ax1.legend(fontsize=8)
    ax1.set_title("energy against voltage")
    d = days.date.astype("datetime64[D]").astype(float)
    e_p = days.energy["p"]
    when = days.date.astype("datetime64[D]")
    ax2.plot(when[~on], e_p[~on], "o", mfc="none", color="C0", label="off")
    ax2.plot(when[on], e_p[on], "o", color="C3", label="on")
    for i in range(d.size - 1):
        if d[i + 1] - d[i] == 1 and on[i] != on[i + 1]:
            ax2.plot(when[i : i + 2], e_p[i : i + 2], "-", color="0.6", lw=0.7)
    ax2.set_xlabel("date")
    fig.autofmt_xdate()
    ax2.set_ylabel("daily energy (per unit of the power base x h)")
    ax2.set_title("the daily pairs")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    return fig
