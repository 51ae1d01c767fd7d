"""Chains left in a lower mode at the end of burn-in, restarted where the best chain is.

``cmld-lite`` on the real record's first fault has two modes (docs/composite.md, "Two
modes of cmld-lite"): one fits P and Q and leaves the negative-sequence current to its
noise (``tau_i2`` about 60), the other fits that current with a fast motor A at the
price of P (``tau_i2`` about 1,000, ``tau_p`` half the first's); the first's joint log
density is higher by about 22 at its typical draws. A random walk does not cross
between them, so which mode a chain keeps depends on where its burn-in went, and the
chains disagree (R-hat 1.5-3).

At the end of burn-in (discarded draws: this only chooses where the kept chains start),
each chain's joint log density (the collapsed density with the noise precisions' prior)
over the second half of its burn-in is summarised by its median; a chain whose median
is more than :data:`RESTART_GAP` below the best chain's is moved to that chain's state
(and its move's adapted scales) and goes on with its own generator. Within one mode the
chains' medians differ by the spread of the log density over its typical set, about
``sqrt(d / 2)`` (4 for ``cmld-lite``'s 30 coordinates), so a gap of 10 is another mode.
The fit says so in words (:func:`words`): the lower mode is named with its gap, not
hidden behind an R-hat that no longer sees it. A mode no chain found is not seen.
"""

from __future__ import annotations

import copy
import math

import numpy as np

__all__ = ["RESTART_GAP", "restart_lagging", "words"]

#: Log-density gap (medians over the late burn-in) past which a chain is in a lower mode.
RESTART_GAP = 10.0


def restart_lagging(chains: list, late_lp: list[list[float]]) -> list[tuple[int, int, float]]:
    """Move each lagging chain's state to the best chain's; ``(chain, best, gap)`` each.

    ``chains``: each chain's :class:`~loadbayes.inference.chain.Chain` (its ``state`` is
    replaced by a copy); ``late_lp``: each chain's log densities over its late burn-in.
    """
    med = [float(np.median(x)) if len(x) else -math.inf for x in late_lp]
    best = int(np.argmax(med))
    if not math.isfinite(med[best]):
        return []
    moved = []
    for k, chain in enumerate(chains):
        gap = med[best] - med[k]
        if k != best and math.isfinite(gap) and gap > RESTART_GAP:
            chain.state = copy.deepcopy(chains[best].state)
            moved.append((k, best, gap))
    return moved


def words(moved: list[tuple[int, int, float]], chains: int) -> str | None:
    """The sentence a fit with restarted chains says (None: none restarted)."""
    if not moved:
        return None
    gaps = ", ".join(f"{g:.0f}" for _, _, g in moved)
    return (f"the posterior has more than one mode: {len(moved)} of {chains} chains ended "
            "their burn-in in a mode whose log density was lower than the best chain's by "
            f"{gaps} and went on from the best chain's state; the draws are the higher "
            "mode's (a mode no chain found is not seen: more chains or other seeds would "
            "show one)")  # fmt: skip
