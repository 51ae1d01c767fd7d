"""The report of one fit (any model): ``loadbayes report RESULT.json|.nc --out report.html``.

From a NetCDF file (all draws) the report has every section with figures; from the JSON
summary it has the numbers only and says where the figures would come from. The summary
comes first: what was fitted, the headline numbers with their intervals, the verdict of
the diagnostics and every warning; true values, when given, are flagged where the
interval misses them.

One idea needs these 419 lines: the report of one fit, its summary first and then a
section per part (parameters, figures, correlations, settings), from a JSON or a NetCDF
result.
"""

from __future__ import annotations

import html
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from loadbayes.core.display import DESCRIPTIONS, fmt, fmt_like
from loadbayes.report.page import Page, table_html

__all__ = ["MODEL_NAMES", "fit_report", "load_result", "write_report"]

#: Model names in words.
MODEL_NAMES = {
    "zip": "ZIP load model",
    "exp": "exponential load model",
    "im": "third-order induction motor",
    "composite": "composite load model (ZIP + induction motor)",
}

#: R-hat above which chains are said not to agree; bulk ESS below which draws are few.
RHAT_LIMIT, ESS_LIMIT = 1.01, 400


def load_result(path: str | Path) -> tuple[dict[str, Any], Any]:
    """Read a fit: ``(JSON contract dict, Posterior or None)``; ``.nc`` gives both.

    Raises
    ------
    DataError
        A missing or unreadable file, or one that is not a loadbayes result.
    """
    from loadbayes.io.errors import DataError

    p = Path(path)
    if not p.is_file():
        raise DataError("file not found" if not p.exists() else "is not a file", str(path))
    if p.suffix.lower() in (".nc", ".netcdf", ".nc4"):
        from loadbayes.posterior import Posterior

        try:
            post = Posterior.from_netcdf(p)
        except Exception as exc:  # netCDF4/h5netcdf raise many types; say it in one line
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise DataError(f"not a loadbayes NetCDF result ({msg})", str(path)) from None
        return post.to_dict(), post
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(f"not a JSON result ({exc})", str(path)) from None
    if not isinstance(d, dict) or "parameters" not in d or "model" not in d:
        raise DataError("not a loadbayes result: no 'model' and 'parameters'", str(path))
    return d, None


def _what(d: Mapping[str, Any]) -> str:
    st = d.get("settings", {}) or {}
    model = MODEL_NAMES.get(d["model"], f"{d['model']} model")
    chans = "P and Q" if any(k in d["parameters"] for k in ("a4", "nq", "tau_q")) else "P"
    if d["model"] == "im":
        chans = "flux, speed and current equations"
    data = st.get("data") or ", ".join(map(str, st.get("files") or [])) or None
    src = f" of {data}" if data and data not in ("DataFrame", "mapping") else ""
    if d["model"] == "composite":
        n_ev = len(st.get("events") or [])
        src = f" of {n_ev} event(s)" + (f" ({data})" if data else "")
    span = ""
    if st.get("time_start"):
        span = f", from {st['time_start']} to {st['time_end']}"
    n = d.get("n") or st.get("n")
    kept = f"{d.get('chains')} chains × {int(d.get('kept_draws', 0)):,} kept draws"
    if st.get("draws_thinned"):
        burn, draws, thin = (int(st.get(k, v)) for k, v in (("burn", 0), ("draws", 0), ("thin", 1)))
        total = len(range(burn, draws, thin))
        used = int(d.get("kept_draws", 0))
        kept = (f"{d.get('chains')} chains × {total:,} kept draws; the NetCDF file and this "
                f"report use {used:,} of them a chain, evenly spaced")  # fmt: skip
    how = f"by {d.get('method')} ({kept})"
    return f"A {model} ({chans}) fitted to {int(n):,} samples{src}{span}, {how}."


#: The words of a fit whose load level is confounded with the voltage
#: (:data:`loadbayes.fit.drift.CONFOUNDED`).
CONFOUNDED_MARK = "the load level changes over the record and the voltage follows it"


