"""The composite fit's parts of the report: the recordings, what they determine, settings.

:func:`meaning` and :func:`unit` read :data:`loadbayes.report.composite_names.QUANTITIES`
(the one place of the composite's units); :func:`sections` adds the figure of V(t),
P(t), Q(t) against the recordings (from a NetCDF result that keeps them) and the
identifiability section (from the JSON as well); :func:`settings` lists the settings
a reader needs to rerun the fit.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from typing import Any

__all__ = ["headline_names", "meaning", "sections", "settings", "unit"]


def meaning(name: str, *, with_unit: bool = False) -> str:
    """A composite quantity's meaning in words (``with_unit``: "words [unit]")."""
    from loadbayes.report.composite_names import describe
    from loadbayes.report.composite_table import meaning as with_brackets

    return with_brackets(name) if with_unit else describe(name)[1]


def unit(name: str) -> str:
    """A composite quantity's unit."""
    from loadbayes.report.composite_names import describe

    return describe(name)[0]


def headline_names(d: Mapping[str, Any]) -> list[str]:
    """The rows of the summary table: those ``fit composite`` prints."""
    from loadbayes.report.composite_table import table_names

    n_events = len((d.get("settings") or {}).get("events") or []) or 1
    return table_names(d["parameters"], n_events)


def sections(page: Any, d: Mapping[str, Any], post: Any, hdi: float) -> None:
    """The figure of the recordings (with draws) and the identifiability section."""
    e = html.escape
    if post is not None:
        from loadbayes.report.figures import composite_fit_figure

        seed = int((d.get("settings") or {}).get("seed") or 0)
        fig = composite_fit_figure(post, hdi_prob=hdi, seed=seed)
        if fig is not None:
            page.section(fig.title).figure(fig.png, fig.caption, alt=fig.alt, title=fig.title)
    ident = d.get("identifiability")
    if not ident:
        return
    sec = page.section("What the events determine")
    sec.text(ident.get("summary", ""))
    for ridge in ident.get("ridges") or []:
        sec.text(ridge["words"])
    static = ident.get("static_part")
    if static:
        from loadbayes.report.composite_table import static_lines

        lines = static_lines(static, hdi_prob=hdi)
        if lines:
            items = "".join(f"<li>{e(line.strip())}</li>" for line in lines)
            sec.add(
                "<div class='warn'><b>Static (ZIP) part: its shares are not determined.</b> "
                "One sag shows the static part at two voltages only; the shares trade off "
                "along a line, and the reported a1..a6 are not what the data determine. What "
                f"the events do fix:<ul>{items}</ul></div>"
            )
        else:
            sec.add(f"<p class='ok'><b>Static (ZIP) part.</b> {e(static['summary'])}</p>")
    helps = ident.get("what_would_help") or []
    if helps:
        sec.text("What would help: " + "; ".join(helps) + ".")


def settings(d: Mapping[str, Any], st: Mapping[str, Any]) -> dict[str, Any]:
    """The settings a reader needs: files, events, bases (when given), draws and seed."""
    events = st.get("events") or []
    ev_text = "; ".join(
        f"{ev.get('name')}: {ev.get('n')} samples over {ev.get('t_span_s', 0):.3g} s, "
        f"v0 = {ev.get('v0', float('nan')):.4g} p.u."
        for ev in events
    )
    bases = {
        k: st.get(k)
        for k in ("v_base_kv", "s_base_mva", "v_base", "s_base")
        if st.get(k) is not None
    }
    steps = st.get("steps") or {}
    torque = st.get("torque")
    return {
        "files": ", ".join(map(str, st.get("files") or [])) or None,
        "events": ev_text or None,
        "bases": bases or None,
        "nominal frequency (Hz)": st.get("f_hz"),
        "load torque (A, B, C)": torque
        if isinstance(torque, str)
        else (", ".join(f"{x:g}" for x in torque) if torque else None),  # fmt: skip
        "voltage steps": None
        if not steps
        else (
            "modelled (an instant inside each step's interval)"
            if steps.get("modelled")
            else "read as ramps"
        ),  # fmt: skip
        "likelihood": st.get("likelihood"),
        "method": d.get("method"),
        "chains × draws (burn, thin)": f"{d.get('chains')} × {d.get('draws')} "
        f"({d.get('burn')}, {d.get('thin')})",
        "seed": st.get("seed"),
        "wall time (s)": ", ".join(f"{k} {v:.1f}" for k, v in (st.get("timing_s") or {}).items())
        or None,
    }
