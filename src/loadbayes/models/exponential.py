"""The exponential static load model, with optional frequency dependence.

With ``x = V / V0`` and, when frequency is measured, ``df = (f - f0) / f0``::

    P = P0 x^np (1 + kpf df),     Q = Q0 x^nq (1 + kqf df)

(the IEEE "exponential" load; without frequency, ``kpf = kqf = 0``). ``np = 0, 1, 2``
are constant power, current and impedance.

How it is sampled, and why
--------------------------
The model is linear in ``P0`` and ``P0 kpf`` but not in the exponent. Two noise models
are offered:

``noise="additive"`` (default): ``P = P0 x^np (1 + kpf df) + e``, ``e ~ N(0, 1/tau_p)``,
    on ``y = P / P0`` when P0 is given (the ZIP model's scale and noise, so the two
    models' likelihoods compare directly) or on P when ``p0="auto"``. Gibbs with one
    Metropolis step: given the exponent, the rest is a conjugate linear block. The
    exponent is drawn by a random-walk Metropolis step *with the linear coefficients
    integrated out* (their Gaussian integral given ``tau`` is closed-form), then the
    linear coefficients from their normal conditional, then ``tau`` from its gamma
    conditional. Integrating the coefficients out matters: on the paper's voltage band
    (0.66-0.89 p.u.) P0 and np are strongly correlated (P0 is an extrapolation to
    x = 1), and a one-at-a-time update would crawl along that ridge. The step size is
    adapted during burn-in only (target acceptance 0.44). Each iteration costs O(n):
    ``x^np`` changes with ``np``.
``noise="multiplicative"``: ``log P = log P0 + np log x + kpf df + e``: the frequency
    factor is ``exp(kpf df)``, equal to ``1 + kpf df`` to first order (for
    ``|kpf df| < 0.03`` the two differ by less than 0.05%). This is a linear regression
    in ``(log P0, np, kpf)``: the conjugate blocked Gibbs sampler on sufficient
    statistics, O(1) per iteration in n, the fastest path on long records. It needs
    ``P / P0 > 0`` at every sample, and its noise is relative (sd ``1/sqrt(tau)`` in log
    units), which is right for a meter with a relative accuracy class.

A paper-style user (additive Gaussian noise of 10% of P0 on P, as the paper's 33-bus
experiments) gets the additive model by default: it is the model that generated such
data, it does not break on samples with ``P <= 0``, and it is on the same scale as the
ZIP fit, so a LOO comparison needs no Jacobian (:mod:`loadbayes.experiments.model_choice`
applies the ``1/P`` Jacobian when the multiplicative form is compared).

The posterior comes back as :class:`~loadbayes.posterior.Posterior` with ``np`` (``nq``),
``kpf`` (``kqf``) when frequency is given, ``p0`` (``q0``) when ``auto``, and ``tau_p``
(``tau_q``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd
from numba import njit

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import Gram
from loadbayes.io.errors import DataError

__all__ = ["NOISE_MODELS", "ExponentialModel", "ExpPriors", "fit_exp"]

Nominal = float | Literal["auto"]
Noise = Literal["additive", "multiplicative"]
NOISE_MODELS = ("additive", "multiplicative")

#: Weak prior of an exponent (np, nq): normal, mean 0, sd 10.
EXPONENT_SD = 10.0
#: Weak prior of a frequency coefficient (kpf, kqf) and of P0 kpf: normal, sd 10 (1e4 auto).
KF_SD = 10.0
_ADAPT_EVERY = 50
_TAU_FLOOR = 1e-100


@dataclass(frozen=True)
class ExpPriors:
    """Priors of one channel of the exponential model.

    Parameters
    ----------
    exponent : (float, float)
        Normal (mean, sd) of np (nq).
    linear : BlockPrior
        Normal prior of the linear coefficients given the exponent (``kpf``; or ``P0``
        and ``P0 kpf`` with ``auto``) and gamma prior of ``tau``. With no linear
        coefficient (P0 known, no frequency) only its ``shape`` and ``rate`` are used.
    """

    exponent: tuple[float, float]
    linear: BlockPrior


@dataclass(frozen=True)
class ExponentialModel:
    """Exponential load model for P and, optionally, Q.

    Parameters
    ----------
    v0 : float
        Nominal voltage, in the units of the voltage data.
    p0, q0 : float or "auto"
        Nominal P and Q at ``V = v0`` (and ``f = f0``), in the units of the data.
    with_q : bool
        Fit Q too.
    with_f : bool
        Frequency is measured (column ``f``): fit kpf (kqf).
    f0 : float
        Nominal frequency, in the units of the frequency data.
    noise : {"additive", "multiplicative"}
        See the module notes.
    """

    v0: float = 1.0
    p0: Nominal = 1.0
    q0: Nominal = 1.0
    with_q: bool = True
    with_f: bool = False
    f0: float = 60.0
    noise: Noise = "additive"

    name = "exp"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.v0) and self.v0 > 0):
            raise ValueError(f"v0 must be positive, got {self.v0}")
        if not (np.isfinite(self.f0) and self.f0 > 0):
            raise ValueError(f"f0 must be positive, got {self.f0}")
        if self.noise not in NOISE_MODELS:
            raise ValueError(f"noise must be one of {NOISE_MODELS}, got {self.noise!r}")
        for name in ("p0", "q0"):
            val = getattr(self, name)
            if val != "auto" and not (isinstance(val, (int, float)) and np.isfinite(val)):
                raise ValueError(f"{name} must be a number or 'auto', got {val!r}")
            if val != "auto" and val == 0:
                raise ValueError(f"{name} must be non-zero (it divides the data)")

    # ------------------------------------------------------------ structure
    def channels(self) -> list[tuple[str, Nominal, str, str]]:
        """``(channel, nominal, exponent name, frequency-coefficient name)`` per channel."""
        out: list[tuple[str, Nominal, str, str]] = [("p", self.p0, "np", "kpf")]
        if self.with_q:
            out.append(("q", self.q0, "nq", "kqf"))
        return out

    @property
    def coefficients(self) -> list[str]:
        """Reported coefficients, in order."""
        out = []
        for ch, nom, e, kf in self.channels():
            out.append(e)
            if self.with_f:
                out.append(kf)
            if nom == "auto":
                out.append(f"{ch}0")
        return out

    @property
    def free(self) -> list[str]:
        """Coefficients checked pairwise for identifiability."""
        return self.coefficients

    def default_priors(self, **kw: Any) -> dict[str, Any]:
        """Weak priors: exponent N(0, 10^2), kpf N(0, 10^2), tau Gamma(1e-3, 1e-9).

        With ``auto`` the linear block is (P0, P0 kpf), N(0, (1e4)^2) each. In the
        multiplicative form the priors are those of the log-linear block.
        """
        out: dict[str, Any] = {}
        for block in self.blocks if self.noise == "multiplicative" else []:
            sds = [1e4 if c.startswith("log_") else EXPONENT_SD for c in block.coef_names]
            out[block.name] = BlockPrior.weak(block.k, sd=sds, **kw)
        if self.noise == "multiplicative":
            return out
        for ch, nom, _, _ in self.channels():
            k = _n_linear(nom, self.with_f)
            sd = 1e4 if nom == "auto" else KF_SD
            out[ch] = ExpPriors((0.0, EXPONENT_SD), BlockPrior.weak(max(k, 1), sd=sd, **kw))
        return out

    # --------------------------------------------------- multiplicative form
    @property
    def gram_columns(self) -> tuple[str, ...]:
        """Columns of the log-linear regressions (multiplicative form)."""
        cols = ["lx", "1"] + (["df"] if self.with_f else [])
        cols += [f"l{ch}" for ch, _, _, _ in self.channels()]
        return tuple(cols)

    @property
    def blocks(self) -> list[LinearBlock]:
        """Conjugate blocks of the multiplicative form: one per channel."""
        out = []
        for ch, nom, e, kf in self.channels():
            names = ([f"log_{ch}0"] if nom == "auto" else []) + [e] + ([kf] if self.with_f else [])
            design = (["1"] if nom == "auto" else []) + ["lx"] + (["df"] if self.with_f else [])
            out.append(LinearBlock(ch, tuple(names), f"tau_{ch}", ((tuple(design), f"l{ch}"),)))
        return out

    def rows(self, data: Mapping[str, np.ndarray]) -> np.ndarray:
        """Rows of the log-linear regressions (multiplicative form)."""
        x = np.asarray(data["v"], dtype=float) / self.v0
        cols = [np.log(x), np.ones_like(x)]
        if self.with_f:
            cols.append(self.freq_deviation(data))
        for ch, nom, _, _ in self.channels():
            y = np.asarray(data[ch], dtype=float) / (1.0 if nom == "auto" else float(nom))
            bad = np.flatnonzero(~(y > 0))
            if bad.size:
                what = f"{ch} / {ch}0" if nom != "auto" else ch
                raise DataError(
                    f"the multiplicative (log) form needs {what} > 0, got {y[bad[0]]:g}; "
                    "use the additive form",
                    column=ch,
                    row=int(bad[0]) + 1,
                )
            cols.append(np.log(y))
        return np.column_stack(cols)

    def freq_deviation(self, data: Mapping[str, np.ndarray]) -> np.ndarray:
        """``df = (f - f0) / f0``."""
        return (np.asarray(data["f"], dtype=float) - self.f0) / self.f0

    def check(self, gram: Gram) -> list[str]:
        """Refuse data that cannot identify the model (multiplicative form)."""
        n_par = max(b.k for b in self.blocks) + 1
        if gram.n < n_par:
            raise DataError(
                f"{gram.n} valid samples, fewer than the {n_par} parameters of a block",
                column="v",
            )
        i = gram.index("lx")
        if gram.col_min[i] == gram.col_max[i]:
            raise DataError("voltage has no spread: the exponent cannot be identified", column="v")
        return []

    def transform(self, draws: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Reported parameters from the raw draws of either form."""
        out: dict[str, np.ndarray] = {}
        for ch, nom, e, kf in self.channels():
            out[e] = draws[e]
            if self.with_f:
                out[kf] = draws[kf]
            if nom == "auto":
                out[f"{ch}0"] = (
                    draws[f"{ch}0"] if f"{ch}0" in draws else np.exp(draws[f"log_{ch}0"])
                )
        for ch, *_ in self.channels():
            out[f"tau_{ch}"] = draws[f"tau_{ch}"]
        return out

    # ---------------------------------------------------------- prediction
    def curve(
        self,
        draws: Mapping[str, np.ndarray],
        ch: str,
        x: np.ndarray,
        df: np.ndarray | float = 0.0,
    ) -> np.ndarray:
        """``P(x, df)`` (data units) for each draw: shape ``(draws, len(x))``."""
        nom, e, kf = {c: (n, ee, k) for c, n, ee, k in self.channels()}[ch]
        th = np.asarray(draws[e]).reshape(-1)[:, None]
        scale = np.asarray(draws[f"{ch}0"]).reshape(-1)[:, None] if nom == "auto" else float(nom)
        xx = np.asarray(x, dtype=float)[None, :]
        dfx = np.broadcast_to(np.asarray(df, dtype=float), xx.shape[1:])[None, :]
        fac = 1.0
        if self.with_f:
            k = np.asarray(draws[kf]).reshape(-1)[:, None]
            fac = np.exp(k * dfx) if self.noise == "multiplicative" else 1.0 + k * dfx
        return scale * xx**th * fac

    def predict(
        self,
        draws: Mapping[str, np.ndarray],
        v: np.ndarray,
        *,
        f: np.ndarray | float | None = None,
        hdi_prob: float = 0.95,
        rng: np.random.Generator | int | None = None,
        max_draws: int = 2000,
        **_: Any,
    ) -> pd.DataFrame:
        """Posterior band of the load curve P(V) (and Q(V)) at frequency ``f`` (nominal).

        Returns
        -------
        pandas.DataFrame
            Columns ``v``, ``p_mean``, ``p_low``, ``p_high`` (and the same for q).
        """
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        v = np.asarray(v, dtype=float)
        first = np.asarray(draws[self.channels()[0][2]]).reshape(-1)
        idx = np.arange(first.size)
        if idx.size > max_draws:
            idx = np.sort(gen.choice(idx, max_draws, replace=False))
        sub = {k: np.asarray(a).reshape(-1)[idx] for k, a in draws.items()}
        df = 0.0 if f is None else (np.asarray(f, dtype=float) - self.f0) / self.f0
        out: dict[str, np.ndarray] = {"v": v}
        lo, hi = (1 - hdi_prob) / 2, 1 - (1 - hdi_prob) / 2
        for ch, *_ in self.channels():
            c = self.curve(sub, ch, v / self.v0, df)
            out[f"{ch}_mean"] = c.mean(axis=0)
            out[f"{ch}_low"] = np.quantile(c, lo, axis=0)
            out[f"{ch}_high"] = np.quantile(c, hi, axis=0)
        return pd.DataFrame(out)


