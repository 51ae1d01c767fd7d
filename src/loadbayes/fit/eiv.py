"""Errors in variables for the ZIP fit: a latent true voltage behind the measured one.

Every other fit treats V as exact. With noise of sd ``s`` on V the shares are biased
toward a flat load by ``var(V_true) / var(V)`` (attenuation), and more data only narrow
the interval around the wrong value. Here the measured voltage is ``v_i = x_i + u_i``,
``u_i ~ N(0, s^2)``, with one latent true voltage ``x_i`` per sample, and the powers
follow the ZIP curve of the latent one:

    y_ci = P0_c (a1 x_i^2 + a2 x_i + a3) + e_ci,    e_ci ~ N(0, 1 / tau_c)

written, as in :class:`~loadbayes.models.zip.ZIPModel`, as a regression on the columns
``(1, x^2 - 1, x - 1)`` (``auto`` nominal power) or ``(x^2 - 1, x - 1)`` on
``y / P0 - 1`` (a known one). The Gibbs sampler keeps the conjugate blocks:

1. the coefficients and ``tau`` of each channel given the latent voltages: the normal
   and gamma conditionals of the plain fit, on the Gram matrix of the current ``x``;
2. each ``x_i`` given the rest (independent across samples, a quartic log-density:
   Gaussian in ``v_i`` times the Gaussian likelihood of P and Q, each quadratic in
   ``x_i``): one Metropolis-Hastings step per sample whose proposal is the exact
   conditional of the curve linearised at the current ``x_i`` (a Gauss-Newton step).
   The curve is nearly linear over one noise sd, so almost every proposal is accepted
   (the acceptance rate is recorded);
3. with ``v_noise="auto"`` the noise precision ``1 / s^2``: gamma given the ``v - x``.

The latent voltages have a flat prior (the functional model: no assumption about how
the true V is distributed over the day).

Known sd or ``auto``
--------------------
A known sd (``--v-noise 0.005``) is the recommended form: the instrument class of the
voltage transformer and transducer states it (class 0.5: about 0.25% sd), and with it
the correction is exact. ``auto`` learns ``s`` from the data: with P and Q both
present the common error in V moves the residuals of P and Q together (their slopes in
V are known given the shares), which identifies it; with P alone only the curvature
does, weakly, and the interval of ``s`` (``sigma_v``) shows it.

One idea needs these 453 lines: the errors-in-variables Gibbs sampler, its three
conditionals above in one compiled segment that ``inference/chain.Chain`` drives, with its
entry and the check of its option.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import GramAccumulator
from loadbayes.inference.chain import Chain
from loadbayes.inference.linalg import precision_draw
from loadbayes.io.errors import OptionError
from loadbayes.posterior import Posterior

__all__ = ["EIV_DEFAULTS", "check_v_noise", "fit_zip_eiv"]

#: Sampler settings when the caller gives none: the latent voltages make each
#: iteration O(n), and the chains mix in a few hundred iterations (measured R-hat < 1.01
#: at 4 x 3000 draws on 2000 samples), so the plain fit's 40 000 draws are not needed.
EIV_DEFAULTS = SamplerSettings(draws=4_000, burn=1_000)
#: Iterations whose random numbers are drawn in one piece (memory ~ 2 n SEGMENT floats),
#: fewer when 2 n SEGMENT would pass SEGMENT_NUMBERS (a day at 1 s: 23 iterations).
SEGMENT = 256
SEGMENT_NUMBERS = 2_000_000
#: Gamma prior of the V-noise precision with ``auto``, and of the precision of the true
#: voltages about their mean: weak, as the plain fit's tau.
TAU_V_PRIOR = (1e-3, 1e-9)
TAU_V_RATE = TAU_V_PRIOR[1]


def check_v_noise(v_noise: Any) -> float | str | None:
    """``None``, a positive sd in per unit of v0, or ``"auto"`` (one-line OptionError)."""
    if v_noise is None:
        return None
    if isinstance(v_noise, str):
        text = v_noise.strip().lower()
        if text == "auto":
            return "auto"
        try:
            v_noise = float(text)
        except ValueError:
            raise OptionError(
                f"v_noise must be a positive sd in per unit or 'auto', got {v_noise!r}"
            ) from None
    value = float(v_noise)
    if not (np.isfinite(value) and 0 < value < 0.2):
        raise OptionError(
            f"v_noise must be a positive sd in per unit below 0.2 (0.01 is 1%), got {value:g}"
        )
    return value


@njit(cache=True, nogil=True)
def _eiv_segment(
    v,
    ys,
    j0,
    pm,
    pp,
    rate0,
    shape_g,
    x,
    beta,
    tau,
    tau_v,
    fit_tau_v,
    rate_v0,
    hyper,
    z_beta,
    g_tau,
    g_tau_v,
    z_hyper,
    z_x,
    u_x,
    start,
    burn,
    thin,
    kept0,
    out_beta,
    out_tau,
    out_tau_v,
    accepted,
):  # pragma: no cover - compiled
    """``m`` iterations of one chain (``m`` = rows of ``z_x``) from iteration ``start``.

    The kept ones (past ``burn``, every ``thin``-th: ``inference.chain.is_kept``) go to
    row ``k - kept0`` of the ``out_`` arrays, ``k`` their index among the chain's kept
    draws (the driver's arrays: ``inference.chain.Chain.run_batched``).

    ``ys`` (C, n) are the channels' responses, ``j0[c]`` 0 (columns 1, z1, z2) or 1
    (z1, z2: known nominal power); ``beta`` (C, 3) holds the intercept in column 0 (0
    for a known nominal power). ``shape_g`` are standard gamma draws of shape
    ``a0 + n/2`` (C per iteration, and one for tau_v), divided here by the rate.
    ``hyper`` is (mu, lambda) of the latent voltages' normal prior, ``z_hyper`` a
    standard normal and a standard gamma of shape ``a + n/2`` per iteration for them.
    """
    n = v.size
    nc = ys.shape[0]
    m = z_x.shape[0]
    s = np.zeros((3, 3))
    t = np.zeros((nc, 3))
    yy = np.zeros(nc)
    for c in range(nc):
        for i in range(n):
            yy[c] += ys[c, i] * ys[c, i]
    for j in range(m):
        it = start + j
        # -- the Gram matrix of (1, x^2 - 1, x - 1) at the current latent voltages
        s[:, :] = 0.0
        t[:, :] = 0.0
        for i in range(n):
            f1 = x[i] * x[i] - 1.0
            f2 = x[i] - 1.0
            s[0, 0] += 1.0
            s[0, 1] += f1
            s[0, 2] += f2
            s[1, 1] += f1 * f1
            s[1, 2] += f1 * f2
            s[2, 2] += f2 * f2
            for c in range(nc):
                t[c, 0] += ys[c, i]
                t[c, 1] += f1 * ys[c, i]
                t[c, 2] += f2 * ys[c, i]
        s[1, 0] = s[0, 1]
        s[2, 0] = s[0, 2]
        s[2, 1] = s[1, 2]
        # -- each channel's coefficients | tau, then tau | coefficients
        for c in range(nc):
            a = j0[c]
            k = 3 - a
            lam = np.empty((k, k))
            h = np.empty(k)
            for r in range(k):
                h[r] = tau[c] * t[c, a + r]
                for q in range(k):
                    lam[r, q] = pp[c, r, q] + tau[c] * s[a + r, a + q]
                    h[r] += pp[c, r, q] * pm[c, q]
            b = np.empty(k)
            if not precision_draw(lam, h, z_beta[j, c, :k], np.empty((k, k)), np.empty(k), b):
                b[:] = beta[c, a:]  # not positive definite (cannot happen with a prior)
            ssr = yy[c]
            for r in range(k):
                ssr -= 2.0 * b[r] * t[c, a + r]
                for q in range(k):
                    ssr += b[r] * s[a + r, a + q] * b[q]
            beta[c, :] = 0.0
            beta[c, a:] = b
            tau[c] = max(g_tau[j, c] / (rate0[c] + 0.5 * max(ssr, 0.0)), 1e-100)
        # -- the latent voltages' prior: mu | x (flat prior), then lambda | x, mu
        sx = 0.0
        for i in range(n):
            sx += x[i]
        mu = sx / n + z_hyper[j, 0] / np.sqrt(n * hyper[1])
        sxx = 0.0
        for i in range(n):
            sxx += (x[i] - mu) ** 2
        lam = max(z_hyper[j, 1] / (TAU_V_RATE + 0.5 * sxx), 1e-100)
        hyper[0] = mu
        hyper[1] = lam
        # -- each latent voltage: MH with the linearised conditional as proposal
        sq = 0.0
        for i in range(n):
            xi = x[i]
            lp_x = -0.5 * tau_v * (v[i] - xi) ** 2 - 0.5 * lam * (xi - mu) ** 2
            h_x = tau_v + lam
            num_x = tau_v * v[i] + lam * mu
            for c in range(nc):
                f = beta[c, 0] + beta[c, 1] * (xi * xi - 1.0) + beta[c, 2] * (xi - 1.0)
                d = 2.0 * beta[c, 1] * xi + beta[c, 2]
                r = ys[c, i] - f
                lp_x -= 0.5 * tau[c] * r * r
                h_x += tau[c] * d * d
                num_x += tau[c] * d * (r + d * xi)
            m_x = num_x / h_x
            xn = m_x + z_x[j, i] / np.sqrt(h_x)
            lp_n = -0.5 * tau_v * (v[i] - xn) ** 2 - 0.5 * lam * (xn - mu) ** 2
            h_n = tau_v + lam
            num_n = tau_v * v[i] + lam * mu
            for c in range(nc):
                f = beta[c, 0] + beta[c, 1] * (xn * xn - 1.0) + beta[c, 2] * (xn - 1.0)
                d = 2.0 * beta[c, 1] * xn + beta[c, 2]
                r = ys[c, i] - f
                lp_n -= 0.5 * tau[c] * r * r
                h_n += tau[c] * d * d
                num_n += tau[c] * d * (r + d * xn)
            m_n = num_n / h_n
            # log q(xn | x) and log q(x | xn)
            q_fwd = 0.5 * np.log(h_x) - 0.5 * h_x * (xn - m_x) ** 2
            q_rev = 0.5 * np.log(h_n) - 0.5 * h_n * (xi - m_n) ** 2
            if np.log(u_x[j, i]) < lp_n - lp_x + q_rev - q_fwd:
                x[i] = xn
                accepted[0] += 1.0
            sq += (v[i] - x[i]) ** 2
        accepted[1] += n
        if fit_tau_v:
            tau_v = max(g_tau_v[j] / (rate_v0 + 0.5 * sq), 1e-100)
        if it >= burn and (it - burn) % thin == 0:
            kk = (it - burn) // thin - kept0
            out_beta[kk, :, :] = beta
            out_tau[kk, :] = tau
            out_tau_v[kk] = tau_v
    return tau_v


@dataclass
class _Latent:
    """One chain's state: the latent voltages, coefficients, precisions (updated in place)."""

    x: np.ndarray  # (n,) latent true voltages
    beta: np.ndarray  # (C, 3)
    tau: np.ndarray  # (C,)
    tau_v: float
    hyper: np.ndarray  # (mu, lambda) of the latent voltages' normal prior
    accepted: np.ndarray  # latent-voltage steps accepted, proposed


def _chain(
    gen: np.random.Generator,
    x_obs: np.ndarray,
    ys: np.ndarray,
    j0: np.ndarray,
    priors: list[BlockPrior],
    *,
    v_noise: float | str,
    settings: SamplerSettings,
) -> dict[str, np.ndarray]:
    """One chain: kept draws of the coefficients (C, 3), tau (C), tau_v; acceptance.

    The iterations run in the compiled :func:`_eiv_segment`, a segment of them per call
    (a Python call per iteration would cost more than the iteration on a short record);
    :class:`~loadbayes.inference.chain.Chain` owns the count, the kept draws' arrays,
    the stop flag and the statistics (``Chain.run_batched``).
    """
    n = x_obs.size
    nc = ys.shape[0]
    pm = np.zeros((nc, 3))
    pp = np.zeros((nc, 3, 3))
    rate0 = np.zeros(nc)
    shape = np.zeros(nc)
    for c, pr in enumerate(priors):
        k = 3 - int(j0[c])
        pm[c, :k] = pr.mean
        pp[c, :k, :k] = pr.precision
        rate0[c] = pr.rate
        shape[c] = pr.shape + 0.5 * n
    fit_tau_v = v_noise == "auto"
    if fit_tau_v:
        # start from the first-difference estimate (an upper bound when V moves slowly)
        sd0 = max(float(np.std(np.diff(x_obs))) / np.sqrt(2.0), 1e-4)
        tau_v = 1.0 / sd0**2
    else:
        tau_v = 1.0 / float(v_noise) ** 2
    # start: least squares at the measured voltage, jittered per chain
    x = x_obs + gen.standard_normal(n) / np.sqrt(tau_v) * 0.1
    beta = np.zeros((nc, 3))
    tau = np.zeros(nc)
    cols = np.column_stack([np.ones(n), x_obs**2 - 1.0, x_obs - 1.0])
    for c in range(nc):
        a = int(j0[c])
        coef, *_ = np.linalg.lstsq(cols[:, a:], ys[c], rcond=None)
        beta[c, a:] = coef
        res = ys[c] - cols[:, a:] @ coef
        tau[c] = 1.0 / max(float(np.var(res)), 1e-12)
    shape_v = TAU_V_PRIOR[0] + 0.5 * n
    hyper = np.array([float(np.mean(x_obs)), 1.0 / max(float(np.var(x_obs)), 1e-12)])
    state = _Latent(x, beta, tau, tau_v, hyper, np.zeros(2))

    def segment(st: _Latent, rng, start, m, out, kept0) -> _Latent:
        # The random numbers of m iterations in one piece, in this order, then the loop.
        z_beta = rng.standard_normal((m, nc, 3))
        g_tau = rng.standard_gamma(shape, size=(m, nc))
        g_tau_v = rng.standard_gamma(shape_v, size=m)
        z_hyper = np.column_stack(
            [rng.standard_normal(m), rng.standard_gamma(TAU_V_PRIOR[0] + 0.5 * n, size=m)]
        )
        z_x = rng.standard_normal((m, n))
        u_x = rng.random((m, n))
        st.tau_v = _eiv_segment(
            x_obs, ys, j0, pm, pp, rate0, shape, st.x, st.beta, st.tau, st.tau_v, fit_tau_v,
            TAU_V_PRIOR[1], st.hyper, z_beta, g_tau, g_tau_v, z_hyper, z_x, u_x, start,
            settings.burn, settings.thin, kept0, out["beta"], out["tau"], out["tau_v"],
            st.accepted,
        )  # fmt: skip
        return st

    chain = Chain(
        None, state, gen, fields={"beta": (nc, 3), "tau": (nc,), "tau_v": ()}, record=None,
        burn=settings.burn, thin=settings.thin,
        stats=lambda: {"accept": np.array(state.accepted[0] / max(state.accepted[1], 1.0))},
    )  # fmt: skip
    # at most SEGMENT iterations, and about 32 MB of random numbers, at a time
    chain.run_batched(settings.draws, max(1, min(SEGMENT, SEGMENT_NUMBERS // max(n, 1))), segment)
    return {**chain.draws(), **chain.sample_stats()}


def fit_zip_eiv(
    model,
    cols: Mapping[str, np.ndarray],
    *,
    v_noise: float | str,
    priors: Mapping[str, BlockPrior] | None = None,
    sampler: SamplerSettings,
    observed: Mapping[str, np.ndarray] | None = None,
    settings: Mapping[str, Any] | None = None,
    warnings: list[str] | None = None,
) -> Posterior:
    """The ZIP posterior with a latent true voltage (module notes).

    Parameters
    ----------
    model : ZIPModel
        The nominal point and channels.
    cols : mapping
        ``v``, ``p`` (``q``) in per unit, rows in any order.
    v_noise : float or "auto"
        The sd of the noise on V in per unit of the voltage base (known, from the
        instrument class), or ``"auto"`` to sample it.
    priors : mapping, optional
        The blocks' :class:`BlockPrior` (non-conjugate); the model's weak ones otherwise.
    sampler : SamplerSettings
        How the chains run.
    observed, settings, warnings
        Recorded with the result.

    Returns
    -------
    Posterior
        The plain fit's draws (a1.., tau_p.., p0/q0 with ``auto``) and ``sigma_v`` (the
        V-noise sd in per unit; constant when given); ``settings["v_noise"]`` and
        ``settings["eiv_acceptance"]`` (the latent-voltage steps accepted).
    """
    from loadbayes.core.parallel import chain_generators, run_chains
    from loadbayes.fit.core import prior_settings

    v_noise = check_v_noise(v_noise)  # type: ignore[assignment]
    priors = dict(priors or model.default_priors())
    for name, pr in priors.items():
        if pr.conjugate:
            raise OptionError(
                f"the errors-in-variables fit takes the default (non-conjugate) priors; "
                f"the prior of {name!r} is conjugate"
            )
    x_obs = np.asarray(cols["v"], dtype=float) / model.v0
    names, ys, j0, block_priors = [], [], [], []
    for block in model.blocks:
        ch = block.name
        nom = model.p0 if ch == "p" else model.q0
        y = np.asarray(cols[ch], dtype=float)
        ys.append(y if nom == "auto" else y / float(nom) - 1.0)
        j0.append(0 if nom == "auto" else 1)
        names.append(block)
        block_priors.append(priors[ch])
    y_arr = np.ascontiguousarray(np.vstack(ys))
    j0_arr = np.asarray(j0, dtype=np.int64)
    gens = chain_generators(sampler.seed, sampler.chains)
    # the sd is in per unit of the voltage base; the latent voltage is x = V / v0
    noise_x = v_noise if v_noise == "auto" else float(v_noise) / model.v0
    res = run_chains(
        lambda i, g: _chain(
            g, x_obs, y_arr, j0_arr, block_priors, v_noise=noise_x, settings=sampler
        ),
        gens,
    )
    raw: dict[str, np.ndarray] = {}
    for c, block in enumerate(names):
        a = int(j0_arr[c])
        for i, coef in enumerate(block.coef_names):
            raw[coef] = np.stack([r["beta"][:, c, a + i] for r in res])
        raw[block.tau_name] = np.stack([r["tau"][:, c] for r in res])
    out = model.transform(raw)
    tau_v = np.stack([r["tau_v"] for r in res])
    out["sigma_v"] = model.v0 / np.sqrt(tau_v)
    acc = GramAccumulator(model.gram_columns)
    acc.update(model.rows(cols))
    gram = acc.result()
    warn = list(warnings or []) + model.check(gram)
    accept = float(np.mean([r["accept"] for r in res]))
    full = dict(settings or {})
    full.update(
        n=int(x_obs.size),
        scheme="eiv-mwg",
        chains=sampler.chains,
        draws=sampler.draws,
        burn=sampler.burn,
        thin=sampler.thin,
        init=sampler.init,
        seed=sampler.seed,
        priors=prior_settings(priors),
        v_noise=v_noise,
        eiv_acceptance=accept,
    )
    if accept < 0.5:
        warn.append(
            f"only {100 * accept:.0f}% of the latent-voltage steps were accepted: the ZIP "
            "curve is far from linear over one noise sd; check v_noise"
        )
    post = Posterior(
        out,
        model=model.name,
        method="gibbs-eiv",
        coefficients=model.coefficients,
        free=getattr(model, "free", None),
        observed=observed,
        constant={"gram": gram.matrix},
        settings=full,
        warnings=warn,
    )
    post.extra_json.update(v_noise=v_noise, eiv_acceptance=round(accept, 4))
    return post