def _verdict(d: Mapping[str, Any]) -> tuple[bool, str]:
    ps = d["parameters"]
    rh = [v.get("r_hat") for v in ps.values() if v.get("r_hat") is not None]
    ess = [v.get("ess_bulk") for v in ps.values() if v.get("ess_bulk") is not None]
    if not rh and not ess:
        return True, "No convergence diagnostics (one chain, or a point estimate)."
    worst_r = max(rh) if rh else float("nan")
    least = min(ess) if ess else float("nan")
    ok = (not rh or worst_r <= RHAT_LIMIT) and (not ess or least >= ESS_LIMIT)
    text = (
        f"largest R-hat {worst_r:.3f} (limit {RHAT_LIMIT}), smallest bulk ESS {least:,.0f} "
        f"(at least {ESS_LIMIT} wanted)"
    )
    return ok, ("Chains agree: " if ok else "Chains may not have converged: ") + text + "."


def _meaning(d: Mapping[str, Any], name: str, *, with_unit: bool = False) -> str:
    if d["model"] == "composite":
        from loadbayes.report.composite import meaning

        return meaning(name, with_unit=with_unit)
    return DESCRIPTIONS.get(name, "")


def _truth_flags(d: Mapping[str, Any], truth: Mapping[str, float]) -> dict[str, bool]:
    """True where the given true value lies outside the parameter's interval."""
    out = {}
    for name, t in truth.items():
        p = d["parameters"].get(name)
        if p is None or p.get("hdi_low") is None:
            continue
        out[name] = not (p["hdi_low"] <= t <= p["hdi_high"])
    return out


def fit_report(
    d: Mapping[str, Any],
    post: Any = None,
    *,
    truth: Mapping[str, float] | None = None,
    title: str | None = None,
    source: str | None = None,
) -> str:
    """The HTML report of one fit.

    Parameters
    ----------
    d : mapping
        The fit's JSON contract (:meth:`Posterior.to_dict`).
    post : Posterior, optional
        The draws (from NetCDF), for the figures; without them the report has numbers only.
    truth : mapping, optional
        Known true values (a simulation), flagged where the interval misses them.
    title : str, optional
        Page title; by default from the model and the data.
    source : str, optional
        The result file, named in the page.

    Returns
    -------
    str
        A self-contained HTML page.
    """
    from loadbayes._version import __version__

    truth = dict(truth or {})
    unknown = set(truth) - set(d["parameters"])
    if unknown:
        raise ValueError(
            f"truth given for {', '.join(sorted(unknown))}, which the fit does not have "
            f"(it has {', '.join(d['parameters'])})"
        )
    flags = _truth_flags(d, truth)
    hdi = float(d.get("hdi_prob", 0.95))
    pct = f"{hdi:.0%}"
    st = d.get("settings", {}) or {}
    model_name = MODEL_NAMES.get(d["model"], d["model"])
    data = st.get("data")
    if data in ("DataFrame", "mapping"):  # fitted from memory: no file to name
        data = None
    fitted = d.get("loadbayes_version", "?")
    page = Page(
        title or f"{model_name[0].upper()}{model_name[1:]}" + (f": {data}" if data else ""),
        "Report"
        + (f" of {source}" if source else "")
        + f", fitted with loadbayes {fitted}"
        + (f", reported with {__version__}" if fitted != __version__ else "")
        + ".",
    )
    coefs = [n for n in d["parameters"] if not n.startswith("tau")]
    if post is not None:
        coefs = [n for n in post.coefficients if n in d["parameters"]]
    if d["model"] == "composite":  # the rows the CLI prints (the JSON has them all)
        from loadbayes.report.composite import headline_names

        coefs = headline_names(d)

    # -------------------------------------------------------------- summary
    e = html.escape
    ok, verdict = _verdict(d)
    head_rows = []
    for n in coefs:
        p = d["parameters"][n]
        lo, hi = fmt_like(p["hdi_low"], p["sd"]), fmt_like(p["hdi_high"], p["sd"])
        row = [n, _meaning(d, n, with_unit=True), fmt_like(p["mean"], p["sd"]), f"{lo} to {hi}"]
        if truth:
            row += [fmt(truth[n]) if n in truth else "", _flag_text(flags.get(n))]
        head_rows.append(row)
    for n, p in (d.get("derived") or {}).items():
        lo, hi = fmt_like(p["hdi_low"], p["sd"]), fmt_like(p["hdi_high"], p["sd"])
        row = [n, DESCRIPTIONS.get(n, ""), fmt_like(p["mean"], p["sd"]), f"{lo} to {hi}"]
        head_rows.append(row + (["", ""] if truth else []))
    header = ["parameter", "meaning", "mean", f"{pct} interval"] + (
        ["true value", "check"] if truth else []
    )
    summary = [f"<p>{e(_what(d))}</p>"]
    summary.append(table_html(header, head_rows, text_cols=(0, 1, 5),
                              flags=[bool(flags.get(n)) for n in coefs]
                              + [False] * (len(head_rows) - len(coefs))))  # fmt: skip
    if truth:
        missed = [n for n, bad in flags.items() if bad]
        cls = "warn" if missed else "ok"
        text = (
            f"{len(missed)} of {len(flags)} true values lie outside their {pct} interval: "
            + ", ".join(missed)
            + "."
            if missed
            else f"Every one of the {len(flags)} true values lies inside its {pct} interval."
        )
        summary.append(f"<p class='{cls}'>{e(text)}</p>")
    warnings = list(d.get("warnings") or [])
    confounded = [w for w in warnings if CONFOUNDED_MARK in w]
    if confounded:
        # No green box over an unphysical result: the chains may agree on a wrong answer.
        ok = False
        verdict = ("The chains agree, but on a confounded answer: " + confounded[0]
                   + " " + verdict)  # fmt: skip
    summary.append(f"<p class='{'ok' if ok else 'warn'}'>{e(verdict)}</p>")
    if warnings:
        items = "".join(f"<li>{e(w)}</li>" for w in warnings)
        summary.append(f"<div class='warn'><b>Warnings ({len(warnings)})</b><ul>{items}</ul></div>")
    else:
        summary.append("<p class='ok'>No warnings about the data or the fit.</p>")
    if post is None:
        summary.append(
            "<p class='warn'>Made from the JSON summary, which holds no draws: the figures "
            "need the draws. Fit again with <code>--netcdf fit.nc</code> and run "
            "<code>loadbayes report fit.nc</code>.</p>"
        )
    page.summary("".join(summary))

    # ----------------------------------------------------------- sections
    if d["model"] == "composite":
        from loadbayes.report.composite import sections

        sections(page, d, post, hdi)
    _parameters_section(page, d, post, truth, flags, pct)
    if post is not None:
        # A composite's marginals: the rows of its summary (the JSON holds ~40 names).
        shown = coefs if d["model"] == "composite" else None
        _figure_sections(page, post, hdi, truth, shown)
    _correlation_section(page, d, coefs)
    _settings_section(page, d, st)
    return page.render()


