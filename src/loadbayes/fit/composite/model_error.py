"""How much of a prediction's error is the model's form: an AR(1) discrepancy beside noise.

The stated model of one recorded channel (P or Q, per unit) at its scored rows ``k``::

    y_k = m_k(theta) + d_k + e_k

``m`` is the model's response at a posterior draw, ``e`` white noise of variance
``s_e^2`` (the recorder's and the load's fast flicker) and ``d`` the model's form error,
the simplest time-series discrepancy (Kennedy and O'Hagan 2001, section 2.1): a
stationary AR(1) series of variance ``s_d^2`` whose coefficient ``rho`` is per sample
interval (across rows left out, ``rho ** gap``).

- ``s_e^2`` is read with no model (:func:`noise_floor`): half the variance of the first
  differences of the steady rows before the fault. A slow wander of the load cancels in
  differences and is left to ``d``: no load model driven by the voltage follows it.
- ``s_d``, ``rho``: maximum likelihood on the fitted event's residuals (posterior-mean
  prediction, the held-out scoring's path) with ``s_e`` held (:func:`fit_discrepancy`);
  the exact Gaussian likelihood of covariance ``s_d^2 rho^|k_i - k_j| + s_e^2 I``, by
  the Kalman filter of ``d``.
- The share of the fitted event's error that is model form: ``s_d^2 / (s_d^2 + s_e^2)``.

On a held-out event :func:`error_split` divides the mean square of recorded minus the
posterior-mean prediction into the noise (``s_e^2``), the parameters' spread (the mean
over rows of the draws' variance of the response), the model form the fitted event showed
(``s_d^2``), and the rest: error the fitted event never showed (negative when the
held-out event was easier). :func:`discrepancy_band` is the band of a new observation
under the stated model, the fitted event's ``d`` added: at each row the posterior-mean
prediction +- z sqrt(spread^2 + s_d^2 + s_e^2), Gaussian. ``s_d`` and ``rho`` enter at
their maximum: their own posterior spread is left out, so with ``rho`` near 0.8 on about
70 rows (about ten effective ones) the band is if anything narrow, by up to the ratio of
Student's t on ten degrees of freedom to the normal at 97.5 % (2.23 / 1.96 = 1.14).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.stats import norm

__all__ = [
    "Discrepancy",
    "discrepancy_band",
    "error_split",
    "fit_discrepancy",
    "held_out_error",
    "noise_floor",
]

#: Largest AR(1) coefficient the fit may return (a random walk has no stationary variance).
RHO_MAX = 0.995


@dataclass(frozen=True)
class Discrepancy:
    """The fitted model error of one channel: AR(1) ``sd_d``, ``rho``; white ``sd_e``."""

    sd_d: float
    rho: float
    sd_e: float
    n: int

    @property
    def share(self) -> float:
        """The share of the fitted event's error variance that is model form."""
        total = self.sd_d**2 + self.sd_e**2
        return self.sd_d**2 / total if total > 0 else math.nan


def _index(t: np.ndarray) -> np.ndarray:
    """Sample indices of rows at times ``t`` (gaps where rows were left out)."""
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        return np.zeros(t.size, dtype=int)
    dt = float(np.median(np.diff(t)))
    return np.rint((t - t[0]) / dt).astype(int)


def noise_floor(x: np.ndarray) -> float:
    """White-noise variance of steady rows: half the variance of their first differences."""
    d = np.diff(np.asarray(x, dtype=float))
    return 0.5 * float(np.var(d)) if d.size > 1 else 0.0


def _nll(par: np.ndarray, r: list[float], gap: list[float], var_e: float) -> float:
    # The exact Gaussian likelihood by the Kalman filter of d (O(n), not a Cholesky of the
    # n x n covariance): d_k = a d_k-1 + w, a = rho ** gap, y = d + e.
    var_d, rho = math.exp(2 * par[0]), RHO_MAX * math.tanh(par[1])
    m, p, out = 0.0, var_d, 0.0
    for k, (y, g) in enumerate(zip(r, gap, strict=True)):
        if k:
            a = rho**g
            m, p = a * m, a * a * p + var_d * (1.0 - a * a)
        s = p + var_e
        v = y - m
        out += math.log(s) + v * v / s
        gain = p / s
        m, p = m + gain * v, p * (1.0 - gain)
    return 0.5 * out


