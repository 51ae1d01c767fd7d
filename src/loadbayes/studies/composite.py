"""The composite load from simulated terminal recordings: the events, the fit, the NLS.

Protocol (every number is measured by :func:`run`):

* events: the small industrial motor (f_m = 0.5, T0 = 0.6) with a ZIP part
  (P: 0.4, 0.2, 0.4; Q: 0.5, 0.2, 0.3), two sags of 30% and 45% held 0.2 s with a 0.3 s
  recovery, 3 s at 60 samples/s, noise 1% of |S0| (SciPy's DOP853 as the truth,
  :mod:`loadbayes.cases.composite_sim`);
* fit: :func:`loadbayes.fit.composite.driver.fit_composite` on both events jointly (the motor
  shared), 4 chains, default priors; the NLS baseline (penalised least squares with
  its Gaussian approximation) beside it;
* table: truth, posterior mean and 95% interval, NLS estimate and its sd, for the
  quantities of the naming contract; figure: P and Q with the posterior band over the
  measured traces, and motor-parameter pairs against the truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["CompositeStudy", "html_section", "run", "text_table"]

SHOWN = (
    "p0", "q0", "a1", "a2", "a3", "a4", "a5", "a6", "f_m", "t_prime_s", "x_prime",
    "x_open", "h_s", "rs", "t0", "mva_m", "q_c",
)  # fmt: skip


@dataclass
class CompositeStudy:
    """What :func:`run` returns: the table, the figure and the settings."""

    table: pd.DataFrame
    figure: Any
    settings: dict[str, Any]
    identifiability: dict[str, Any]


def run(*, quick: bool = True, seed: int = 0, smoke: bool = False) -> CompositeStudy:
    """Simulate the two events, fit them, and tabulate against the truth and the NLS.

    ``smoke``: 400 iterations (200 burn-in), a check of the pipeline, not a result.
    """
    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite import fit_composite, predictive_band
    from loadbayes.models.zip_motor import CompositeModel
    from loadbayes.plots.composite import plot_composite

    events, truth = [], None
    for k, depth in enumerate((0.3, 0.45)):
        ev, tr = simulate_event(
            "small_industrial",
            depth=depth,
            recovery_s=0.3,
            noise=0.01,
            seed=seed + k,
            zip_p=(0.4, 0.2, 0.4),
            zip_q=(0.5, 0.2, 0.3),
            name=f"sag {depth:.0%}",
        )
        events.append(ev)
        truth = truth or tr
    draws, burn = (400, 200) if smoke else (2000, 1000) if quick else (8000, 3000)
    sampler = SamplerSettings(draws=draws, burn=burn, chains=4, seed=seed)
    fit = fit_composite(CompositeModel(window_s=0), events, sampler=sampler)
    post, nls = fit.posterior, fit.baseline
    rows = []
    for name in SHOWN:
        x = post.draws[name].ravel()
        lo, hi = np.percentile(x, [2.5, 97.5])
        rows.append(
            {
                "parameter": name,
                "truth": float(truth[name]),
                "posterior_mean": float(x.mean()),
                "ci95_low": float(lo),
                "ci95_high": float(hi),
                "covered": bool(lo <= truth[name] <= hi),
                "nls": float(nls.draws[name].mean()),
                "nls_sd": float(nls.draws[name].std()),
            }
        )
    table = pd.DataFrame(rows).set_index("parameter")
    bands = predictive_band(post, events, seed=seed)
    fig = plot_composite(post, events, bands, baseline=nls, truth=truth)
    settings = {
        "events": [e.name for e in events],
        "n": [e.n for e in events],
        "draws": draws,
        "burn": burn,
        "chains": 4,
        "seed": seed,
        "seconds": fit.seconds,
    }
    return CompositeStudy(table, fig, settings, post.extra_json["identifiability"])


def text_table(study: CompositeStudy) -> str:
    """The table as aligned text."""
    return study.table.to_string(float_format=lambda x: f"{x:.4g}")


def html_section(study: CompositeStudy) -> str:
    """The composite-load section of the report (an HTML ``<section>``)."""
    from loadbayes.studies.report import escape, figure_html, table_html

    st = study.settings
    cov = int(study.table["covered"].sum())
    parts = [
        '<section id="composite">',
        "<h2>Composite load (ZIP + induction motor) from terminal recordings</h2>",
        "<p>Two simulated sags (30% and 45%, 0.2 s, 0.3 s recovery; small industrial motor, "
        "f_m = 0.5; 3 s at 60 samples/s; noise 1% of |S0|) fitted jointly: "
        f"{st['chains']} chains x {st['draws']} iterations ({st['burn']} burn-in), seed "
        f"{st['seed']}; NLS baseline beside it. The truth lies in {cov} of "
        f"{len(study.table)} 95% intervals.</p>",
        table_html(study.table, float_format="{:.4g}"),
        figure_html(study.figure, "P and Q with the posterior band; motor pairs (star: truth)."),
        f"<p>{escape(study.identifiability['summary'])}</p>",
        "</section>",
    ]
    return "\n".join(parts)
