"""The table ``loadbayes fit composite`` prints: ``fit zip``'s format, units on every row.

One row a quantity (each event's operating point and mix, then the motor's), the numbers
to the digits their sd warrants (:func:`loadbayes.report.text.summary_table`), and a
meaning column in words with the unit in brackets, both from
:data:`~loadbayes.report.composite_names.QUANTITIES`.
"""

from __future__ import annotations

from typing import Any

from loadbayes.core.display import fmt_like, precision_sd
from loadbayes.fit.composite.naming import event_suffix
from loadbayes.report.composite_names import TABLE_NAMES, describe
from loadbayes.report.text import summary_table

__all__ = [
    "TABLE_WIDTH",
    "composite_table",
    "meaning",
    "run_lines",
    "static_lines",
    "table_names",
]

#: The table's width: the composite's names and units need more than ``fit zip``'s 80.
TABLE_WIDTH = 100


def meaning(name: str) -> str:
    """``"words [unit]"`` of a named draw (the table's and the report's meaning column)."""
    unit, words = describe(name)
    if not words:
        return ""
    return f"{words} [{unit}]" if unit else words


def table_names(draws: dict[str, Any], n_events: int) -> list[str]:
    """The table's rows: each event's quantities (suffixed), the motor's, torque, noise."""
    per_event, motor = TABLE_NAMES
    names = []
    for k in range(n_events):
        sfx = event_suffix(k)
        names += [f"{n}{sfx}" for n in per_event]
        # The steps' instants (the fault and its clearing, when modelled as steps).
        names += sorted(n for n in draws if n.startswith("t_step") and n.endswith(sfx)
                        and (sfx or "_e" not in n))  # fmt: skip
    names += list(motor)
    # Estimated torque shares and sampled Student-t degrees of freedom, when there.
    if "log_a_over_c" in draws:
        names += ["a", "b", "c"]
    names += [n for n in ("nu_p", "nu_q") if n in draws]
    return [n for n in names if n in draws]


def composite_table(
    post: Any, summary: Any, *, n_events: int, hdi_prob: float = 0.95, width: int = TABLE_WIDTH
) -> str:
    """The composite posterior as the CLI prints it.

    Parameters
    ----------
    post : Posterior
        The composite fit.
    summary : DataFrame
        Its :meth:`~loadbayes.posterior.Posterior.summary` (at ``hdi_prob``), or the
        rows of it to print.
    n_events : int
        Events fitted (their suffixed rows are listed).
    hdi_prob : float
        Probability of the interval.
    width : int
        Longest line (the meaning is cut to fit; its unit is kept).

    Returns
    -------
    str
    """
    names = [n for n in table_names(post.draws, n_events) if n in summary.index]
    title = (
        f"composite posterior, {post.method}, {n_events} event(s), {post.n_chains} chains x "
        f"{post.n_draws:,} draws"
    )
    return summary_table(post, hdi_prob=hdi_prob, summary=summary.loc[names], width=width,
                         describe=meaning, title=title)  # fmt: skip


def static_lines(static: dict[str, Any], *, hdi_prob: float = 0.95) -> list[str]:
    """The static part's verdict as the CLI prints it, under the table.

    For each event and channel whose ZIP shares are not determined
    (:func:`~loadbayes.fit.composite.identifiability.static_identifiability`): a line
    saying so, then the combinations the data do fix, each with its interval.
    """
    pct = f"{hdi_prob:.0%}"
    lines = []
    for k, ev in enumerate(static.get("events", [])):
        for ch in ("p", "q"):
            part = ev.get(ch)
            if part is None or part["determined"]:
                continue
            names = ", ".join(part["shares"])
            r = part["correlation"]
            corr = "" if r is None else f", correlation {r:+.3f}"
            lines.append(
                f"static {ch.upper()} of event {k + 1} ({ev['event']}): the shares {names} are "
                f"not determined{corr}; the event fixes ({pct} interval):"
            )
            for c in part["combinations"]:
                digits = precision_sd(c["sd"], c["low"], c["high"])
                mid, lo, hi = (fmt_like(c[key], digits) for key in ("mean", "low", "high"))
                lines.append(f"  {c['name']} = {mid} ({lo} to {hi}): {c['meaning']}")
    return lines


def run_lines(post: Any) -> list[str]:
    """The settings a reader of the figure needs, one line each: files, bases, the run.

    The bases are shown when the settings hold them (``v_base_kv``, ``s_base_mva``, or
    the plain ``v_base``, ``s_base``).
    """
    st = post.settings
    lines = []
    files = st.get("files") or [e.get("name") for e in st.get("events") or []]
    if files:
        lines.append("data: " + ", ".join(map(str, files)))
    bases = [f"{k} = {st[k]:g}" for k in ("v_base_kv", "s_base_mva", "v_base", "s_base")
             if isinstance(st.get(k), (int, float))]  # fmt: skip
    nominal = f"f = {st['f_hz']:g} Hz" if isinstance(st.get("f_hz"), (int, float)) else ""
    if bases or nominal:
        lines.append("bases: " + ", ".join([*bases, nominal] if nominal else bases))
    run = [f"{post.n_chains} chains x {st.get('draws', '?')} iterations "
           f"({st.get('burn', '?')} burn-in, thin {st.get('thin', 1)})",
           f"seed {st.get('seed', '?')}", f"{st.get('likelihood', 'normal')} likelihood",
           f"method {post.method}"]  # fmt: skip
    torque = st.get("torque")
    if torque is not None:
        run.append("torque " + (torque if isinstance(torque, str)
                                else "(" + ", ".join(f"{x:g}" for x in torque) + ")"))  # fmt: skip
    lines.append("run: " + "; ".join(run))
    return lines
