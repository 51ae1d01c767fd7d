"""The demo's CVR section: the energy and instantaneous CVR factors of a generated test.

The feeder of ``loadbayes example cvr`` (:mod:`loadbayes.cases.cvr_example`: a 90-day
on/off test with thermostatic heaters, PV, weather, a head voltage that sags with the
load, gaps and glitches) fitted by :func:`loadbayes.fit.cvr.cvr` as the command does,
with the schedule found from the voltage; the section sets each factor beside its
counterfactual truth, says why the two differ, and draws energy against voltage and the
daily pairs. A few seconds (the quick run cuts the step fit's draws).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["CVRStudy", "html_section", "run"]


@dataclass
class CVRStudy:
    """The fit's result (with its draws, for the figure) and the truth."""

    result: dict[str, Any]
    truth: dict[str, float]
    settings: dict[str, Any]


def run(*, quick: bool = True, seed: int = 0, smoke: bool = False) -> CVRStudy:
    """Fit the example feeder (``seed`` seeds the draws; the feeder is the example's).

    ``smoke``: the first 30 of the 90 days and 200 draws, a check of the pipeline, not a
    result (the truth stays the 90 days').
    """
    from loadbayes.cases.cvr_example import FEEDER_KV, FEEDER_MVA, cvr_frame, cvr_truth
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.cvr import CVR_DEFAULTS, cvr

    draws = 200 if smoke else 1_000 if quick else 4_000
    frame = cvr_frame()
    if smoke:
        frame = frame.iloc[: 30 * 288]  # 5-minute rows
    res = cvr(
        frame, t_col="time", v_col="v_kv", p_col="p_mw", q_col="q_mvar",
        v_base=FEEDER_KV, s_base=FEEDER_MVA, weather_col="temp_c", holiday_col="holiday",
        pv_col="irradiance", sampler=CVR_DEFAULTS.with_(draws=draws, seed=seed),
        step_sampler=SamplerSettings(draws=draws + 300, burn=300, chains=2, seed=seed),
    )  # fmt: skip
    rows = res["instantaneous"].get("dP/dV", {}).get("step_rows")
    return CVRStudy(res, cvr_truth(step_rows=rows), {"draws": draws, "seed": seed,
                                                     "quick": quick, "smoke": smoke})  # fmt: skip


def _row(name: str, s: dict | None, truth: float | None) -> dict[str, Any]:
    if not s:
        return {"quantity": name, "estimate": "not fitted", "95% interval": "", "truth": truth}
    return {"quantity": name, "estimate": round(s["mean"], 3),
            "95% interval": f"[{s['low']:.3g}, {s['high']:.3g}]",
            "truth": None if truth is None else round(truth, 3)}  # fmt: skip


def html_section(study: CVRStudy) -> str:
    """The CVR section of the report (an HTML ``<section>``)."""
    import pandas as pd

    from loadbayes.plots.cvr import plot_cvr
    from loadbayes.studies.report import bullet_list, escape, figure_html, frame_html

    r, t = study.result, study.truth
    imp = r.get("source_impedance") or {}
    rows = [
        _row("energy CVR factor, P (%dE/%dV)", r["energy"].get("p"), t["cvr_energy_p"]),
        _row("energy CVR factor, Q", r["energy"].get("q"), t["cvr_energy_q"]),
        _row(
            "instantaneous dP/dV (at the steps used)",
            r["instantaneous"].get("dP/dV"),
            t.get("dp_dv_at_steps"),
        ),  # fmt: skip
        _row(
            "head voltage's sensitivity (p.u./MW)",
            {"mean": imp["z"], "low": imp["low"], "high": imp["high"]} if imp else None,
            t["z_pu_per_mw"],
        ),  # fmt: skip
    ]
    words = [r.get("why", {}).get("words", ""), r["power"]["words"], *r["notes"]]
    words += [f"warning: {w}" for w in r["warnings"]]
    g = r["glitches"]
    parts = [
        '<section id="cvr">',
        "<h2>Conservation voltage reduction: the energy factor and dP/dV</h2>",
        "<p>The feeder of <code>loadbayes example cvr</code>: 90 days at a 12.47 kV head "
        "every 5 minutes, the 3% reduction on one day of each pair, thermostatic heaters, "
        "PV behind the meter, a head voltage that sags 0.003 p.u. per MW of load; the "
        f"schedule found from the {escape(r['schedule']['source'])}; glitches left out: "
        f"{g['spikes_v']} V spike, {g['spikes_p']} P spike, {g['stuck']} stuck samples. "
        "The truth is counterfactual (the same days with the reduction on every day and "
        f"off every day). Exact draws: {study.settings['draws']} per chain, seed "
        f"{study.settings['seed']}.</p>",
        frame_html(pd.DataFrame(rows), caption="The CVR factors against their truth"),
        bullet_list([escape(w) for w in words if w]),
        figure_html(
            plot_cvr(r),
            "Daily energy against voltage (calendar, weather and "
            "level taken out), and the daily on/off pairs.",
        ),  # fmt: skip
        "</section>",
    ]
    return "\n".join(parts)