def _n_linear(nom: Nominal, with_f: bool) -> int:
    return (1 if nom == "auto" else 0) + (1 if with_f else 0)


# ------------------------------------------------------------ additive sampler
@njit(cache=True, nogil=True)
def _sums(th, lx, u, y, o, g2u, g2u1, guy, out3):  # pragma: no cover - compiled
    """Sums over samples at exponent ``th`` with ``g = exp(th lx)``.

    ``g2u = sum g^2 u u'``, ``g2u1 = sum g^2 u``, ``guy = sum g u y``,
    ``out3 = [sum g y, sum g^2]``.
    """
    n, kc = u.shape
    for p in range(kc):
        g2u1[p] = 0.0
        guy[p] = 0.0
        for q in range(kc):
            g2u[p, q] = 0.0
    gy = 0.0
    g2 = 0.0
    for i in range(n):
        g = math.exp(th * lx[i])
        gg = g * g
        gy += g * y[i]
        g2 += gg
        for p in range(kc):
            gu = g * u[i, p]
            guy[p] += gu * y[i]
            g2u1[p] += gg * u[i, p]
            for q in range(p, kc):
                g2u[p, q] += gu * g * u[i, q]
    for p in range(kc):
        for q in range(p):
            g2u[p, q] = g2u[q, p]
    out3[0] = gy
    out3[1] = g2