def _corr(r: float | None) -> str:
    if r is None:
        return "–"
    return "0.00" if abs(r) < 0.005 else f"{r:+.2f}"


def _flag_text(flag: bool | None) -> str:
    if flag is None:
        return ""
    return "OUTSIDE the interval" if flag else "inside"


def _parameters_section(page, d, post, truth, flags, pct) -> None:
    from loadbayes.predictive import param_unit

    sec = page.section("Parameters")
    names = list(d["parameters"])
    rows = []
    for n in names:
        p = d["parameters"][n]
        unit = param_unit(n, post) if post is not None else ""
        if d["model"] == "composite":
            from loadbayes.report.composite import unit as composite_unit

            unit = composite_unit(n)
        row = [n, _meaning(d, n), unit, fmt_like(p["mean"], p["sd"]), fmt(p["sd"], 2),
               fmt_like(p["hdi_low"], p["sd"]), fmt_like(p["hdi_high"], p["sd"]),
               "–" if p.get("ess_bulk") is None else f"{p['ess_bulk']:,.0f}",
               "–" if p.get("r_hat") is None else f"{p['r_hat']:.3f}"]  # fmt: skip
        if truth:
            row.append(fmt(truth[n]) if n in truth else "")
        rows.append(row)
    header = ["parameter", "meaning", "unit", "mean", "sd", f"{pct} low", f"{pct} high",
              "ESS", "R-hat"] + (["true"] if truth else [])  # fmt: skip
    sec.add(
        table_html(header, rows, text_cols=(0, 1, 2), flags=[bool(flags.get(n)) for n in names])
    )
    sec.text(
        f"Mean and standard deviation of the posterior draws, the {pct} highest-density "
        "interval, the bulk effective sample size (ESS) and the rank-normalised R-hat. A mean "
        "and its interval show the digits their sd warrants (two digits of the sd); the sd "
        "has two significant digits. Noise precisions tau are 1/variance of the noise."
    )


