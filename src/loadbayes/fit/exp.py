"""Exponential-load fits: the log-linear Gibbs form and Metropolis within Gibbs."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from loadbayes.fit.core import accumulate, as_columns, fit, fit_gram
from loadbayes.io.errors import DataError
from loadbayes.models.exponential import ExponentialModel, Noise, Nominal

__all__ = ["fit_exp"]


def fit_exp(
    data: Any,
    *,
    v0: float = 1.0,
    p0: Nominal = 1.0,
    q0: Nominal = 1.0,
    with_q: bool | None = None,
    with_f: bool | None = None,
    f0: float = 60.0,
    noise: Noise = "additive",
    priors: Mapping[str, Any] | None = None,
    chains: int = 4,
    draws: int = 40_000,
    burn: int = 5_000,
    thin: int = 1,
    init: str = "prior",
    seed: int = 0,
    settings: Mapping[str, Any] | None = None,
    warnings: list[str] | None = None,
):
    """Posterior of the exponential load model from in-memory measurements.

    Parameters
    ----------
    data : mapping or DataFrame
        Columns ``v``, ``p``, and ``q`` (reactive power) and ``f`` (frequency) when
        present; per unit or any units consistent with ``v0``, ``p0``, ``q0``, ``f0``.
    v0, p0, q0 : float or "auto"
        Nominal values (``auto`` estimates P0 / Q0).
    with_q, with_f : bool, optional
        Fit Q / the frequency coefficients; by default when the column is present.
    f0 : float
        Nominal frequency (``df = (f - f0) / f0``).
    noise : {"additive", "multiplicative"}
        Noise model and sampler (module notes).
    priors : mapping, optional
        Per channel: :class:`ExpPriors` (additive) or :class:`BlockPrior` of the
        log-linear block (multiplicative); weak defaults otherwise.
    chains, draws, burn, thin, init, seed
        Sampler settings; ``draws`` includes burn-in.
    settings, warnings
        Recorded with the result.

    Returns
    -------
    Posterior
        Draws of np (nq), kpf (kqf) with frequency, p0 (q0) with auto, tau_p (tau_q).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> v = rng.uniform(0.85, 1.05, 400)
    >>> p = v**1.5 + rng.normal(0, 0.01, 400)
    >>> post = fit_exp({"v": v, "p": p}, draws=2000, burn=500, chains=2)
    >>> round(post.mean()["np"], 1)
    1.5
    """
    cols = as_columns(data)
    for c in ("v", "p"):
        if c not in cols:
            raise DataError(f"missing column '{c}'")
    if with_q is None:
        with_q = "q" in cols
    if with_f is None:
        with_f = "f" in cols
    if with_f and "f" not in cols:
        raise DataError("frequency dependence needs a column 'f'")
    if burn >= draws:
        raise ValueError(f"burn-in ({burn}) must be smaller than the draws ({draws})")
    model = ExponentialModel(v0=v0, p0=p0, q0=q0, with_q=with_q, with_f=with_f, f0=f0, noise=noise)
    v = cols["v"]
    if v.size and not np.all(v > 0):
        i = int(np.flatnonzero(~(v > 0))[0])
        raise DataError(f"voltage must be positive, got {v[i]:g}", column="v", row=i + 1)
    keep = ["v", "p"] + (["q"] if with_q else []) + (["f"] if with_f else [])
    observed = {k: cols[k] for k in keep} if v.size <= 200_000 else None
    base = dict(settings or {})
    base.update(v0=v0, p0=p0, q0=q0 if with_q else None, f0=f0 if with_f else None, noise=noise)
    if noise == "multiplicative":
        gram = accumulate(model, [cols])
        post = fit_gram(
            model,
            gram,
            priors=priors or model.default_priors(),
            chains=chains,
            draws=draws,
            burn=burn,
            thin=thin,
            init=init,
            seed=seed,
            observed=observed,
            settings=base,
            warnings=warnings or (),
        )
        post.settings["scheme"] = "blocked (log-linear)"
        return post
    warn = list(warnings or [])
    span = float(np.ptp(v) / v0)
    if span < 0.02:
        warn.append(
            f"voltage spans only {100 * span:.2g}% of v0: the exponent is poorly determined "
            "on so narrow a band."
        )
    return fit(
        model,
        cols,
        priors=priors,
        chains=chains,
        draws=draws,
        burn=burn,
        thin=thin,
        seed=seed,
        observed=observed,
        settings=base,
        warnings=warn,
    )