@njit(cache=True, nogil=True)
def _chol(a, lo):  # pragma: no cover - compiled
    """Lower Cholesky factor of a small SPD matrix; False if not positive definite."""
    k = a.shape[0]
    for j in range(k):
        s = a[j, j]
        for p in range(j):
            s -= lo[j, p] * lo[j, p]
        if not s > 0.0:
            return False
        lo[j, j] = math.sqrt(s)
        for i in range(j + 1, k):
            s = a[i, j]
            for p in range(j):
                s -= lo[i, p] * lo[j, p]
            lo[i, j] = s / lo[j, j]
        for i in range(j):
            lo[i, j] = 0.0
    return True


@njit(cache=True, nogil=True)
def _collapsed(tau, o, y2, s3, g2u, g2u1, guy, pc, pcm, lam, h, lo, w):  # pragma: no cover
    """Log p(y | exponent, tau) up to a constant, with the linear block integrated out.

    Leaves ``lam``, ``h`` (the linear block's conditional precision and linear term) and
    ``lo`` (Cholesky of ``lam``) and ``w = lo^-1 h`` behind for the draw that follows.
    """
    kc = h.shape[0]
    tt = y2 - 2.0 * o * s3[0] + o * o * s3[1]  # t't with t = y - o g
    val = -0.5 * tau * tt
    if kc == 0:
        return val
    for p in range(kc):
        h[p] = pcm[p] + tau * (guy[p] - o * g2u1[p])
        for q in range(kc):
            lam[p, q] = pc[p, q] + tau * g2u[p, q]
    if not _chol(lam, lo):
        return -np.inf
    logdet = 0.0
    for p in range(kc):
        s = h[p]
        for q in range(p):
            s -= lo[p, q] * w[q]
        w[p] = s / lo[p, p]
        logdet += math.log(lo[p, p])
    quad = 0.0
    for p in range(kc):
        quad += w[p] * w[p]
    return val - logdet + 0.5 * quad


