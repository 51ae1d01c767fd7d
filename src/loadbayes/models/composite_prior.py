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

from loadbayes.models.composite import BETA_NAMES, SCALE_FREE_MATRIX, THETA_NAMES, EventRecord

__all__ = ["POSITIVE_BETA", "STEP_PRIOR_SD", "THETA_PRIOR", "CompositePrior"]

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
        key = (self.theta_mean.tobytes(), self.theta_sd.tobytes())
        hit = _SCALE_FREE_CACHE.get(key)
        if hit is not None:
            return hit
        mean = _T @ self.theta_mean
        cov = _T @ np.diag(self.theta_sd**2) @ _T.T
        cu = cov[:5, :5]
        gain = np.linalg.solve(cu, cov[:5, 5])
        var = cov[5, 5] - cov[5, :5] @ gain
        out = (mean[:5], cu, gain, float(np.sqrt(var)))
        _SCALE_FREE_CACHE[key] = out
        return out

    def log_u(self, u: np.ndarray) -> float:
        """Log prior density of the scale-free coordinates ``u`` up to a constant."""
        mean, cov, _, _ = self.scale_free()
        key = ("prec", cov.tobytes())
        prec = _SCALE_FREE_CACHE.get(key)
        if prec is None:
            prec = _SCALE_FREE_CACHE[key] = np.linalg.inv(cov)
        d = u - mean
        return -0.5 * float(d @ prec @ d)

    def draw_log_t0(self, u: np.ndarray, rng: np.random.Generator) -> float:
        """``log T0 | u`` from the prior (the likelihood does not depend on it)."""
        mean, _, gain, sd = self.scale_free()
        return float(self.theta_mean[5] + gain @ (u - mean) + sd * rng.standard_normal())

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
