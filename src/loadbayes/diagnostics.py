"""Warnings that say what is known: convergence, identifiability, priors, noise on V.

Every command that samples calls :func:`fit_warnings` on its posterior before writing
it, whatever the sampler: R-hat and ESS, the combination the data do determine next to
a "cannot be told apart" warning, a prior that dominates, and (for V, P, Q data) a hint
that V carries noise, which every model here treats as exact.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np
import pandas as pd

__all__ = [
    "ESS_MIN",
    "RHAT_MAX",
    "fit_warnings",
    "identifiability_notes",
    "prior_dominance",
    "sampler_warnings",
    "voltage_noise_warning",
]

#: R-hat above this: the chains have not mixed (Vehtari et al. 2021 recommend 1.01).
RHAT_MAX = 1.01
#: Bulk or tail ESS below this: the summary's last digits are Monte Carlo noise
#: (Vehtari et al. 2021: 100 per chain for 4 chains).
ESS_MIN = 400
#: Share of V's variance in its sample-to-sample changes above which we warn of noise.
V_NOISE_SHARE = 0.05
#: Posterior sd above this fraction of the prior sd: the prior, not the data, decides.
PRIOR_SHARE = 0.5

_PAIR = re.compile(
    r"^(\w+) and (\w+) cannot be told apart on these data "
    r"\(posterior correlation ([+-]?[\d.]+)\)"
)

# The combination a ZIP pair's data determine: the slope of the load at V0.
_ZIP_SLOPE = {("a1", "a2"): ("p", 2.0, 1.0), ("a4", "a5"): ("q", 2.0, 1.0)}


def sampler_warnings(table: pd.DataFrame, *, chains: int, kept: int) -> list[str]:
    """R-hat, ESS and kept-draw warnings from a summary table (any sampler).

    Parameters
    ----------
    table : DataFrame
        :meth:`Posterior.summary` output (columns ``r_hat``, ``ess_bulk``, ``ess_tail``).
    chains, kept : int
        Number of chains and kept draws per chain.

    Returns
    -------
    list of str
    """
    out = []
    if kept < 100:
        out.append(
            f"only {kept} kept draws per chain ({chains} chains): too few for a reliable "
            "R-hat and ESS; raise --draws, or lower --burn or --thin"
        )
    if chains < 2:
        out.append("one chain: R-hat cannot check convergence; use --chains 2 or more")
    rhat = table["r_hat"].astype(float)
    bad = rhat[rhat > RHAT_MAX]
    if len(bad):
        worst = bad.idxmax()
        out.append(
            f"R-hat up to {bad.max():.3f} ({worst}; {len(bad)} parameters above {RHAT_MAX}): "
            "the chains disagree, the intervals are not to be trusted; run longer (--draws)"
        )
    ess = table[["ess_bulk", "ess_tail"]].astype(float).min(axis=1)
    low = ess[ess < ESS_MIN]
    if len(low):
        worst = low.idxmin()
        out.append(
            f"effective sample size down to {low.min():.0f} of {chains * kept} draws "
            f"({worst}; below {ESS_MIN}): the posterior means and intervals carry Monte "
            "Carlo error; run longer (--draws)"
        )
    return out


def identifiability_notes(post, *, hdi_prob: float = 0.95) -> list[str]:
    """Rewrite "cannot be told apart" warnings to say what the data do determine.

    Each pair flagged by :class:`~loadbayes.posterior.Posterior` gets the combination of
    the two that the data pin down (for a ZIP pair, ``2 a1 + a2``: the slope dP/dV at V0
    in per unit of P0; otherwise the direction of least posterior variance) with its
    interval, and says whether each alone is still determined.

    Parameters
    ----------
    post : Posterior
        The fit (its ``warnings`` are read, not changed).
    hdi_prob : float
        Probability of the central interval of the combination.

    Returns
    -------
    list of str
        ``post.warnings`` with the pair warnings replaced.
    """
    out = []
    for w in post.warnings:
        m = _PAIR.match(w)
        if not m or m.group(1) not in post.draws or m.group(2) not in post.draws:
            out.append(w)
            continue
        a, b, r = m.group(1), m.group(2), float(m.group(3))
        out.append(_pair_note(post, a, b, r, hdi_prob))
    return out


def _pair_note(post, a: str, b: str, r: float, hdi_prob: float) -> str:
    xa, xb = post.draws[a].reshape(-1), post.draws[b].reshape(-1)
    if post.model == "zip" and (a, b) in _ZIP_SLOPE:
        ch, ca, cb = _ZIP_SLOPE[(a, b)]
        what = f"{ca:g} {a} + {b} (d{ch.upper()}/dV at V0, per unit)"
    else:
        cov = np.cov(np.stack([xa, xb]))
        _, vecs = np.linalg.eigh(cov)
        u = vecs[:, 0] / vecs[np.argmax(np.abs(vecs[:, 0])), 0]
        ca, cb = float(u[0]), float(u[1])
        what = f"{ca:.3g} {a} {'+' if cb >= 0 else '-'} {abs(cb):.3g} {b}"
    comb = ca * xa + cb * xb
    lo, hi = np.quantile(comb, [(1 - hdi_prob) / 2, (1 + hdi_prob) / 2])
    known = f"the data determine {what} = {comb.mean():.4g} +/- {comb.std():.2g} "
    known += f"({100 * hdi_prob:g}% interval {lo:.4g} to {hi:.4g})"
    sd_a, sd_b = xa.std(), xb.std()
    alone = all(s <= 0.05 * max(1.0, abs(m)) for s, m in ((sd_a, xa.mean()), (sd_b, xb.mean())))
    if any("the load level changes over the record" in w for w in post.warnings):
        # A wider voltage range would not help a fit whose level is confounded with V:
        # the advice is the confounding warning's (issue 22).
        return (
            f"{a} and {b} cannot be told apart on these data (posterior correlation "
            f"{r:+.4f}); {known}, but see the warning on the load level: it is confounded."
        )
    if alone:
        return (
            f"{a} and {b} are strongly correlated (posterior correlation {r:+.4f}) but each "
            f"is still determined ({a} = {xa.mean():.4g} +/- {sd_a:.2g}, {b} = "
            f"{xb.mean():.4g} +/- {sd_b:.2g}); {known}."
        )
    more = (
        "a wider voltage range or an informative prior on one of them"
        if post.model in ("zip", "exp")
        else "a deeper or longer disturbance (more variation of speed and flux) or an "
        "informative prior on one of them"
    )
    return (
        f"{a} and {b} cannot be told apart on these data (posterior correlation {r:+.4f}; "
        f"{a} +/- {sd_a:.2g}, {b} +/- {sd_b:.2g} alone); {known}. {more[0].upper()}"
        f"{more[1:]} would separate them."
    )


def prior_dominance(post, prior_sd: Mapping[str, float]) -> list[str]:
    """Coefficients whose posterior is mostly their prior.

    Parameters
    ----------
    post : Posterior
    prior_sd : mapping
        Prior standard deviation of each coefficient the user set a prior on.

    Returns
    -------
    list of str
        One warning per coefficient whose posterior sd exceeds half its prior sd.
    """
    out = []
    for name, sd in prior_sd.items():
        if name not in post.draws or not sd > 0:
            continue
        s = float(np.std(post.draws[name]))
        if s > PRIOR_SHARE * sd:
            out.append(
                f"the prior decides {name}: its posterior sd {s:.3g} is close to the prior "
                f"sd {sd:.3g}, so the data add little; the result repeats the prior"
            )
    return out


def voltage_noise_warning(v: np.ndarray, *, wording: str = "cli", eiv: bool = True) -> str | None:
    """A warning when V looks noisy (errors in variables), or None.

    Parameters
    ----------
    v : ndarray
        Voltages in row (time) order.
    wording : {"cli", "python"}
        Name the errors-in-variables option as ``--v-noise`` or ``v_noise=``.
    eiv : bool
        The fit has that option (the ZIP fit; the exponential one has not).

    Returns
    -------
    str or None

    Notes
    -----
    Every model here treats V as exact. Noise on V of variance ``s2`` biases the ZIP
    shares toward zero slope by the factor ``var(V_true) / var(V)`` (attenuation). If
    the true V moves slowly from row to row, half the variance of the first differences
    estimates ``s2`` (from above: fast true changes count too). We warn when that is
    more than 5% of the variance of V. It cannot tell noise from a V that truly changes
    fast (the warning says so); and when the differences are as large as V's whole
    spread (half their variance at least half of V's), the rows are no time series
    (independent experiments, shuffled records) and it stays silent.
    """
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 20:
        return None
    with np.errstate(all="ignore"):  # an absurd voltage is refused elsewhere by name
        total = float(np.var(v))
        share = 0.5 * float(np.var(np.diff(v))) / total if total > 0 else 0.0
    if not (np.isfinite(share) and share > V_NOISE_SHARE):
        return None
    if share >= 0.5:
        # Rows that are no time series (independent experiments, like the paper's power
        # flows, or shuffled records): row-to-row differences say nothing about noise.
        return None
    pct = f"{100 * share:.0f}%"
    head = (
        f"V changes from row to row by {pct} of its variance (half the variance of its "
        "differences): if that is measurement noise on V, the shares are biased by up to "
        f"about {pct} toward a flat load, because the fit treats V as exact"
    )
    if not eiv:
        return f"{head} (errors in variables, docs/zip.md); ignore this if V really moves that fast"
    sd = float(np.sqrt(0.5 * np.var(np.diff(v))) / np.median(v))
    opt = (
        (f"--v-noise SD (the instrument's sd in per unit; at most {sd:.2g} here) or "
         "--v-noise auto (with Q)")
        if wording == "cli"
        else (f"v_noise=SD (the instrument's sd in per unit; at most {sd:.2g} here) or "
              "v_noise='auto' (with Q)")
    )  # fmt: skip
    return (
        f"{head}; {opt} fits a latent true voltage instead (errors in variables, "
        "docs/zip.md; each iteration then visits every sample: 2.6 s instead of 0.05 s "
        "on a day of 1440 rows); ignore this if V really moves that fast"
    )


def fit_warnings(
    post,
    table: pd.DataFrame,
    *,
    hdi_prob: float = 0.95,
    prior_sd: Mapping[str, float] | None = None,
) -> list[str]:
    """Every warning of a fit, in order, without repeats; also stored on ``post``.

    Parameters
    ----------
    post : Posterior
    table : DataFrame
        Its summary at ``hdi_prob``.
    hdi_prob : float
    prior_sd : mapping, optional
        See :func:`prior_dominance`.

    Returns
    -------
    list of str
    """
    chains, kept = post.n_chains, post.n_draws
    ws = identifiability_notes(post, hdi_prob=hdi_prob)
    ws += sampler_warnings(table, chains=chains, kept=kept)
    ws += prior_dominance(post, prior_sd or {})
    out = list(dict.fromkeys(ws))
    post.warnings[:] = out
    return out