@njit(cache=True, nogil=True)
def _exp_chain(
    lx,
    u,
    y,
    o,
    th_m,
    th_sd,
    pc,
    pcm,
    a0,
    b0,
    th,
    tau,
    step,
    gen,
    draws,
    burn,
    thin,
    out_th,
    out_c,
    out_t,
    stats,
):  # pragma: no cover - compiled
    """One chain: (exponent | tau) collapsed MH, (c | exponent, tau), (tau | exponent, c)."""
    n, kc = u.shape
    y2 = 0.0
    for i in range(n):
        y2 += y[i] * y[i]
    g2u = np.empty((kc, kc))
    g2u1 = np.empty(kc)
    guy = np.empty(kc)
    s3 = np.empty(2)
    g2u_n = np.empty((kc, kc))
    g2u1_n = np.empty(kc)
    guy_n = np.empty(kc)
    s3_n = np.empty(2)
    lam = np.empty((kc, kc))
    h = np.empty(kc)
    lo = np.zeros((kc, kc))
    w = np.empty(kc)
    c = np.zeros(kc)
    _sums(th, lx, u, y, o, g2u, g2u1, guy, s3)
    shape = a0 + 0.5 * n
    acc_win = 0
    kept = 0
    keep = burn
    for it in range(draws):
        # exponent | tau, with the linear coefficients integrated out
        cur = _collapsed(tau, o, y2, s3, g2u, g2u1, guy, pc, pcm, lam, h, lo, w)
        cur -= 0.5 * ((th - th_m) / th_sd) ** 2
        prop = th + step * gen.standard_normal()
        lu = math.log(gen.random())
        _sums(prop, lx, u, y, o, g2u_n, g2u1_n, guy_n, s3_n)
        new = _collapsed(tau, o, y2, s3_n, g2u_n, g2u1_n, guy_n, pc, pcm, lam, h, lo, w)
        new -= 0.5 * ((prop - th_m) / th_sd) ** 2
        if lu < new - cur:
            th = prop
            for p in range(kc):
                g2u1[p] = g2u1_n[p]
                guy[p] = guy_n[p]
                for q in range(kc):
                    g2u[p, q] = g2u_n[p, q]
            s3[0] = s3_n[0]
            s3[1] = s3_n[1]
            acc_win += 1
            if it >= burn:
                stats[0] += 1
        if it >= burn:
            stats[1] += 1
        elif (it + 1) % _ADAPT_EVERY == 0:
            step *= math.exp(2.0 * (acc_win / _ADAPT_EVERY - 0.44))
            acc_win = 0
        # c | exponent, tau  (lam, lo, w recomputed at the current exponent)
        _collapsed(tau, o, y2, s3, g2u, g2u1, guy, pc, pcm, lam, h, lo, w)
        for p in range(kc):
            w[p] += gen.standard_normal()
        for p in range(kc - 1, -1, -1):  # lo' c = w + z: c ~ N(lam^-1 h, lam^-1)
            s = w[p]
            for q in range(p + 1, kc):
                s -= lo[q, p] * c[q]
            c[p] = s / lo[p, p]
        # tau | exponent, c
        tt = y2 - 2.0 * o * s3[0] + o * o * s3[1]
        ssr = tt
        for p in range(kc):
            dty = guy[p] - o * g2u1[p]
            ssr -= 2.0 * c[p] * dty
            for q in range(kc):
                ssr += c[p] * g2u[p, q] * c[q]
        ssr = max(ssr, 0.0)
        tau = max(gen.standard_gamma(shape) / (b0 + 0.5 * ssr), _TAU_FLOOR)
        if it == keep:
            out_th[kept] = th
            for p in range(kc):
                out_c[kept, p] = c[p]
            out_t[kept] = tau
            kept += 1
            keep += thin
    return True


