"""Whether a prediction's draws are the posterior's: the fit's chains, fault by fault.

A prediction pools every chain's draws. Where the chains have not met, the band is of
the places the chains happened to sample, not of the posterior, and it can be narrow
and wrong at once, said nowhere. Measured (issue 37, GridDyn's default CMLD load, noise
seed 16, ``cmld-lite`` fitted to the 13 % fault alone, 2 x 2000 draws, sampler seed 7):
the two chains sat on the feeder's X at 0.207 [0.191, 0.223] and 0.150 [0.136, 0.163]
(R-hat of ``log_x_fd`` 1.85, bulk ESS 2.9; the fit with the 25 % fault too puts it at
0.08), their late burn-in log densities too close for ``restart.py`` to name a lower
mode. Played through the deep 46 % fault, 2 of chain 1's 146 picked draws played (90
collapsed, 54 failed numerically) against 114 of chain 2's 154: the band was chain 2's
alone, 0.42 p.u. wide in P, and held 8 % of GridDyn's P and 7 % of its Q. Sampler
seeds 8 and 9 and a run of 2 x 8000 draws gave the feeder's X at 0.12-0.20 per chain
and coverage of P 0.28, 0.08, 0.10; each said "not converged" only in the fit's
warnings, and the prediction said nothing.

So :func:`judge` says it where it matters, in the prediction itself:

- **not converged**: the largest R-hat of the sampled coordinates the draws are played
  with (``model.theta_names``) is not below :data:`~loadbayes.diagnostics.RHAT_MAX`;
- **the chains disagree about this fault**: for some outcome of a draw (plays with
  motor D running, plays stalled, collapses, fails numerically), the 95 % Jeffreys
  intervals of its share among two chains' picked draws do not overlap. The draws of
  a chain are autocorrelated, so these intervals are too narrow and the rule is quick to
  call a disagreement; it is a warning, and it is meant to be.

Nothing is said (None, and the prediction's JSON is as it was) for a fit of one chain
(R-hat needs two) or whose chains have converged and agree.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.diagnostics import RHAT_MAX
from loadbayes.fit.composite.predict_scope import jeffreys
from loadbayes.models.parts_play import COLLAPSES, FAILS, PLAYS

__all__ = ["CLASSES", "judge"]

#: The outcomes compared between chains: ``(key, words)``.
CLASSES = (
    ("plays_running", "play with motor D running"),
    ("plays_stalled", "play stalled"),
    ("collapses", "collapse"),
    ("fails_numerically", "fail numerically"),
)


def _classes(why: np.ndarray, stalled: np.ndarray) -> np.ndarray:
    """Each picked draw's class (an index into :data:`CLASSES`; -1 for none of them)."""
    out = np.full(why.shape, -1)
    out[(why == PLAYS) & ~stalled] = 0
    out[(why == PLAYS) & stalled] = 1
    out[why == COLLAPSES] = 2
    out[why == FAILS] = 3
    return out


def judge(post, model, pick: np.ndarray, why: np.ndarray, stalled: np.ndarray,
          prob: float = 0.95) -> dict[str, Any] | None:  # fmt: skip
    """What the prediction says of its chains (module docstring); None: nothing to say.

    ``pick``: the pooled indices of the draws played (chain-major, ``(chain, draw)``
    flattened); ``why``: each one's outcome (``parts_play``'s codes); ``stalled``: each
    one's motor D stalled (False where it did not play, or the model has no motor D).
    """
    n_chains, n_draws = post.n_chains, post.n_draws
    if n_chains < 2:
        return None
    from loadbayes.core.convergence import summarize

    names = [n for n in model.theta_names if n in post.draws]
    x = np.stack([np.asarray(post.draws[n], dtype=float) for n in names])
    rhat = summarize(x, tail=False)["r_hat"]
    finite = np.isfinite(rhat)
    worst = int(np.argmax(np.where(finite, rhat, -np.inf))) if finite.any() else None
    r_max = float(rhat[worst]) if worst is not None else None
    converged = r_max is None or r_max < RHAT_MAX
    cls = _classes(np.asarray(why), np.asarray(stalled, dtype=bool))
    chain = np.asarray(pick) // n_draws
    per = []
    for c in range(n_chains):
        mine = cls[chain == c]
        n = int(mine.size)
        row: dict[str, Any] = {"chain": c + 1, "n": n}
        for k, (key, _) in enumerate(CLASSES):
            m = int(np.sum(mine == k))
            row[key] = {"n": m, "share": m / n if n else None,
                        "interval": jeffreys(m, n, prob) if n else [0.0, 1.0]}  # fmt: skip
        per.append(row)
    apart = []  # (class key, chain a, chain b) whose intervals do not overlap
    for key, _ in CLASSES:
        for a in range(n_chains):
            for b in range(a + 1, n_chains):
                if per[a]["n"] and per[b]["n"]:
                    ia, ib = per[a][key]["interval"], per[b][key]["interval"]
                    if ia[1] < ib[0] or ib[1] < ia[0]:
                        apart.append((key, a + 1, b + 1))
    if converged and not apart:
        return None
    r_words = (f"R-hat up to {r_max:.2f} ({names[worst]})" if r_max is not None
               else "R-hat not computed")  # fmt: skip
    if apart:
        shown = [r for r in per if r["n"]]
        each = "; ".join(
            f"chain {r['chain']}'s {r['n']}: " + ", ".join(
                f"{r[key]['share']:.0%} {w}" for key, w in CLASSES if r[key]["n"])
            for r in shown)  # fmt: skip
        message = (
            f"the fit's chains disagree about this fault ({each}; {r_words}): the posterior "
            "has more than one mode here that the sampler did not mix, and the band holds "
            "whichever the chains found, not the posterior's spread: it may be far too "
            "narrow. Not an answer: fit again with more chains and more draws (--chains, "
            "--draws, --burn) until they agree"
        )
    else:
        message = (
            f"the fit's chains have not converged ({r_words}), though their draws agree "
            "about this fault: the band is of draws that may not yet span the posterior, "
            "and a longer fit may move or widen it (--draws, --burn)"
        )
    return {
        "converged": converged,
        "r_hat_max": r_max,
        "r_hat_worst": names[worst] if worst is not None else None,
        "disagree": bool(apart),
        "apart": [{"outcome": k, "chains": [a, b]} for k, a, b in apart],
        "per_chain": per,
        "rule": (
            f"not converged: an R-hat of the sampled coordinates played not below "
            f"{RHAT_MAX}; disagree: some outcome's share has disjoint {prob:.0%} "
            "Jeffreys intervals in two chains (the draws' autocorrelation ignored: "
            "quick to call a disagreement)"
        ),  # fmt: skip
        "message": message,
    }
