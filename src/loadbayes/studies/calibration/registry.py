"""The samplers under test: one :class:`~loadbayes.testing.sbc.SamplerUnderTest` each.

:data:`REGISTRY` is what the SBC and coverage tests (``tests/statistical``) and
``make validate`` iterate over. To put a new sampler under test (the exponential model,
a composite ZIP + motor estimator), write its prior simulator, data simulator and fit
function and add one entry to :func:`_entries`; nothing else changes.

Every fit goes through the package's own path (the model's Gram columns, the block
statistics, the sampler, the transforms), with one chain thinned until the kept draws
are nearly independent; the lag-1 autocorrelation of what is kept is reported by SBC.

Designs (why they are what they are)
------------------------------------
ZIP, blocked and exact: the paper's bus-18 voltage band (0.66-0.89 p.u.), where a1 and
a2 sit on a ridge (posterior correlation near -0.99): the case blocking is for.
ZIP, single-site: one coefficient at a time crawls along that ridge (lag-1
autocorrelation ~0.98 per sweep), so its SBC uses a wide band (0.3-1.7 p.u., correlation
about -0.96) and keeps one sweep in 50; the ridge itself is covered by the comparison
with the exact posterior in ``tests/statistical/test_zip_posterior.py``.
Motor: a clean simulated record of the small industrial motor (the default 25% sag),
every 10th sample (n = 301), T0 given; the targets are redrawn from the regression model
given the coefficients, with one noise precision per block as the model has it.
Student-t: ZIP P on the bus-18 band with t noise (nu fixed at 4, or drawn from the
sampler's own prior on nu). Online: the tracker's last posterior, exact, over a sliding
window, and with random-walk drift (then the truth is the end of the simulated walk).
Composite: ``studies/calibration/composite_sbc.py`` (a short sag, the motor's scale-free
coordinates, the seven linear coefficients and the noise precisions drawn from the fit's
prior); 200 replications in CI (each fit runs a few thousand ODE solves).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.studies.calibration.composite_sbc import composite_sampler
from loadbayes.testing.sbc import SamplerUnderTest, draw_block_prior

__all__ = [
    "BUS18_BAND",
    "REGISTRY",
    "WIDE_BAND",
    "ZIP_PRIOR",
    "ZIP_PRIOR_AUTO",
    "ZIP_PRIOR_CONJ",
    "im_sampler",
    "im_truth",
    "online_sampler",
    "robust_sampler",
    "zip_sampler",
]


# ------------------------------------------------------------------------------ ZIP
@dataclass(frozen=True)
class _ZipData:
    v: np.ndarray
    p: np.ndarray
    q: np.ndarray | None = None

    def columns(self) -> dict[str, np.ndarray]:
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

    def simulate(theta: Mapping[str, float], rng: np.random.Generator) -> _ZipData:
        v = rng.uniform(band[0], band[1], n)
        out = {}
        for ch, (c1, c2, c3) in channels:
            nom = theta[f"{ch}0"] if auto else 1.0
            curve = theta[c1] * v**2 + theta[c2] * v + theta[c3]
            out[ch] = nom * curve + rng.standard_normal(n) / np.sqrt(theta[f"tau_{ch}"])
        return _ZipData(v, out["p"], out.get("q"))

    def fit(data: _ZipData, seed: int) -> dict[str, np.ndarray]:
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
            chains=1,
            draws=burn + thin * kept,
            burn=burn,
            thin=thin,
            seed=seed,
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


# ---------------------------------------------------------------------------- motor
_IM_COEFS = ("b1", "b2", "b3", "ab", "ac")
_IM_TAUS = ("tau_e", "tau_w", "tau_i")
_IM_BLOCKS = (("flux", ("b1", "b2"), "tau_e"), ("speed", ("b3",), "tau_w"),
              ("current", ("ab", "ac"), "tau_i"))  # fmt: skip


@functools.lru_cache(maxsize=4)
def _im_record(motor: str, every: int) -> tuple[dict[str, np.ndarray], dict]:
    """The clean states of a simulated record (the fixed design of the motor SBC)."""
    from loadbayes.cases.motor_sim import simulate

    df = simulate(motor, noise=0.0, seed=0)
    cols = {k: df[k].to_numpy()[::every].copy() for k in ("ud", "uq", "ed", "eq", "w")}
    return cols, dict(df.attrs)


def _im_targets(
    states: Mapping[str, np.ndarray], theta: Mapping[str, float], t0: float, wb: float,
    currents: str, rng: np.random.Generator,
) -> dict[str, np.ndarray]:  # fmt: skip
    """Draw the targets of the regression model given the coefficients.

    Currents first (they are regressors of the measured form), then the flux and speed
    equations given them; with modelled currents those use the model's currents.
    """
    ud, uq, ed, eq, w = (states[k] for k in ("ud", "uq", "ed", "eq", "w"))
    n = ed.size
    dd, dq = ud - ed, uq - eq
    ab, ac = theta["ab"], theta["ac"]
    sd_i, sd_e, sd_w = (1.0 / np.sqrt(theta[k]) for k in ("tau_i", "tau_e", "tau_w"))
    id_ = ab * dd + ac * dq + sd_i * rng.standard_normal(n)
    iq = ab * dq - ac * dd + sd_i * rng.standard_normal(n)
    if currents == "measured":
        rd, rq = id_, iq
    else:
        rd, rq = ab * dd + ac * dq, ab * dq - ac * dd
    yed = theta["b1"] * ed + theta["b2"] * rq + sd_e * rng.standard_normal(n)
    yeq = theta["b1"] * eq - theta["b2"] * rd + sd_e * rng.standard_normal(n)
    te = ed * rd + eq * rq
    dw = theta["b3"] * (t0 * w * w - te) + sd_w * rng.standard_normal(n)
    return {
        **states,
        "id": id_,
        "iq": iq,
        "ded": yed - wb * (w - 1.0) * eq,
        "deq": yeq + wb * (w - 1.0) * ed,
        "dw": dw,
    }


def _im_priors(motor: str, every: int, *, noise: float, rel_sd: float, conjugate: bool):
    """Priors centred on the motor's coefficients (sd ``rel_sd`` of each).

    Each noise precision is centred on ``noise`` times the RMS of its block's targets.
    """
    states, attrs = _im_record(motor, every)
    truth = dict(attrs["coefficients"])
    theta = dict(truth, tau_e=np.inf, tau_w=np.inf, tau_i=np.inf)  # no noise
    clean = _im_targets(states, theta, attrs["t0"], attrs["wb"], "modelled",
                        np.random.default_rng(0))  # fmt: skip
    w, ed, eq = states["w"], states["ed"], states["eq"]
    wb = attrs["wb"]
    rms = {
        "flux": np.sqrt(np.mean(np.r_[clean["ded"] + wb * (w - 1) * eq,
                                      clean["deq"] - wb * (w - 1) * ed] ** 2)),
        "speed": np.sqrt(np.mean(clean["dw"] ** 2)),
        "current": np.sqrt(np.mean(np.r_[clean["id"], clean["iq"]] ** 2)),
    }  # fmt: skip
    out = {}
    shape = 5.0
    for block, names, _ in _IM_BLOCKS:
        mean = np.array([truth[k] for k in names])
        prec = 1.0 / (rel_sd * np.abs(mean)) ** 2
        rate = shape * (noise * rms[block]) ** 2
        if conjugate:  # b | tau ~ N(m, (tau P)^-1): the same sd at the prior-mean tau
            prec = prec * rate / shape
        out[block] = BlockPrior(mean=mean, precision=prec, shape=shape, rate=rate,
                                conjugate=conjugate)  # fmt: skip
    return out


def im_sampler(
    name: str,
    *,
    scheme: str,
    currents: str,
    motor: str = "small_industrial",
    every: int = 10,
    noise: float = 0.05,
    rel_sd: float = 0.2,
    conjugate: bool = False,
    default_priors: bool = False,
    thin: int = 1,
    burn: int = 200,
    kept: int = 999,
    notes: str = "",
) -> SamplerUnderTest:
    """An induction-motor sampler under test (all three blocks), through :func:`fit_im`.

    Parameters
    ----------
    name : str
        Registry key.
    scheme : {"blocked", "single-site", "exact"}
        Sampler (``exact`` needs ``currents="measured"`` and ``conjugate``).
    currents : {"modelled", "measured"}
        Form of the model (:class:`~loadbayes.models.motor_fit.InductionMotorModel`).
    motor : str
        Documented motor whose clean record is the design.
    every : int
        Keep every ``every``-th sample of the record.
    noise, rel_sd : float
        Prior: coefficients ``N(true, (rel_sd true)^2)``; noise sd near ``noise`` times
        the RMS of each block's targets.
    conjugate : bool
        Normal-gamma priors (measured form only).
    default_priors : bool
        Fit with the model's weak defaults (fixed-truth coverage; no prior simulator).
    thin, burn, kept
        Chain settings.
    notes : str
        For the report.

    Returns
    -------
    SamplerUnderTest
    """
    params = _IM_COEFS + _IM_TAUS

    def priors() -> dict[str, BlockPrior]:
        return _im_priors(motor, every, noise=noise, rel_sd=rel_sd, conjugate=conjugate)

    def draw_prior(rng: np.random.Generator) -> dict[str, float]:
        out: dict[str, float] = {}
        for block, names, tau_name in _IM_BLOCKS:
            coef, tau = draw_block_prior(priors()[block], rng)
            out.update({k: float(c) for k, c in zip(names, coef, strict=True)})
            out[tau_name] = tau
        return out

    def simulate(theta: Mapping[str, float], rng: np.random.Generator) -> dict[str, np.ndarray]:
        states, attrs = _im_record(motor, every)
        return _im_targets(states, theta, attrs["t0"], attrs["wb"], currents, rng)

    def fit(data: Mapping[str, np.ndarray], seed: int) -> dict[str, np.ndarray]:
        from loadbayes.fit import fit_im

        attrs = _im_record(motor, every)[1]
        post = fit_im(
            data,
            t0=attrs["t0"],
            f_hz=attrs["f_nominal_hz"],
            currents=currents,
            warn=False,  # SBC runs thousands of fits; their warnings are not the point
            priors=None if default_priors else priors(),
            scheme=scheme,  # type: ignore[arg-type]
            chains=1,
            draws=burn + thin * kept,
            burn=burn,
            thin=thin,
            seed=seed,
        )
        return {p: post.draws[p][0] for p in params}

    return SamplerUnderTest(
        name=name,
        parameters=params,
        draw_prior=None if default_priors else draw_prior,
        simulate=simulate,
        fit=fit,
        kept=kept,
        notes=notes,
    )


def im_truth(motor: str = "small_industrial", every: int = 10, noise: float = 0.05):
    """The motor's coefficients and the precisions of ``noise`` times each block's RMS."""
    pri = _im_priors(motor, every, noise=noise, rel_sd=0.2, conjugate=False)
    truth = dict(_im_record(motor, every)[1]["coefficients"])
    for block, _, tau_name in _IM_BLOCKS:
        truth[tau_name] = pri[block].shape / pri[block].rate
    return truth


# ------------------------------------------------------------ robust (Student-t)
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

    def simulate(theta: Mapping[str, float], rng: np.random.Generator) -> _ZipData:
        v = rng.uniform(band[0], band[1], n)
        dof = theta["nu_p"] if nu == "auto" else float(nu)
        curve = theta["a1"] * v**2 + theta["a2"] * v + theta["a3"]
        return _ZipData(v, curve + rng.standard_t(dof, n) / np.sqrt(theta["tau_p"]))

    def fit(data: _ZipData, seed: int) -> dict[str, np.ndarray]:
        from loadbayes.fit import fit_robust
        from loadbayes.models.zip import ZIPModel

        post = fit_robust(
            ZIPModel(with_q=False), data.columns(), priors={"p": prior}, nu=nu,  # type: ignore[arg-type]
            chains=1, draws=burn + thin * kept, burn=burn, thin=thin, seed=seed,
        )  # fmt: skip
        return {p: post.draws[p][0] for p in params}

    return SamplerUnderTest(name, params, draw_prior, simulate, fit, kept, notes)


# ------------------------------------------------------------------------ online
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


# ------------------------------------------------------------------------- registry
def _entries() -> list[SamplerUnderTest]:
    return [
        zip_sampler(
            "zip-blocked",
            scheme="blocked",
            prior=ZIP_PRIOR,
            band=BUS18_BAND,
            with_q=True,
            thin=2,
            notes="P and Q, n = 50 on the bus-18 band (a1-a2 ridge); independent prior; thin 2",
        ),
        zip_sampler(
            "zip-single-site",
            scheme="single-site",
            prior=ZIP_PRIOR,
            band=WIDE_BAND,
            thin=50,
            kept=499,
            notes="P, n = 50 on a wide band (0.3-1.7 p.u.: a1-a2 correlation about -0.96 "
            "instead of -0.99); independent prior; thin 50",
        ),
        zip_sampler(
            "zip-exact",
            scheme="exact",
            prior=ZIP_PRIOR_CONJ,
            band=BUS18_BAND,
            with_q=True,
            notes="P and Q, n = 50 on the bus-18 band; conjugate prior; independent draws",
        ),
        zip_sampler(
            "zip-blocked-conjugate",
            scheme="blocked",
            prior=ZIP_PRIOR_CONJ,
            band=BUS18_BAND,
            thin=2,
            notes="P, n = 50 on the bus-18 band; conjugate prior through the Gibbs kernel; thin 2",
        ),
        zip_sampler(
            "zip-auto-blocked",
            scheme="blocked",
            prior=ZIP_PRIOR_AUTO,
            band=(0.85, 1.15),
            thin=2,
            auto=True,
            notes="P with unknown nominal power (block p0, d1, d2; shares d/p0), n = 50 "
            "on 0.85-1.15 p.u.; thin 2",
        ),
        im_sampler(
            "im-modelled-blocked",
            scheme="blocked",
            currents="modelled",
            thin=100,
            kept=99,
            notes="motor, modelled currents (the coupled sampler, the default); small "
            "industrial motor's sag record, n = 301; b3 and (ab, ac) decorrelate slowly "
            "(autocorrelation 0.73 at lag 1, 0.17 at lag 40), so 99 draws one in 100",
        ),
        im_sampler(
            "im-modelled-single-site",
            scheme="single-site",
            currents="modelled",
            thin=150,
            kept=99,
            notes="motor, modelled currents, one coefficient at a time (ab: autocorrelation "
            "0.96 at lag 1, 0.29 at lag 40); 99 draws one in 150",
        ),
        im_sampler(
            "im-measured-blocked",
            scheme="blocked",
            currents="measured",
            thin=2,
            notes="motor, the paper's form (three conjugate blocks, measured currents "
            "as regressors); thin 2",
        ),
        im_sampler(
            "im-measured-single-site",
            scheme="single-site",
            currents="measured",
            thin=5,
            kept=499,
            notes="motor, the paper's form, one coefficient at a time; thin 5",
        ),
        im_sampler(
            "im-measured-exact",
            scheme="exact",
            currents="measured",
            conjugate=True,
            notes="motor, the paper's form with conjugate priors; independent draws",
        ),
        robust_sampler(
            "robust-nu4",
            nu=4.0,
            kept=199,
            notes="Student-t Gibbs (latent weights), nu = 4 fixed; P, n = 50 on the bus-18 "
            "band, t4 noise; 199 draws, thin 5",
        ),
        robust_sampler(
            "robust-nu-auto",
            nu="auto",
            notes="Student-t Gibbs with nu sampled (Metropolis on log nu, weights "
            "integrated out) from its Gamma(2, 0.1) prior on [1, 1000]; 199 draws, thin 10",
            thin=10,
            kept=199,
        ),
        composite_sampler(
            "composite-mwg",
            # One in 80 (was 40, then 50): with the 5 ms RK4 step the lag-1 guard's
            # largest median came to 0.099 at one in 40, and with the sag's step instant
            # sampled too, 0.131 (log_t_prime) at one in 50. 39 kept draws (40 ranks, 2
            # per bin) keep the cost as it was.
            thin=80,
            kept=39,
            burn=600,
            ci_replications=200,
            notes="composite ZIP + motor (adaptive Metropolis on the motor's scale-free "
            "coordinates with the linear block integrated out, then beta and tau exact); "
            "a 35% sag, 1.5 s at 30 samples/s, its step's instant drawn; 39 draws one in "
            "80 after 600",
        ),
        online_sampler(
            "online-exact",
            mode="exact",
            notes="online tracker, recursive Bayes over all 50 samples; the last "
            "posterior's marginals",
        ),
        online_sampler(
            "online-window",
            mode="window",
            notes="online tracker, sliding window of the last 30 of 50 samples",
        ),
        online_sampler(
            "online-drift",
            mode="drift",
            notes="online tracker, random-walk drift (sd 0.5 / sqrt(tau) per sample, a "
            "dynamic linear model): the truth is the coefficients at the last sample",
        ),
    ]


#: Every sampler under test, by name.
REGISTRY: dict[str, SamplerUnderTest] = {e.name: e for e in _entries()}
