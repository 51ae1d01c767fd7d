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
ZIP fit, so a LOO comparison needs no Jacobian (:mod:`loadbayes.studies.model_choice`
applies the ``1/P`` Jacobian when the multiplicative form is compared).

The posterior comes back as :class:`~loadbayes.posterior.Posterior` with ``np`` (``nq``),
``kpf`` (``kqf``) when frequency is given, ``p0`` (``q0``) when ``auto``, and ``tau_p``
(``tau_q``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd

from loadbayes.core.blocks import LinearBlock, PowerLawBlock
from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import Gram
from loadbayes.io.errors import DataError

__all__ = ["NOISE_MODELS", "ExponentialModel", "ExpPriors"]

Nominal = float | Literal["auto"]
Noise = Literal["additive", "multiplicative"]
NOISE_MODELS = ("additive", "multiplicative")

#: Weak prior of an exponent (np, nq): normal, mean 0, sd 10.
EXPONENT_SD = 10.0
#: Weak prior of a frequency coefficient (kpf, kqf) and of P0 kpf: normal, sd 10 (1e4 auto).
KF_SD = 10.0


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

    @property
    def pieces(self) -> str:
        """Likelihood pieces: log-linear blocks (multiplicative) or power-law blocks (additive)."""
        return "linear" if self.noise == "multiplicative" else "power-law"

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

    # ------------------------------------------------------- additive form
    def power_law_blocks(self, data: Mapping[str, np.ndarray]) -> list[PowerLawBlock]:
        """The additive form's channels as ``y = x^theta (o + U c) + e`` blocks.

        ``y = P / P0`` with ``o = 1`` for a known P0; ``y = P`` with ``o = 0`` and ``P0``
        the first linear coefficient for ``auto``; ``U`` holds ``df`` with frequency.
        """
        x = np.asarray(data["v"], dtype=float) / self.v0
        lx = np.ascontiguousarray(np.log(x))
        if np.ptp(lx) == 0:
            raise DataError("voltage has no spread: the exponent cannot be identified", column="v")
        out = []
        for ch, nom, e, kf in self.channels():
            y = np.asarray(data[ch], dtype=float)
            if nom != "auto":
                y = y / float(nom)
            ucols, names = [], []
            if nom == "auto":
                ucols.append(np.ones_like(x))
                names.append(f"{ch}0")
            if self.with_f:
                ucols.append(self.freq_deviation(data))
                names.append(f"{kf}_lin")
            u = np.column_stack(ucols) if ucols else np.empty((x.size, 0))
            n, kc = u.shape
            if n < kc + 2:
                raise DataError(
                    f"{n} valid samples, fewer than the {kc + 2} parameters of the "
                    f"{ch.upper()} channel",
                    column="v",
                )
            out.append(
                PowerLawBlock(
                    name=ch,
                    exponent_name=e,
                    coef_names=tuple(names),
                    tau_name=f"tau_{ch}",
                    log_x=lx,
                    design=np.ascontiguousarray(u),
                    target=np.ascontiguousarray(y),
                    offset=0.0 if nom == "auto" else 1.0,
                )
            )
        return out

    def from_power_law(self, ch: str, theta, coef, tau) -> dict[str, np.ndarray]:
        """Named draws of one channel from its power-law block's (theta, c, tau)."""
        nom = dict((c, n) for c, n, _, _ in self.channels())[ch]
        e, kf = {c: (ee, k) for c, _, ee, k in self.channels()}[ch]
        raw = {e: theta}
        if nom == "auto":
            raw[f"{ch}0"] = coef[..., 0]
        if self.with_f:
            j = 1 if nom == "auto" else 0
            with np.errstate(divide="ignore", invalid="ignore"):
                raw[kf] = coef[..., j] / coef[..., 0] if nom == "auto" else coef[..., j]
        raw[f"tau_{ch}"] = tau
        return raw


def _n_linear(nom: Nominal, with_f: bool) -> int:
    return (1 if nom == "auto" else 0) + (1 if with_f else 0)
