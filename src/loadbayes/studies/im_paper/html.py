"""The IM section of the HTML report: settings, tables, prose and embedded figures."""

from __future__ import annotations

from loadbayes.studies.im_paper.charts import figures
from loadbayes.studies.im_paper.study import (
    METHODS,
    ImStudy,
)
from loadbayes.studies.im_paper.tables import physical_table, table1, table3
from loadbayes.studies.im_paper.text import _sentences
from loadbayes.studies.report import bullet_list, embedded_png, frame_html, png_bytes


def html_section(study: ImStudy, pngs: dict[str, bytes] | None = None) -> str:
    """The IM section of the report: a ``<section>`` with settings, tables and figures.

    Parameters
    ----------
    study : ImStudy
        The study.
    pngs : dict of str to bytes, optional
        PNG bytes of :func:`figures` by name (rendered here when not given).

    Returns
    -------
    str
        HTML fragment; figures embedded as base64 PNG.
    """
    if pngs is None:
        pngs = {k: png_bytes(f) for k, f in figures(study).items()}
    t1, t3, phys = table1(study), table3(study), physical_table(study)
    st = study.settings
    d = st["disturbance"]
    dist = ", ".join(f"{k} {v}" for k, v in d.items() if k != "kind")
    smp = st["sampler"]
    settings = [
        f"motors: {', '.join(st['motors'])} (sources in docs/motor.md)",
        f"samples: {st['samples']} per motor ({st['t_end_s']:g} s at {1000 * st['dt_s']:g} ms)",
        f"disturbance: {d.get('kind')} ({dist})",
        f"noise: {100 * st['noise']:g}% of each channel's RMS, {st['noise_on']}",
        f"seed: {st['seed']}; Gibbs: {smp['draws']} iterations, {smp['burn']} burn-in, "
        f"{smp['chains']} chains",
        f"priors: {st['priors']}; T0: {st['t0']}; Kalman filter: {st['kalman']}",
    ]

    def img(name: str, alt: str) -> str:
        return embedded_png(pngs, name, alt)

    t1_show = t1[
        [
            "motor",
            "coefficient",
            "true",
            "gs_mean",
            "gs_err_pct",
            "gs_covers",
            "measured_mean",
            "measured_err_pct",
            "paper_true",
            "paper_mean",
            "paper_err_pct",
        ]
    ]
    t3_show = t3[
        ["motor", "coefficient", *METHODS, "true", "paper_gs", "paper_ls", "paper_kf", "paper_true"]
    ]
    eiv = study.eiv
    parts = [
        '<section id="im">',
        "<h2>Induction motor: the paper's IM study</h2>",
        bullet_list(settings),
        "<h3>Table I: true value, posterior mean, error %</h3>",
        frame_html(t1_show),
        "<h3>Table III: coefficients by method</h3>",
        "<p>" + "; ".join(f"{k}: {v}" for k, v in METHODS.items()) + ".</p>",
        frame_html(t3_show),
        "<h3>What differs from the paper</h3>",
        bullet_list(_sentences(study, t1, t3, phys)),
        "<h3>Posterior of the five coefficients (Fig. 6)</h3>",
        img("fig6_coefficients", "posterior histograms of b1, b2, b3, ab, ac"),
        "<h3>Physical parameters</h3>",
        frame_html(phys),
        img("physical", "physical parameters with 95% intervals"),
    ]
    if not eiv.empty:
        parts += [
            "<h3>Errors in variables</h3>",
            "<p>Posterior-mean error (%) with noise on the targets only (the paper's "
            "setting) and on the regressors too (ed, eq, w, ud, uq), for both forms.</p>",
            frame_html(eiv),
            img("eiv", "errors in variables"),
        ]
    parts.append("</section>")
    return "\n".join(parts)
