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
hidden behind an R-hat that no longer sees it. A gap above :data:`NEAR_GAP` but within
the restart's is said too (a chain may be entering or leaving another mode: the chains
are not moved, the gap is named). A mode no chain found is not seen; so that both of
``cmld-lite``'s are found, half the chains start about the least-squares fit of P and Q
alone (``nls.NLSResult.others``), the other half about the fit of every channel.
"""

from __future__ import annotations

import copy
import math

import numpy as np

__all__ = ["NEAR_GAP", "RESTART_GAP", "late_gaps", "restart_lagging", "words"]

#: Log-density gap (medians over the late burn-in) past which a chain is in a lower mode.
RESTART_GAP = 10.0
#: A smaller gap the fit names without moving a chain (:func:`words`).
NEAR_GAP = 5.0


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


def late_gaps(late_lp: list[list[float]]) -> list[float]:
    """Each chain's late burn-in median log density below the best chain's (0 for it)."""
    med = [float(np.median(x)) if len(x) else -math.inf for x in late_lp]
    top = max(med)
    return [top - m if math.isfinite(top) else math.nan for m in med]


def words(moved: list[tuple[int, int, float]], chains: int,
          gaps: list[float] | None = None) -> str | None:  # fmt: skip
    """What a fit whose chains ended their burn-in apart says (None: nothing to say).

    ``moved``: :func:`restart_lagging`'s answer; ``gaps``: :func:`late_gaps` before it.
    """
    moved_k = {k for k, _, _ in moved}
    near = [g for k, g in enumerate(gaps or []) if k not in moved_k and NEAR_GAP < g]
    out = []
    if moved:
        big = ", ".join(f"{g:.0f}" for _, _, g in moved)
        out.append(f"the posterior has more than one mode: {len(moved)} of {chains} chains "
                   "ended their burn-in in a mode whose log density was lower than the best "
                   f"chain's by {big} and went on from the best chain's state; the draws are "
                   "the higher mode's")  # fmt: skip
    if near:
        small = ", ".join(f"{g:.0f}" for g in sorted(near, reverse=True))
        out.append(f"{len(near)} of {chains} chains ended their burn-in with a log density "
                   f"lower than the best chain's by {small} (more than {NEAR_GAP:g}, under "
                   f"the restart's {RESTART_GAP:g}): they may be in another mode or still "
                   "entering one, "
                   "and were not moved; the R-hat says whether they met")  # fmt: skip
    if not out:
        return None
    return "; ".join(out) + (" (a mode no chain found is not seen: more chains or other "
                             "seeds would show one)")  # fmt: skip
