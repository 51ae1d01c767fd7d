"""How deep a sag must be before motor D stalls: the planner's summary of a sweep.

A sweep (``predict.sweep``) gives, at each sag depth, the share of the posterior's draws
in which motor D stalls. Where each draw stalls at every depth past its own stall depth
(a deeper sag of the same duration holds the load bus lower), that share is the
posterior's distribution function of the stall depth, read at the swept depths: the
depth where it crosses one half is the stall depth's median, and the depths where it
crosses ``(1 - prob) / 2`` and ``(1 + prob) / 2`` (0.025 and 0.975 at ``prob`` 0.95)
bound its interval. :func:`stall_depth` finds each crossing by linear interpolation
between the two swept depths around it (the first depth whose share reaches the level,
so the Monte Carlo noise of a non-monotone sweep takes the shallowest crossing), and
gives None, said in words, where the sweep does not cross a level: the share is already
at it at the shallowest depth swept, or never reaches it at the deepest.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["crossing", "stall_depth"]


def crossing(depths: Sequence[float], share: Sequence[float], level: float):
    """The depth where ``share`` first reaches ``level`` (linear between depths), and why not.

    ``(depth, None)``, or ``(None, reason)`` with ``reason`` ``"below"`` (the share is
    under the level at every swept depth) or ``"above"`` (already at it at the first).
    """
    x = np.asarray(depths, dtype=float)
    y = np.asarray(share, dtype=float)
    hit = np.flatnonzero(y >= level)
    if hit.size == 0:
        return None, "below"
    i = int(hit[0])
    if i == 0:
        return None, "above"
    x0, x1, y0, y1 = x[i - 1], x[i], y[i - 1], y[i]
    return float(x0 + (x1 - x0) * (level - y0) / (y1 - y0)), None


def stall_depth(depths: Sequence[float], probabilities: Sequence[float | None], *,
                prob: float = 0.95, duration: float | None = None,
                part: str = "motor D") -> dict[str, Any]:  # fmt: skip
    """The sag depth where a part's stall probability crosses one half, with its interval.

    ``depths`` ascending, ``probabilities`` the stall probability at each (None where
    the model has no part that stalls); ``part`` names what stalls (motor D; a
    ``zip+motor`` fit's induction motor). Returns ``{"depth", "interval": [lo, hi], "levels",
    "message"}``: ``depth`` the crossing of 0.5, ``interval`` those of ``(1 - prob) / 2``
    and ``(1 + prob) / 2``, each None where the sweep does not cross it; ``message`` says
    it in words (module docstring).
    """
    x = np.asarray(depths, dtype=float)
    if x.size == 0 or np.any(np.diff(x) <= 0):
        raise ValueError("stall_depth: the swept depths must be ascending and not empty")
    if len(probabilities) != x.size:
        raise ValueError("stall_depth: one stall probability per swept depth")
    levels = [(1.0 - prob) / 2.0, 0.5, (1.0 + prob) / 2.0]
    if any(p is None for p in probabilities):
        return {"depth": None, "interval": [None, None], "levels": levels,
                "message": f"the model has no {part}: nothing stalls"}  # fmt: skip
    found = [crossing(x, probabilities, lv) for lv in levels]
    lo, mid, hi = (d for d, _ in found)
    span = f"{x[0]:.3g} to {x[-1]:.3g}"
    of = f" of sags lasting {duration:g} s" if duration is not None else ""
    words = []
    if mid is not None:
        words.append(f"{part} stalls with probability 0.5 at a sag {mid:.3g} deep{of}")
    # One sentence per side: the highest level already reached, the lowest never reached.
    above = [lv for (_, why), lv in zip(found, levels, strict=True) if why == "above"]
    below = [lv for (_, why), lv in zip(found, levels, strict=True) if why == "below"]
    if above:
        words.append(f"the stall probability is already {max(above):g} or more at the "
                     f"shallowest depth swept ({x[0]:.3g})")  # fmt: skip
    if below:
        words.append(f"the stall probability stays below {min(below):g} up to the deepest "
                     f"depth swept ({x[-1]:.3g})")  # fmt: skip
    if lo is not None and hi is not None:
        words.append(f"{prob:.0%} of the draws stall between depths {lo:.3g} and {hi:.3g}")
    else:
        words.append(f"the {prob:.0%} interval of the stall depth is not within the sweep "
                     f"({span})")  # fmt: skip
    return {"depth": mid, "interval": [lo, hi], "levels": levels,
            "message": "; ".join(words) + "."}  # fmt: skip
