"""The composite load's prior: the motor's log-parameters, the linear block, the noise.

:data:`THETA_PRIOR` is the default log-normal prior of the motor (:data:`THETA_NAMES`),
:class:`CompositePrior` the whole prior and its form in the sampled scale-free
coordinates (``SCALE_FREE_MATRIX``), :data:`STEP_PRIOR_SD` the Gaussian stand-in for a
step fraction's uniform prior. The inference that uses it is ``fit/composite/``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import BETA_NAMES, SCALE_FREE_MATRIX, THETA_NAMES

__all__ = [
    "COEFFICIENT_PRIOR_NAMES",
    "POSITIVE_BETA",
    "STEP_PRIOR_SD",
    "THETA_PRIOR",
    "CoefficientPrior",
    "CompositePrior",
    "named_coefficients",
]

#: Default prior of the motor's log-parameters: (median, sd of the log). Centred on the
#: library's typical motors (docs/motor.md, "The documented motors";
#: models/motor_library.py) with a wide spread: a factor e^sd either way.
THETA_PRIOR: dict[str, tuple[float, float]] = {
    "log_rs": (math.log(0.02), 1.0),
    "log_x_prime": (math.log(0.15), 0.7),
    "log_dx": (math.log(2.5), 0.7),
    "log_t_prime": (math.log(0.5), 1.2),
    "log_h": (math.log(0.8), 0.6),
    "log_t0": (math.log(0.6), 0.5),
}
#: Sd of the Gaussian stand-in for a step fraction's uniform prior in the NLS start and
#: its Laplace covariance: wide, so that the data alone place the step.
STEP_PRIOR_SD = 10.0
#: Index in ``BETA_NAMES`` of the coefficient whose prior is truncated to positive
#: values: ``p_m0``, the motor's initial active power.
POSITIVE_BETA = BETA_NAMES.index("p_m0")
_T = SCALE_FREE_MATRIX
# Priors are frozen dataclasses holding arrays (not hashable): cache by their bytes.
_SCALE_FREE_CACHE: dict[Any, Any] = {}


@dataclass(frozen=True)
class CompositePrior:
    """Prior of the composite model.

    Parameters
    ----------
    theta_mean, theta_sd : ndarray, shape (6,)
        Normal prior of :data:`THETA_NAMES` (logs).
    beta_sd : ndarray, shape (7,)
        Sd of the zero-mean normal prior of each linear coefficient (system p.u.);
        ``p_m0`` (the motor's initial active power) is truncated to positive values.
    tau_shape, tau_rate : float
        Gamma prior (shape, rate) of each noise precision.
    """

    theta_mean: np.ndarray
    theta_sd: np.ndarray
    beta_sd: np.ndarray
    tau_shape: float = 1e-3
    tau_rate: float = 1e-9

    @classmethod
    def default(cls, events: Sequence[EventRecord], *, scale: float = 10.0) -> CompositePrior:
        """Weak default: THETA_PRIOR, and ``beta_sd = scale * max |S|`` of the data."""
        s = max(float(np.max(np.hypot(e.p, e.q))) for e in events)
        return cls(
            np.array([THETA_PRIOR[n][0] for n in THETA_NAMES]),
            np.array([THETA_PRIOR[n][1] for n in THETA_NAMES]),
            np.full(7, scale * s),
        )

    def scale_free(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """The prior in the sampled coordinates ``u`` (five) and of ``log T0`` given ``u``.

        Returns
        -------
        (mean_u, cov_u, gain, sd_cond)
            ``u ~ N(mean_u, cov_u)`` (the marginal of the theta prior through
            ``SCALE_FREE_MATRIX``); ``log T0 | u ~ N(m6 + gain @ (u - mean_u), sd_cond^2)``.
        """
        # Read every iteration (log_u, draw_log_t0): the instance keeps what the cache gave.
        mine = self.__dict__.get("_scale_free")
        if mine is not None:
            return mine
        key = (self.theta_mean.tobytes(), self.theta_sd.tobytes())
        hit = _SCALE_FREE_CACHE.get(key)
        if hit is not None:
            object.__setattr__(self, "_scale_free", hit)
            return hit
        mean = _T @ self.theta_mean
        cov = _T @ np.diag(self.theta_sd**2) @ _T.T
        cu = cov[:5, :5]
        gain = np.linalg.solve(cu, cov[:5, 5])
        var = cov[5, 5] - cov[5, :5] @ gain
        out = (mean[:5], cu, gain, float(np.sqrt(var)))
        _SCALE_FREE_CACHE[key] = out
        object.__setattr__(self, "_scale_free", out)
        return out

    def log_u(self, u: np.ndarray) -> float:
        """Log prior density of the scale-free coordinates ``u`` up to a constant."""
        mean, cov, _, _ = self.scale_free()
        prec = self.__dict__.get("_prec_u")
        if prec is None:
            key = ("prec", cov.tobytes())
            prec = _SCALE_FREE_CACHE.get(key)
            if prec is None:
                prec = _SCALE_FREE_CACHE[key] = np.linalg.inv(cov)
            object.__setattr__(self, "_prec_u", prec)
        d = u - mean
        return -0.5 * float(d @ prec @ d)

    def draw_log_t0(self, u: np.ndarray, rng: np.random.Generator) -> float:
        """``log T0 | u`` from the prior (the likelihood does not depend on it)."""
        mean, _, gain, sd = self.scale_free()
        return float(self.theta_mean[5] + gain @ (u - mean) + sd * rng.standard_normal())

    def draw_log_t0s(self, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """:meth:`draw_log_t0` of each row of ``u`` (n, 5) at once: the same normals, in order.

        A Generator's ``standard_normal(n)`` gives the n numbers that n single calls give.
        """
        mean, _, gain, sd = self.scale_free()
        z = rng.standard_normal(u.shape[0])
        return self.theta_mean[5] + (u - mean) @ gain + sd * z

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (for the output's settings)."""
        return {
            "theta": {
                n: {"mean_log": float(m), "sd_log": float(s)}
                for n, m, s in zip(THETA_NAMES, self.theta_mean, self.theta_sd, strict=True)
            },
            "beta_sd": dict(zip(BETA_NAMES, self.beta_sd.tolist(), strict=True)),
            "tau": {"shape": self.tau_shape, "rate": self.tau_rate},
        }


#: The named quantities of one event's coefficients that a prior can be put on.
COEFFICIENT_PRIOR_NAMES = ("a1", "a2", "a3", "a4", "a5", "a6", "f_m", "p0", "q0")


def named_coefficients(beta: np.ndarray) -> dict[str, np.ndarray]:
    """``a1..a6, f_m, p0, q0`` of coefficients ``beta`` (..., 7) (:data:`BETA_NAMES`)."""
    b = np.asarray(beta, dtype=float)
    cp, cq, pm = b[..., 0:3], b[..., 3:6], b[..., 6]
    p_zip = cp.sum(-1)
    q0 = cq.sum(-1)
    p0 = p_zip + pm
    with np.errstate(divide="ignore", invalid="ignore"):
        out = {f"a{i + 1}": cp[..., i] / p_zip for i in range(3)}
        out.update({f"a{i + 4}": cq[..., i] / q0 for i in range(3)})
        out["f_m"] = pm / p0
    out["p0"], out["q0"] = p0, q0
    return out


@dataclass(frozen=True)
class CoefficientPrior:
    """An extra prior factor on each event's linear coefficients (the static part, f_m).

    The coefficients' Gaussian prior (:class:`CompositePrior`) keeps them conjugate, so
    the sampler integrates them out; this factor ``r(beta)`` multiplies it, and the
    sampler handles it exactly by importance weights (fit/composite/sampler.py): a normal
    factor ``{name: (mean, sd)}`` on a named quantity (:data:`COEFFICIENT_PRIOR_NAMES`),
    prior knowledge of a share, of the motor share or of the operating point. (Shares
    held in [0, 1] are not a factor: ``--shares bounded`` is its own parametrisation,
    fit/composite/bounded.py.)

    Each factor multiplies the Gaussian prior, so the stated normal is the prior of that
    quantity only where the Gaussian one is flat at its scale (it is: ten times the
    data's largest apparent power).
    """

    normal: tuple[tuple[str, float, float], ...] = ()

    def __post_init__(self) -> None:
        for name, mean, sd in self.normal:
            if name not in COEFFICIENT_PRIOR_NAMES:
                raise ValueError(f"no prior on {name!r}: one of {COEFFICIENT_PRIOR_NAMES}")
            if not (math.isfinite(mean) and math.isfinite(sd) and sd > 0):
                raise ValueError(f"prior of {name}: the mean must be finite, the sd positive")

    @property
    def active(self) -> bool:
        """Whether there is any factor (else the plain conjugate sampler runs)."""
        return bool(self.normal)

    def log_factor(self, beta: np.ndarray) -> np.ndarray:
        """``log r(beta)`` of coefficients (..., 7).

        ``-inf`` where a named quantity is not finite (a share of a zero static part).
        """
        b = np.asarray(beta, dtype=float)
        out = np.zeros(b.shape[:-1])
        named = named_coefficients(b)
        for name, mean, sd in self.normal:
            z = (named[name] - mean) / sd
            out = out - 0.5 * np.where(np.isfinite(z), z * z, np.inf)
        return out

    def to_dict(self) -> dict[str, Any]:
        """For the JSON's settings."""
        return {
            "normal": {name: [mean, sd] for name, mean, sd in self.normal},
        }