def _nls_start(lx: np.ndarray, u: np.ndarray, y: np.ndarray, o: float, th_m: float):
    """Nonlinear least squares of the channel: (exponent, its standard error, sigma2)."""
    from scipy.optimize import least_squares

    n, kc = u.shape

    def resid(p):
        g = np.exp(p[0] * lx)
        return g * (o + u @ p[1:]) - y

    # Start the exponent from a log-log fit where possible, else 1.
    th0 = 1.0
    pos = y > 0
    if o and pos.sum() > 2 and np.ptp(lx[pos]) > 0:
        th0 = float(np.polyfit(lx[pos], np.log(y[pos]), 1)[0])
    elif pos.sum() > 2 and np.ptp(lx[pos]) > 0:
        th0 = float(np.polyfit(lx[pos], np.log(y[pos]), 1)[0])
    th0 = float(np.clip(th0, -20, 20))
    c0 = np.zeros(kc)
    if kc:
        g = np.exp(th0 * lx)
        c0 = np.linalg.lstsq(g[:, None] * u, y - o * g, rcond=None)[0]
    try:
        fit = least_squares(resid, np.r_[th0, c0], method="lm" if n > kc + 1 else "trf")
        p, jac, res = fit.x, fit.jac, fit.fun
    except Exception:  # noqa: BLE001 - a start only; the sampler does the real work
        p = np.r_[th0, c0]
        res = resid(p)
        jac = None
    sigma2 = max(float(res @ res) / max(n - kc - 1, 1), 1e-24)
    se = 0.1
    if jac is not None:
        with np.errstate(all="ignore"):
            cov = sigma2 * np.linalg.pinv(jac.T @ jac)
        if np.isfinite(cov[0, 0]) and cov[0, 0] > 0:
            se = float(np.sqrt(cov[0, 0]))
    return float(p[0]), se, sigma2


