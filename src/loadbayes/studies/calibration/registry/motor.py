"""Induction-motor samplers under test: a simulated record, its targets and priors, the truth."""

from __future__ import annotations

import functools
from collections.abc import Mapping

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.testing.sbc import SamplerUnderTest, draw_block_prior

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
            sampler=SamplerSettings(
                chains=1, draws=burn + thin * kept, burn=burn, thin=thin, seed=seed
            ),
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
