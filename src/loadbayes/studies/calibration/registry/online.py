"""The online tracker under test: exact, sliding window, random-walk drift."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.studies.calibration.registry.zip import ZIP_PRIOR_CONJ
from loadbayes.testing.sbc import SamplerUnderTest, draw_block_prior


def online_sampler(
    name: str,
    *,
    mode: str,
    prior: BlockPrior | None = None,
    n: int = 50,
    band: tuple[float, float] = (0.66, 0.89),
    drift_sd: float = 0.5,
    window: int = 30,
    kept: int = 999,
    notes: str = "",
) -> SamplerUnderTest:
    """The online tracker (:func:`loadbayes.inference.online.track`), its last posterior.

    ``mode`` is ``"exact"`` (recursive Bayes on every sample), ``"window"`` (the last
    ``window`` samples) or ``"drift"`` (random walk ``a_t = a_(t-1) + w_t``,
    ``w_t | tau ~ N(0, drift_sd^2 / tau)``, the truth being the coefficients at the last
    sample). The tracker reports each marginal (Student-t) by its mean, central interval
    and degrees of freedom, and the noise by ``sqrt(beta / a)`` and ``2a``; the fit turns
    those back into the marginals and draws ``kept`` values from each (forgetting is an
    approximation, not a generative model, so it has no SBC).
    """
    prior = prior if prior is not None else ZIP_PRIOR_CONJ
    params = ("a1", "a2", "a3", "tau_p")
    w_cov = drift_sd**2 * np.eye(2)

    def draw_prior(rng: np.random.Generator) -> dict[str, Any]:
        # The parameters are the coefficients at the last sample. With drift they end a
        # random walk, which is part of the prior (it does not depend on the data); the
        # whole path rides along under "_path" for the data simulator.
        coef, tau = draw_block_prior(prior, rng)
        path = np.tile(coef, (n, 1))
        if mode == "drift":  # the walk moves before every sample, the first included
            path = path + np.cumsum(rng.standard_normal((n, 2)), axis=0) * (drift_sd / np.sqrt(tau))
        out: dict[str, Any] = {"a1": float(path[-1, 0]), "a2": float(path[-1, 1])}
        out["a3"] = 1.0 - out["a1"] - out["a2"]
        out["tau_p"] = tau
        out["_path"] = path
        return out

    def simulate(theta: Mapping[str, Any], rng: np.random.Generator) -> dict[str, Any]:
        v = rng.uniform(band[0], band[1], n)
        x = v - 1.0
        z = np.column_stack([x * (v + 1.0), x])
        r = np.einsum("ij,ij->i", z, theta["_path"])
        return {"z": z, "r": r + rng.standard_normal(n) / np.sqrt(theta["tau_p"])}

    def fit(data: Mapping[str, Any], seed: int) -> dict[str, np.ndarray]:
        from scipy import stats as st

        from loadbayes.inference.online import OnlinePrior, track

        res = track(
            data["z"], data["r"], prior=OnlinePrior.from_block_prior(prior), prob=0.95,
            window=window if mode == "window" else None,
            drift=w_cov if mode == "drift" else None,
            contrasts=np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]]),
            offsets=np.array([0.0, 0.0, 1.0]),
        )  # fmt: skip
        rng = np.random.default_rng(seed)
        dof = float(res.dof[-1])
        q = float(st.t.ppf(0.975, dof))
        out = {}
        for j, p in enumerate(("a1", "a2", "a3")):
            loc = float(res.mean[-1, j])
            scale = (float(res.high[-1, j]) - loc) / q
            out[p] = loc + scale * rng.standard_t(dof, kept)
        a, beta = dof / 2.0, float(res.scale[-1]) ** 2 * dof / 2.0
        out["tau_p"] = rng.gamma(a, 1.0 / beta, kept)
        return out

    return SamplerUnderTest(name, params, draw_prior, simulate, fit, kept, notes)
