"""The Student-t ZIP sampler under test, with ``nu`` fixed or drawn from its own prior."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.studies.calibration.registry.zip import ZIP_PRIOR, ZipData
from loadbayes.testing.sbc import SamplerUnderTest, draw_block_prior


def _draw_nu(rng: np.random.Generator) -> float:
    """Draw nu from the robust sampler's prior: Gamma(shape, rate) truncated to its bounds."""
    from loadbayes.inference.robust import NU_BOUNDS, NU_PRIOR

    while True:
        nu = float(rng.gamma(NU_PRIOR[0], 1.0 / NU_PRIOR[1]))
        if NU_BOUNDS[0] <= nu <= NU_BOUNDS[1]:
            return nu


def robust_sampler(
    name: str,
    *,
    nu: float | str,
    prior: BlockPrior | None = None,
    n: int = 50,
    band: tuple[float, float] = (0.66, 0.89),
    thin: int = 5,
    burn: int = 300,
    kept: int = 499,
    notes: str = "",
) -> SamplerUnderTest:
    """The Student-t ZIP sampler (:func:`loadbayes.fit.fit_robust`), P only.

    Data: ZIP with Student-t noise of scale ``1/sqrt(tau)`` and ``nu`` degrees of freedom
    (fixed, or drawn from the sampler's own prior on ``nu`` with ``nu="auto"``).
    """
    prior = prior if prior is not None else ZIP_PRIOR
    params = ("a1", "a2", "a3", "tau_p") + (("nu_p",) if nu == "auto" else ())

    def draw_prior(rng: np.random.Generator) -> dict[str, float]:
        coef, tau = draw_block_prior(prior, rng)
        out = {"a1": float(coef[0]), "a2": float(coef[1]), "tau_p": tau}
        out["a3"] = 1.0 - out["a1"] - out["a2"]
        if nu == "auto":
            out["nu_p"] = _draw_nu(rng)
        return out

    def simulate(theta: Mapping[str, float], rng: np.random.Generator) -> ZipData:
        v = rng.uniform(band[0], band[1], n)
        dof = theta["nu_p"] if nu == "auto" else float(nu)
        curve = theta["a1"] * v**2 + theta["a2"] * v + theta["a3"]
        return ZipData(v, curve + rng.standard_t(dof, n) / np.sqrt(theta["tau_p"]))

    def fit(data: ZipData, seed: int) -> dict[str, np.ndarray]:
        from loadbayes.fit import fit_robust
        from loadbayes.models.zip import ZIPModel

        post = fit_robust(
            ZIPModel(with_q=False), data.columns(), priors={"p": prior}, nu=nu,  # type: ignore[arg-type]
            sampler=SamplerSettings(
                chains=1, draws=burn + thin * kept, burn=burn, thin=thin, seed=seed
            ),
        )  # fmt: skip
        return {p: post.draws[p][0] for p in params}

    return SamplerUnderTest(name, params, draw_prior, simulate, fit, kept, notes)
