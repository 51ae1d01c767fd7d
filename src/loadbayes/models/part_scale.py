"""Each motor's ``log T0`` sampled as its place inside the range its limits leave it.

A motor of parts is sampled in its scale-free coordinates ``o = (log(Rs T0), log(X' T0),
log((X - X') T0), log T', log(H / T0))`` and ``log T0`` (``models/parts_model.py``). The
terminal data see ``o`` only: moving ``log T0`` with ``o`` held changes no response
(the motor's own-base impedances all scale with ``1 / T0``), so the likelihood does not
depend on it. The physical region's hard limits do: ``Rs <= rs_max``, ``H >= h_min`` and
``x_min <= X' <= x_max`` on the motor's own base are, for given ``o``, an interval
``[lo(o), hi(o)]`` of ``log T0``:

    lo = max(log(Rs T0) - log rs_max, log h_min - log(H / T0), log(X' T0) - log x_max)
    hi = log(X' T0) - log x_min

Sampled as it was, ``(o, log T0)`` is a wedge wherever a limit binds: on the real
record's first fault the data pull ``Rs`` past 0.1, so ``log(Rs T0)`` can rise only as
far as ``log T0`` has risen before it, and a random walk creeps along the diagonal
(posterior correlation 0.89 of ``log(Rs T0)`` with ``log T0``, R-hat up to 3 in the
two-motor model; docs/composite.md, "The motors' rating coordinate").

So ``log T0`` is replaced in the sampled vector by ``z``, its place inside ``[lo, hi]``
under its Gaussian prior conditional on ``o`` (mean ``m(o)``, sd ``s``):
``log T0 = m + s Phi^-1(Phi(a) + Phi(z) (Phi(b) - Phi(a)))`` with ``a, b = (lo - m) /
s, (hi - m) / s``. The Jacobian cancels the truncated conditional exactly, so the prior
in ``(o, z)`` is ``N(o) (Phi(b) - Phi(a)) N(z; 0, 1)``: the limits become a smooth factor
on ``o`` (the prior mass of ``log T0`` they leave), ``z`` is a standard normal the
data never see, and every state of ``(o, z)`` is inside the region. The posterior is the
same (the map is a bijection onto the region); only the sampler's coordinates change.
The tails are computed from the side where they are small (``scipy.special.log_ndtr``,
``ndtri``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import log_ndtr, ndtr, ndtri

from loadbayes.models.parts_state import log_mass_of, log_t0_of, map_row

__all__ = ["ScaleMap", "log_mass"]


def log_mass(a, b):
    """``log(Phi(b) - Phi(a))`` (vectorised; -inf where ``a >= b``), from the small tail."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    flip = a > 0  # both tails upper: Phi(-a) - Phi(-b)
    lo, hi = np.where(flip, -b, a), np.where(flip, -a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        top, bottom = log_ndtr(hi), log_ndtr(lo)
        out = top + np.log1p(-np.exp(bottom - top))
    return np.where((a < b) & np.isfinite(out), out, -np.inf)


@dataclass(frozen=True)
class ScaleMap:
    """One motor's ``z <-> log T0`` (module docstring).

    ``index``: the motor's first coordinate (``log(Rs T0)``; ``z`` sits at ``index + 5``,
    where ``log T0`` is in ``theta``); ``mean, cov``: the motor's six-coordinate Gaussian
    prior; the limits on its own base.
    """

    index: int
    mean: np.ndarray
    cov: np.ndarray
    rs_max: float
    h_min: float
    x_min: float
    x_max: float

    def __post_init__(self) -> None:
        s_oo, s_ot = self.cov[:5, :5], self.cov[:5, 5]
        coef = np.linalg.solve(s_oo, s_ot)
        set_ = object.__setattr__
        set_(self, "_coef", coef)
        set_(self, "_m0", float(self.mean[5] - self.mean[:5] @ coef))
        set_(self, "_sd", math.sqrt(float(self.cov[5, 5] - coef @ s_ot)))
        for name in ("rs_max", "h_min", "x_min", "x_max"):
            set_(self, f"_log_{name}", math.log(getattr(self, name)))
        # One vector's log_mass and log_t0 are compiled (models/parts_state.py): the
        # sampler's numbers and the compiled density's, one function.
        set_(self, "row", map_row(self.index, coef, self._m0, self._sd, self.rs_max, self.h_min,
                                  self.x_min, self.x_max))  # fmt: skip

    def _ab(self, u):
        # The conditional's mean and the standardised bounds of log T0, given o.
        i = self.index
        if np.ndim(u) == 1:  # one vector (the sampler's): floats, no array overhead
            o = u[i : i + 5]
            m = self._m0 + float(o @ self._coef)
            lo = max(o[0] - self._log_rs_max, self._log_h_min - o[4], o[1] - self._log_x_max)
            hi = o[1] - self._log_x_min
            return m, (float(lo) - m) / self._sd, (float(hi) - m) / self._sd
        o = np.asarray(u, dtype=float)[..., i : i + 5]
        m = self.mean[5] + (o - self.mean[:5]) @ self._coef
        lo = np.maximum.reduce([o[..., 0] - math.log(self.rs_max),
                                math.log(self.h_min) - o[..., 4],
                                o[..., 1] - math.log(self.x_max)])  # fmt: skip
        hi = o[..., 1] - math.log(self.x_min)
        return m, (lo - m) / self._sd, (hi - m) / self._sd

    def log_mass(self, u):
        """``log(Phi(b) - Phi(a))``: the prior mass of ``log T0`` the limits leave at ``o``."""
        if np.ndim(u) == 1:
            return float(log_mass_of(np.asarray(u, dtype=float), self.row))
        _, a, b = self._ab(u)
        return log_mass(a, b)

    def log_t0(self, u):
        """``log T0`` of the sampled vector(s) ``u`` (NaN where the interval is empty)."""
        if np.ndim(u) == 1:
            return float(log_t0_of(np.asarray(u, dtype=float), self.row))
        m, a, b = self._ab(u)
        z = np.asarray(u, dtype=float)[..., self.index + 5]
        flip = a > 0
        with np.errstate(invalid="ignore"):
            low = ndtri(ndtr(a) * ndtr(-z) + ndtr(z) * ndtr(b))
            high = -ndtri(ndtr(-a) * ndtr(-z) + ndtr(z) * ndtr(-b))
        x = np.clip(np.where(flip, high, low), a, b)
        return np.where(a < b, m + self._sd * x, np.nan)

    def z(self, theta):
        """The inverse: ``z`` of ``theta``'s ``log T0`` (held just inside ``[lo, hi]``)."""
        m, a, b = self._ab(theta)
        x = (np.asarray(theta, dtype=float)[..., self.index + 5] - m) / self._sd
        x = np.clip(x, a, b)
        flip = a > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            low = (ndtr(x) - ndtr(a)) / (ndtr(b) - ndtr(a))
            high = (ndtr(-x) - ndtr(-b)) / (ndtr(-a) - ndtr(-b))  # 1 - w
        low, high = (np.clip(w, 1e-15, 1.0 - 1e-15) for w in (low, high))
        return np.where(flip, -ndtri(high), ndtri(low))

    def project_back(self, theta):
        """The sampled vector of ``theta`` (its ``log T0`` inside ``[lo, hi]``): ``z`` set."""
        u = np.array(theta, dtype=float)
        u[..., self.index + 5] = self.z(theta)
        return u