def fit_discrepancy(resid: np.ndarray, t: np.ndarray, var_e: float) -> Discrepancy:
    """Maximum likelihood ``s_d``, ``rho`` of residuals ``resid`` at times ``t``, ``s_e`` held.

    ``resid``: recorded minus the posterior-mean prediction at the scored rows (not
    centred: an offset is model form); ``var_e``: :func:`noise_floor`'s variance.
    """
    r = np.asarray(resid, dtype=float)
    gap = np.diff(_index(t), prepend=0).astype(float).tolist()
    var_e = max(float(var_e), 1e-12 * float(r @ r) / max(r.size, 1), 1e-30)
    start = np.array([0.5 * math.log(max(float(np.mean(r**2)) - var_e, var_e)), 0.5])
    args = (r.tolist(), gap, var_e)
    res = minimize(_nll, start, args=args, method="Nelder-Mead",
                   options={"xatol": 1e-5, "fatol": 1e-8})  # fmt: skip
    sd_d, rho = math.exp(res.x[0]), RHO_MAX * math.tanh(res.x[1])
    if rho < 0:  # a negative coefficient is no smooth model error: refit it white
        res = minimize(lambda a: _nll(np.array([a[0], 0.0]), *args), start[:1],
                       method="Nelder-Mead")  # fmt: skip
        sd_d, rho = math.exp(res.x[0]), 0.0
    return Discrepancy(sd_d=sd_d, rho=rho, sd_e=math.sqrt(var_e), n=int(r.size))


def discrepancy_band(mean: np.ndarray, spread: np.ndarray, disc: Discrepancy,
                     prob: float = 0.95) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The ``prob`` band of a new observation: ``mean`` +- z sqrt(spread^2 + s_d^2 + s_e^2)."""
    z = float(norm.ppf(0.5 + prob / 2))
    half = z * np.sqrt(np.asarray(spread, dtype=float) ** 2 + disc.sd_d**2 + disc.sd_e**2)
    return mean - half, mean + half


def error_split(resid: np.ndarray, spread: np.ndarray, disc: Discrepancy) -> dict[str, float]:
    """The held-out mean square of ``resid`` split (see the module docstring), as shares.

    Returns ``mse`` and the shares ``noise``, ``parameters``, ``form_seen`` (the model
    form the fitted event showed), ``beyond`` (the rest) and ``form`` (the last two).
    """
    mse = float(np.mean(np.asarray(resid, dtype=float) ** 2))
    if not mse > 0:
        return {"mse": mse}
    noise = disc.sd_e**2 / mse
    par = float(np.mean(np.asarray(spread, dtype=float) ** 2)) / mse
    seen = disc.sd_d**2 / mse
    return {"mse": mse, "noise": noise, "parameters": par, "form_seen": seen,
            "beyond": 1.0 - noise - par - seen, "form": 1.0 - noise - par}  # fmt: skip


def held_out_error(fitted, held, t_fault: float, prob: float = 0.95) -> dict[str, dict]:
    """Per channel, the fitted event's model error and the held-out event scored with it.

    ``fitted``, ``held``: ``EventValidation`` of the fitted event played back through its
    own fit and of the held-out one (``validate.py``, ``validate_parts.py``); ``t_fault``:
    the fitted event's first row whose window straddles a step (the rows before it give
    :func:`noise_floor`). Returns ``{"p": {...}, "q": {...}}``, each with ``disc`` (the
    :class:`Discrepancy`), ``coverage`` (the held-out scored rows inside
    :func:`discrepancy_band`) and ``split`` (:func:`error_split`).
    """
    out = {}
    e0, s0 = fitted.event, np.asarray(fitted.scored, bool)
    e1, s1 = held.event, np.asarray(held.scored, bool)
    pre = s0 & (e0.t < t_fault)
    for ch in ("p", "q"):
        x0, x1 = getattr(e0, ch), getattr(e1, ch)
        disc = fit_discrepancy((x0 - fitted.band[f"{ch}_mean"])[s0], e0.t[s0],
                               noise_floor(x0[pre]))  # fmt: skip
        mean, spread = held.band[f"{ch}_mean"][s1], held.band[f"{ch}_spread"][s1]
        lo, hi = discrepancy_band(mean, spread, disc, prob)
        out[ch] = {"disc": disc, "coverage": float(np.mean((x1[s1] >= lo) & (x1[s1] <= hi))),
                   "split": error_split(x1[s1] - mean, spread, disc)}  # fmt: skip
    return out
