"""A planning ensemble: the posterior draws that span what a fault does to the load.

``loadbayes export RESULT --planning --sag D --duration S`` (or ``--voltage``) plays the
posterior through the fault (``loadbayes.predict``: the command calls it and hands its
per-draw outcomes here), orders the draws played by the planning outcome
(``predict_scope.OUTCOME``: the load's reactive energy above its pre-fault Q after the
fault clears, which orders them by stall severity) and picks, for each asked quantile
(:data:`DEFAULT_QUANTILES`: 5 %, 50 %, 95 %), the draw whose outcome *is* that quantile of
the played draws' outcomes (the inverted empirical CDF: the smallest outcome with at
least that share of draws at or below it, so the pick's value equals the prediction's
quantile). Each file written carries a comment naming its quantile, the outcome's value,
the fault and the draw's index (:func:`comment`). A draw of a fit of parts is played
with its own thresholds (motor D's stall voltage and time, the electronics' trip
voltages: the fit's sampled ones, or its priors' for a fit that did not sample them):
the pick's go into its record (:func:`model_options`), so the record stalls as the
prediction did.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "DEFAULT_QUANTILES",
    "PlanningPick",
    "comment",
    "file_name",
    "label",
    "model_options",
    "parse_quantiles",
    "select",
]

#: The quantiles of the planning outcome written by default (``--quantiles``).
DEFAULT_QUANTILES = (0.05, 0.5, 0.95)
#: The thresholds a fit of parts draws with each draw played (``part_priors``).
_THRESHOLDS = ("vstall", "tstall", "vd1", "vd2")


@dataclass(frozen=True)
class PlanningPick:
    """One draw of the ensemble: its quantile, its index in the pooled draws, its outcome."""

    quantile: float
    index: int
    outcome: float
    stalled: bool | None = None
    thresholds: dict[str, float] = field(default_factory=dict)


def parse_quantiles(text: str | Sequence[float]) -> tuple[float, ...]:
    """``"0.05,0.5,0.95"`` as increasing quantiles in (0, 1); a ValueError in one line."""
    items = text.split(",") if isinstance(text, str) else list(text)
    try:
        qs = tuple(float(x) for x in items)
    except ValueError:
        raise ValueError(f"--quantiles {text!r}: numbers separated by commas, as "
                         "0.05,0.5,0.95") from None  # fmt: skip
    if not qs or len(qs) > 20:
        raise ValueError(f"--quantiles {text!r}: one to twenty quantiles")
    if not all(math.isfinite(q) and 0 < q < 1 for q in qs):
        raise ValueError(f"--quantiles {text!r}: each strictly between 0 and 1")
    if any(b <= a for a, b in zip(qs, qs[1:], strict=False)):
        raise ValueError(f"--quantiles {text!r}: increasing, each once")
    return qs


def select(outcomes: Mapping[str, np.ndarray], quantiles: Sequence[float], *,
           outcome: str) -> list[PlanningPick]:  # fmt: skip
    """The played draws at each quantile of ``outcomes[outcome]`` (see the module docstring).

    ``outcomes`` is ``Prediction.outcomes``: ``index`` (each played draw's index in the
    pooled posterior), the outcome, ``stalled`` and, for a fit of parts, the thresholds
    each draw played with. Among draws of equal outcome the first played is taken.
    """
    x = np.asarray(outcomes[outcome], dtype=float)
    if x.size == 0:  # predict_outcome.py: every draw collapsed or failed at this fault
        raise ValueError("no draw plays through this fault (see predict's outcome): no "
                         "played draw to pick a planning ensemble from")  # fmt: skip
    if not np.all(np.isfinite(x)):
        raise ValueError(f"the prediction's {outcome} is not finite for every draw played")
    stalled = outcomes.get("stalled")
    picks = []
    for q in quantiles:
        value = float(np.quantile(x, q, method="inverted_cdf"))
        j = int(np.flatnonzero(x == value)[0])
        th = {k: float(outcomes[k][j]) for k in _THRESHOLDS if k in outcomes}
        st = None if stalled is None or len(stalled) != x.size else bool(stalled[j])
        picks.append(PlanningPick(float(q), int(outcomes["index"][j]), value, st, th))
    return picks


def label(q: float) -> str:
    """``q05``, ``q50``, ``q97.5``: a quantile in a file name (``export --stat``'s spelling)."""
    pct = f"{100 * q:.6g}"
    return "q" + (pct if "." in pct else pct.zfill(2))


def file_name(out: Path, pick: PlanningPick) -> Path:
    """``case.raw`` -> ``case_q05.raw``: the pick's file beside ``out``."""
    return out.with_name(f"{out.stem}_{label(pick.quantile)}{out.suffix}")


def comment(pick: PlanningPick, fault: Mapping[str, Any], *, outcome: str, unit: str,
            meaning: str = "", stall_of: str | None = None) -> str:  # fmt: skip
    """The line each file of the ensemble carries (quantile, outcome, fault, draw)."""
    what = f"{outcome} ({meaning})" if meaning else outcome
    words = (f"planning ensemble: the {100 * pick.quantile:.6g}% quantile of {what}, "
             f"{pick.outcome:.6g} {unit}, in the fault {fault['name']!r} (down to "
             f"{fault['v_min']:.4g} p.u., {fault['depth']:.0%} below {fault['v_pre']:.4g}, "
             f"for {fault['duration_s']:.4g} s): posterior draw {pick.index}")  # fmt: skip
    if pick.stalled is not None and stall_of:
        words += f"; {stall_of} {'stalls' if pick.stalled else 'does not stall'} in it"
    if pick.thresholds:
        words += "; played with " + ", ".join(f"{k} {v:.4g}" for k, v in pick.thresholds.items())
    return words


def model_options(options: Mapping[str, Any] | None, pick: PlanningPick) -> dict[str, Any] | None:
    """A fit of parts' ``model_options`` with the pick's thresholds (None: nothing to set)."""
    if not options or not pick.thresholds:
        return None
    out = dict(options)
    th = pick.thresholds
    if out.get("motor_d") and "vstall" in th:
        out["motor_d_params"] = {**(out.get("motor_d_params") or {}), "vstall": th["vstall"],
                                 "tstall": th["tstall"]}  # fmt: skip
    if out.get("electronics") and "vd1" in th:
        out["vd1"], out["vd2"] = th["vd1"], th["vd2"]
    return out