def _channel_arrays(model: ExponentialModel, cols: Mapping[str, np.ndarray], ch: str, nom):
    x = np.asarray(cols["v"], dtype=float) / model.v0
    lx = np.log(x)
    y = np.asarray(cols[ch], dtype=float)
    if nom != "auto":
        y = y / float(nom)
    ucols = []
    if nom == "auto":
        ucols.append(np.ones_like(x))
    if model.with_f:
        df = model.freq_deviation(cols)
        ucols.append(df)
    u = np.column_stack(ucols) if ucols else np.empty((x.size, 0))
    o = 0.0 if nom == "auto" else 1.0
    return np.ascontiguousarray(lx), np.ascontiguousarray(u), np.ascontiguousarray(y), o


def _sample_additive(
    model: ExponentialModel,
    cols: Mapping[str, np.ndarray],
    priors: Mapping[str, ExpPriors],
    *,
    chains: int,
    draws: int,
    burn: int,
    thin: int,
    seed: Any,
) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    from loadbayes.core.parallel import chain_generators, num_threads

    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    chans = model.channels()
    raw: dict[str, np.ndarray] = {}
    accept: dict[str, float] = {}
    kept = len(range(burn, draws, thin))
    for (ch, nom, e, kf), child in zip(chans, seq.spawn(len(chans)), strict=True):
        pr = priors[ch]
        if not isinstance(pr, ExpPriors):
            raise ValueError(f"priors['{ch}'] must be an ExpPriors for the additive form")
        lx, u, y, o = _channel_arrays(model, cols, ch, nom)
        n, kc = u.shape
        if n < kc + 2:
            raise DataError(
                f"{n} valid samples, fewer than the {kc + 2} parameters of the {ch.upper()} "
                "channel",
                column="v",
            )
        if np.ptp(lx) == 0:
            raise DataError("voltage has no spread: the exponent cannot be identified", column="v")
        lin = pr.linear
        if kc and lin.k != kc:
            raise ValueError(f"priors['{ch}'].linear needs {kc} coefficient(s), has {lin.k}")
        pc = np.ascontiguousarray(lin.precision if kc else np.zeros((0, 0)))
        pcm = np.ascontiguousarray(lin.precision @ lin.mean if kc else np.zeros(0))
        th_hat, se, sigma2 = _nls_start(lx, u, y, o, pr.exponent[0])
        gens = chain_generators(child, chains)
        out_th = np.empty((chains, kept))
        out_c = np.empty((chains, kept, kc))
        out_t = np.empty((chains, kept))
        acc = np.zeros((chains, 2))

        def run(
            c: int,
            lx=lx,
            u=u,
            y=y,
            o=o,
            pc=pc,
            pcm=pcm,
            pr=pr,
            lin=lin,
            gens=gens,
            th_hat=th_hat,
            se=se,
            sigma2=sigma2,
            out_th=out_th,
            out_c=out_c,
            out_t=out_t,
            acc=acc,
        ) -> bool:
            gen = gens[c]
            # The start is scattered around the NLS fit whatever ``init`` says: a prior
            # draw of an exponent (sd 10) is too far out for a step scaled to the posterior.
            th0 = th_hat + 3.0 * se * gen.standard_normal()
            tau0 = float(np.exp(gen.standard_normal()) / sigma2)
            return _exp_chain(
                lx,
                u,
                y,
                o,
                float(pr.exponent[0]),
                float(pr.exponent[1]),
                pc,
                pcm,
                float(lin.shape),
                float(lin.rate),
                th0,
                tau0,
                2.4 * se,
                gen,
                draws,
                burn,
                thin,
                out_th[c],
                out_c[c],
                out_t[c],
                acc[c],
            )

        workers = min(chains, num_threads(), max(n * draws * chains // 2_000_000, 1))
        if workers > 1:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                list(pool.map(run, range(chains)))
        else:
            for c in range(chains):
                run(c)
        raw[e] = out_th
        if nom == "auto":
            raw[f"{ch}0"] = out_c[..., 0]
        if model.with_f:
            j = 1 if nom == "auto" else 0
            with np.errstate(divide="ignore", invalid="ignore"):
                raw[kf] = out_c[..., j] / out_c[..., 0] if nom == "auto" else out_c[..., j]
        raw[f"tau_{ch}"] = out_t
        accept[ch] = float(acc[:, 0].sum() / max(acc[:, 1].sum(), 1))
    return raw, accept


# -------------------------------------------------------------------- fit_exp
def _as_columns(data: Any) -> dict[str, np.ndarray]:
    if hasattr(data, "to_dict") and hasattr(data, "columns"):
        return {str(c): np.asarray(data[c], dtype=float) for c in data.columns}
    return {k: np.asarray(v, dtype=float) for k, v in dict(data).items()}


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
    from loadbayes.fitting import accumulate, fit_gram
    from loadbayes.posterior import Posterior

    cols = _as_columns(data)
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
    priors = dict(priors or model.default_priors())
    raw, accept = _sample_additive(
        model, cols, priors, chains=chains, draws=draws, burn=burn, thin=thin, seed=seed
    )
    base.update(
        n=int(v.size),
        scheme="metropolis-within-gibbs",
        chains=chains,
        draws=draws,
        burn=burn,
        thin=thin,
        init="scattered around nonlinear least squares",
        seed=seed,
        acceptance=accept,
        priors={
            ch: {
                "exponent": list(p.exponent),
                "linear_mean": p.linear.mean.tolist(),
                "linear_precision": p.linear.precision.tolist(),
                "shape": p.linear.shape,
                "rate": p.linear.rate,
            }
            for ch, p in priors.items()
        },
    )
    warn = list(warnings or [])
    span = float(np.ptp(v) / v0)
    if span < 0.02:
        warn.append(
            f"voltage spans only {100 * span:.2g}% of v0: the exponent is poorly determined "
            "on so narrow a band."
        )
    return Posterior(
        model.transform(raw),
        model="exp",
        method="gibbs-mwg",
        coefficients=model.coefficients,
        free=model.free,
        observed=observed,
        settings=base,
        warnings=warn,
    )