def _figure_sections(page, post, hdi, truth, names=None) -> None:
    from loadbayes.report.figures import (
        curves_figure,
        marginals_figure,
        pairs_figure,
        traces_figure,
    )

    curve = curves_figure(post, hdi_prob=hdi)
    if curve is not None:
        page.section("Load curves").figure(curve.png, curve.caption, alt=curve.alt,
                                           title=curve.title)  # fmt: skip
    marg = marginals_figure(post, hdi_prob=hdi, truth=truth, names=names)
    if marg is not None:
        page.section("Marginal posteriors").figure(marg.png, marg.caption, alt=marg.alt,
                                                   title=marg.title)  # fmt: skip
    pairs = pairs_figure(post)
    if pairs is not None:
        page.section("Pair plots").figure(pairs.png, pairs.caption, alt=pairs.alt,
                                          title=pairs.title)  # fmt: skip
    tr = traces_figure(post)
    if tr is not None:
        page.section("Convergence").figure(tr.png, tr.caption, alt=tr.alt, title=tr.title)


def _correlation_section(page, d, coefs) -> None:
    corr = d.get("correlation") or {}
    names = [n for n in coefs if n in corr][:8]
    if len(names) < 2:
        return
    sec = page.section("Correlations")
    rows = [[a] + [_corr(corr[a].get(b)) for b in names] for a in names]
    sec.add(table_html(["", *names], rows))
    strong = [
        (a, b, corr[a][b])
        for i, a in enumerate(names)
        for b in names[i + 1 :]
        if corr[a].get(b) is not None and abs(corr[a][b]) > 0.9
    ]
    if strong:
        sec.text(
            "Strongly correlated (|r| > 0.9): "
            + "; ".join(f"{a} and {b} ({r:+.3f})" for a, b, r in strong)
            + ". Their combination is better determined than either alone."
        )
    else:
        sec.text("No pair of coefficients is correlated beyond |r| = 0.9.")


def _settings_section(page, d, st) -> None:
    sec = page.section("Settings")
    if d["model"] == "composite":
        from loadbayes.report.composite import settings

        keep = settings(d, st)
    else:
        keep = _linear_settings(d, st)
    items = "".join(
        f"<dt>{html.escape(k)}</dt><dd>{html.escape(_plain(v))}</dd>"
        for k, v in keep.items()
        if v is not None and v != "None / None"
    )
    sec.add(f"<dl class='settings'>{items}</dl>")
    sec.text("Every setting, the priors included, is in the JSON result under 'settings'.")


def _linear_settings(d, st) -> dict[str, Any]:
    return {
        "data": st.get("data"),
        "columns": st.get("columns"),
        "v_base / s_base": f"{st.get('v_base')} / {st.get('s_base')}",
        "v0, p0, q0": f"{st.get('v0')}, {st.get('p0')}, {st.get('q0')}",
        "method": d.get("method"),
        "chains × draws (burn, thin)": f"{d.get('chains')} × {d.get('draws')} "
        f"({d.get('burn')}, {d.get('thin')})",
        "seed": st.get("seed"),
        "rows dropped": st.get("n_dropped"),
        "time span": f"{st['time_start']} to {st['time_end']}" if st.get("time_start") else None,
    }


def _plain(v: Any) -> str:
    if isinstance(v, dict):
        return ", ".join(f"{k} = {w}" for k, w in v.items() if w is not None)
    if isinstance(v, float) and np.isfinite(v):
        return fmt(v)
    return str(v)


def write_report(
    result: str | Path,
    out: str | Path,
    *,
    truth: Mapping[str, float] | None = None,
    title: str | None = None,
    force: bool = False,
) -> Path:
    """Read a result (``.json`` or ``.nc``) and write its report atomically."""
    from loadbayes.io.atomic import atomic_write

    d, post = load_result(result)
    text = fit_report(d, post, truth=truth, title=title, source=Path(result).name)
    out = Path(out)
    with atomic_write(out, force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return out
