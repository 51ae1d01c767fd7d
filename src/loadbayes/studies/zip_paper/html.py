"""The ZIP section of the HTML report: settings, tables, prose and embedded figures."""

from __future__ import annotations

from collections.abc import Mapping

from loadbayes.studies.report import bullet_list, embedded_png, frame_html, png_bytes
from loadbayes.studies.zip_paper.charts import figures
from loadbayes.studies.zip_paper.study import TABLE2_ROWS, TRUE_ZIP, ZipStudy
from loadbayes.studies.zip_paper.tables import (
    comparison,
    needed_n,
    sampler_table,
    study_table2,
    validation_summary,
)
from loadbayes.studies.zip_paper.text import _sentences


def html_section(study: ZipStudy, pngs: Mapping[str, bytes] | None = None) -> str:
    """The ZIP section of the report: settings, tables, figures and the comparison.

    Parameters
    ----------
    study : ZipStudy
        The study.
    pngs : mapping of str to bytes, optional
        PNG bytes of :func:`figures` by name (rendered here when not given).

    Returns
    -------
    str
        A ``<section id="zip">`` fragment with the figures embedded as base64 PNG.
    """
    if pngs is None:
        pngs = {k: png_bytes(f) for k, f in figures(study).items()}
    st = study.settings
    smp = st["sampler"]
    fail = st["failed"]
    settings = [
        f"feeder: pandapower case33bw; ZIP load (P and Q: {TRUE_ZIP}) at bus 18 (pandapower "
        f"bus {st['pandapower_bus']}), P0 = {1e3 * st['p0_mw']:g} kW, Q0 = "
        f"{1e3 * st['q0_mvar']:g} kvar; every other load times its own U"
        f"[{st['factor_range'][0]:g}, {st['factor_range'][1]:g}] factor",
        f"n = {st['n']} experiments fitted ({st['n_used']} converged), the first {st['n']} "
        f"of {st['n_generated']} generated (the sweep uses nested prefixes of the same "
        f"set); bus-18 voltage {st['v_range_pu'][0]:.3f}-{st['v_range_pu'][1]:.3f} p.u.",
        f"noise: sd {st['noise_sd_pu']:g} p.u. on {st['noise_on']}",
        f"seeds: data {st['data_seed']}, validation {st['validation_seed']}, samplers "
        f"{st['data_seed']}",
        f"priors: {st['priors_text']}; start: {st['init']}",
        f"Gibbs: {smp['draws']} iterations including {smp['burn']} burn-in (the paper's M "
        f"and m), {smp['chains']} chains; blocked (a1, a2) unless said otherwise",
        f"Kalman filter: {st['kalman']}",
        f"power flows: {st['power_flows_total']} in all; not converged: "
        f"{st['n_failed_generated']} of {st['n_generated']} generated, "
        + ", ".join(f"{k} {v}" for k, v in fail.items())
        + " in the validation (counted and left out, never dropped silently)",
        f"throughput: {st['flows_per_second_generate']:.0f} power flows/s on "
        f"{st['workers']} worker(s), engine {st['engine']!r}",
    ]
    t2 = study_table2(study)
    t2_show = t2[
        [
            "voltage_error_pct",
            "paper_voltage_error_pct",
            "power_error_pct",
            "paper_power_error_pct",
            "a1",
            "a2",
            "a3",
            "a1_err",
            "a2_err",
            "a3_err",
        ]
    ].reset_index()
    t2_show["true value outside the 95% interval"] = [
        _misses(study, key) for key in _keys(t2_show["method"])
    ]
    comp = comparison(study)
    comp_show = comp[
        ["label", "voltage_error_pct", "power_error_pct", "a1", "a1_sd", "a2", "a2_sd", "a3"]
        + ["a4", "a5", "a6"]
    ]
    vs = validation_summary(study).reset_index()
    samp = sampler_table(study)
    sw = study.sweep[["noise", "n", "n_used", "a1_mean", "a1_sd", "a1_sd_ls", "a2_sd"]]
    sw = sw.assign(corr_a1_a2=study.sweep.corr_a1_a2)
    need = needed_n(study.sweep)

    def img(name: str, alt: str) -> str:
        return embedded_png(pngs, name, alt)

    parts = [
        '<section id="zip">',
        "<h2>ZIP load on the IEEE 33-bus feeder: the paper's ZIP study</h2>",
        bullet_list(settings),
        "<h3>Table II: errors in % over the validation experiments, paper beside</h3>",
        "<p>voltage_error_pct = 100 &middot; mean<sub>i</sub> |V<sub>est,i</sub> - "
        "V<sub>true,i</sub>| / V<sub>true,i</sub>, power_error_pct likewise with the active "
        "power of the bus-18 load; <i>true</i> is the power flow with the true ZIP load, "
        "<i>est</i> the one with the estimated ZIP load (P and Q shares) on the same "
        "experiment. a<sub>k</sub>_err = estimate - truth. The last column names the "
        f"shares whose true value ({', '.join(f'{t:g}' for t in TRUE_ZIP)}) lies outside "
        "the estimator's central 95% interval: an estimate that disagrees with the truth "
        "beyond its own uncertainty.</p>",
        frame_html(t2_show),
        "<h3>What differs from the paper</h3>",
        bullet_list(_sentences(study)),
        "<h3>Every estimator on the same data</h3>",
        frame_html(comp_show.reset_index()),
        "<h3>Validation: |dV| and |dP| at bus 18 (p.u.)</h3>",
        frame_html(vs),
        img("fig3_voltage", "voltage at bus 18, true and estimated, with predictive band"),
        img("fig4_dv_dp", "distributions of |dV| and |dP|"),
        img("fig8_errors", "error distributions of GS, LS and KF"),
        "<h3>Posterior (Fig. 2) and the a1-a2 ridge</h3>",
        img("fig2_posterior", "posterior histograms of a1, a2, a3"),
        img("pair_a1_a2", "joint draws of a1 and a2"),
        "<h3>Sampler: single-site (the paper's) against blocked (Fig. 5)</h3>",
        frame_html(samp),
        img("fig5_burn_in", "burn-in traces"),
        "<h3>Sweep: posterior sd of a1 and a2 against n and noise</h3>",
        "<p>Blocked Gibbs (the study's priors and sampler settings) on nested prefixes of "
        "one set of experiments; a1_sd_ls is the least-squares standard error from the "
        "same sufficient statistics. The needed n is extrapolated from the largest n with "
        "sd &prop; 1/&radic;n.</p>",
        frame_html(sw),
        frame_html(need),
        img("sweep", "posterior sd against n"),
        "</section>",
    ]
    return "\n".join(parts)


def _keys(labels) -> list[str]:
    """Method keys of Table II's row labels (GS -> gs)."""
    inverse = {v: k for k, v in TABLE2_ROWS.items()}
    return [inverse.get(str(lab), str(lab)) for lab in labels]


def _misses(study: ZipStudy, key: str) -> str:
    """The shares a1..a3 whose true value lies outside the 95% central interval of ``key``."""
    import numpy as np

    post = study.fits.get(key)
    if post is None:
        return "n/a"
    out = []
    for name, true in zip(("a1", "a2", "a3"), TRUE_ZIP, strict=True):
        lo, hi = np.quantile(post.draws[name], [0.025, 0.975])
        if not lo <= true <= hi:
            out.append(f"{name} (true {true:g}, interval {lo:.3g} to {hi:.3g})")
    return "; ".join(out) if out else "none"
