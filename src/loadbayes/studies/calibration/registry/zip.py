"""ZIP samplers under test (blocked, single-site, exact, unknown P0), their priors and bands."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.testing.sbc import SamplerUnderTest, draw_block_prior


@dataclass(frozen=True)
class ZipData:
    """Simulated ZIP data: voltages and powers (Q optional), per unit."""

    v: np.ndarray
    p: np.ndarray
    q: np.ndarray | None = None

    def columns(self) -> dict[str, np.ndarray]:  # noqa: D102
        out = {"v": self.v, "p": self.p}
        if self.q is not None:
            out["q"] = self.q
        return out


_CHANNELS = (("p", ("a1", "a2", "a3")), ("q", ("a4", "a5", "a6")))


def zip_sampler(
    name: str,
    *,
    scheme: str,
    prior: BlockPrior | None,
    n: int = 50,
    band: tuple[float, float] = (0.66, 0.89),
    with_q: bool = False,
    auto: bool = False,
    thin: int = 1,
    burn: int = 200,
    kept: int = 999,
    notes: str = "",
) -> SamplerUnderTest:
    """A ZIP sampler under test, fitted through the package's own path.

    Data: ``n`` voltages uniform on ``band`` (per unit, ``v0 = 1``), powers from the
    ZIP model with normal noise of precision ``tau``; with ``auto`` the nominal power is
    a parameter (the block ``(p0, d1, d2)``, reported as ``p0`` and the shares
    ``a_i = d_i / p0``). The fit goes through
    :class:`~loadbayes.models.zip.ZIPModel`, :func:`~loadbayes.fit.accumulate` and
    :func:`~loadbayes.fit.fit_gram` (one chain, ``burn`` then ``kept`` draws
    every ``thin``).

    Parameters
    ----------
    name : str
        Registry key.
    scheme : {"blocked", "single-site", "exact"}
        Sampler.
    prior : BlockPrior or None
        Prior of every channel's block (k = 2, or 3 with ``auto``): what the parameters
        are drawn from and what the fit uses. None: the model's weak defaults, for
        fixed-truth coverage (no prior simulator then).
    n, band, with_q, auto
        Data design.
    thin, burn, kept
        Chain settings of the fit.
    notes : str
        For the report.

    Returns
    -------
    SamplerUnderTest
    """
    channels = _CHANNELS if with_q else _CHANNELS[:1]
    params: list[str] = []
    for ch, (c1, c2, c3) in channels:
        params += ([f"{ch}0"] if auto else []) + [c1, c2, c3, f"tau_{ch}"]

    def draw_prior(rng: np.random.Generator) -> dict[str, float]:
        assert prior is not None
        out: dict[str, float] = {}
        for ch, (c1, c2, c3) in channels:
            coef, tau = draw_block_prior(prior, rng)
            if auto:
                nom, d1, d2 = coef
                out[f"{ch}0"] = float(nom)
                out[c1], out[c2] = float(d1 / nom), float(d2 / nom)
            else:
                out[c1], out[c2] = float(coef[0]), float(coef[1])
            out[c3] = 1.0 - out[c1] - out[c2]
            out[f"tau_{ch}"] = tau
        return out

    def simulate(theta: Mapping[str, float], rng: np.random.Generator) -> ZipData:
        v = rng.uniform(band[0], band[1], n)
        out = {}
        for ch, (c1, c2, c3) in channels:
            nom = theta[f"{ch}0"] if auto else 1.0
            curve = theta[c1] * v**2 + theta[c2] * v + theta[c3]
            out[ch] = nom * curve + rng.standard_normal(n) / np.sqrt(theta[f"tau_{ch}"])
        return ZipData(v, out["p"], out.get("q"))

    def fit(data: ZipData, seed: int) -> dict[str, np.ndarray]:
        from loadbayes.fit import accumulate, fit_gram
        from loadbayes.models.zip import ZIPModel

        nominal = "auto" if auto else 1.0
        model = ZIPModel(v0=1.0, p0=nominal, q0=nominal, with_q=with_q)
        priors = model.default_priors() if prior is None else {b.name: prior for b in model.blocks}
        post = fit_gram(
            model,
            accumulate(model, [data.columns()]),
            priors=priors,
            scheme=scheme,  # type: ignore[arg-type]
            sampler=SamplerSettings(
                chains=1, draws=burn + thin * kept, burn=burn, thin=thin, seed=seed
            ),
        )
        return {p: post.draws[p][0] for p in params}

    return SamplerUnderTest(
        name=name,
        parameters=tuple(params),
        draw_prior=draw_prior if prior is not None else None,
        simulate=simulate,
        fit=fit,
        kept=kept,
        notes=notes,
    )


#: Independent prior (the paper's): a1 ~ N(0.4, 0.5^2), a2 ~ N(0.3, 0.5^2),
#: tau ~ Gamma(5, rate 5 * 0.05^2), i.e. noise sd near 5% of nominal power.
ZIP_PRIOR = BlockPrior(mean=[0.4, 0.3], precision=[4.0, 4.0], shape=5.0, rate=5 * 0.05**2)
#: Conjugate normal-gamma prior: a | tau ~ N(m, (tau P)^-1), the same tau prior; P makes
#: the prior sd of a1, a2 0.5 at the prior-mean tau (400).
ZIP_PRIOR_CONJ = BlockPrior(
    mean=[0.4, 0.3], precision=[0.01, 0.01], shape=5.0, rate=5 * 0.05**2, conjugate=True
)
#: Unknown nominal power: (p0, d1, d2) ~ N((1, 0.4, 0.3), diag(0.1, 0.5, 0.5)^2).
ZIP_PRIOR_AUTO = BlockPrior(
    mean=[1.0, 0.4, 0.3], precision=[100.0, 4.0, 4.0], shape=5.0, rate=5 * 0.05**2
)
#: The paper's bus-18 voltage band: a1 and a2 on a ridge (posterior correlation ~ -0.99).
BUS18_BAND = (0.66, 0.89)
#: A wide band on which the a1-a2 posterior correlation is about -0.96.
WIDE_BAND = (0.3, 1.7)
