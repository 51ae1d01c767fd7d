"""Estimated load-torque shares ``A, B, C`` (``A + B + C = 1``) for the composite fit.

The motor's mechanical torque is ``T0 (A w^2 + B w + C)``. With ``torque="estimate"``
the shares are parameters with a **Dirichlet(1, 1, 1)** prior (uniform on the simplex,
each share in [0, 1], prior mean 1/3, prior sd 0.236), sampled in **additive log-ratio
coordinates** ``z = (log(A/C), log(B/C))`` appended to the adaptive-Metropolis block
``u`` (after the motor's five coordinates and any steps' fractions: two more). In those
coordinates the Dirichlet density, Jacobian included, is ``prod_i s_i^alpha_i``:
``log p(z) = sum_i alpha_i log s_i``.

Why this prior: the loads an engineer meets are near the corners (fans and pumps,
``A = 1``; conveyors, compressors and other constant-torque drives, ``C = 1``) or in
between; a negative share has no physical reading for a load torque. The uniform
Dirichlet puts no preference on either corner and lets the data move the shares; its
log-ratio coordinates are unbounded, so the random walk needs no constraint. The corners
themselves are limits (``z -> infinity``), approached but never reached.

``T0`` multiplies the whole polynomial, so the base symmetry of the scale-free
coordinates (impedances x k, ``T0`` and ``H`` / k) holds for any shares (tested), and
the steady-state solver and the compiled kernel take general ``A, B, C``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from loadbayes.fit.composite.nls import NLSResult
from loadbayes.fit.composite.problem import CompositeProblem

__all__ = [
    "ALPHA",
    "PRIOR_SD",
    "TorqueProblem",
    "extend_start",
    "log_prior_z",
    "shares",
]

#: Dirichlet concentration of (A, B, C).
ALPHA = np.array([1.0, 1.0, 1.0])
#: Prior sd of each share under Dirichlet(1, 1, 1): sqrt(a_i (a0 - a_i) / (a0^2 (a0 + 1))).
PRIOR_SD = math.sqrt(2.0 / 36.0)


def shares(z: np.ndarray) -> tuple[float, float, float]:
    """``(A, B, C)`` from the log-ratio coordinates ``z = (log(A/C), log(B/C))``."""
    e = np.exp(np.array([z[0], z[1], 0.0]) - max(z[0], z[1], 0.0))
    s = e / e.sum()
    return float(s[0]), float(s[1]), float(s[2])


def log_prior_z(z: np.ndarray) -> float:
    """Log density of ``z`` under the Dirichlet prior (Jacobian included), up to a constant."""
    zz = np.array([z[0], z[1], 0.0])
    m = zz.max()
    log_s = zz - (m + math.log(np.exp(zz - m).sum()))
    return float(ALPHA @ log_s)


class TorqueProblem(CompositeProblem):
    """The composite problem with ``u = (motor's five, steps' fractions, log(A/C), log(B/C))``."""

    @property
    def dim(self) -> int:
        """The base problem's coordinates and the two log-ratios."""
        return super().dim + 2

    def collapsed(self, u, tau, torque=None, rho=None):
        """Collapsed log-density of ``u`` with its shares (see the module notes)."""
        if not np.all(np.isfinite(u)):
            return -math.inf, None
        lp, sums = super().collapsed(u[:-2], tau, torque=shares(u[-2:]), rho=rho)
        return lp + log_prior_z(u[-2:]), sums

    def sums(self, u, torque=None):
        """The events' sums at the shares ``u`` carries."""
        return super().sums(u[:-2], torque=shares(u[-2:]))

    def log_collapsed(self, sums, u, tau) -> float:
        """As :meth:`CompositeProblem.log_collapsed`, plus the shares' prior."""
        if not np.all(np.isfinite(u)):
            return -math.inf
        return super().log_collapsed(sums, u[:-2], tau) + log_prior_z(u[-2:])


def extend_start(start: NLSResult, z0: np.ndarray) -> NLSResult:
    """The sampler's start with the shares appended: ``z0`` and the prior's covariance.

    The ALR coordinates of a Dirichlet(1, 1, 1) have variance ``2 psi'(1)`` each and
    covariance ``psi'(1)`` (``psi'(1) = pi^2/6``); a quarter of it starts the proposal.
    """
    tri = math.pi**2 / 6.0
    cov_z = 0.25 * np.array([[2 * tri, tri], [tri, 2 * tri]])
    d = start.u.size
    cov = np.zeros((d + 2, d + 2))
    cov[:d, :d] = start.cov[:d, :d]
    cov[d:, d:] = cov_z
    return replace(start, u=np.concatenate([start.u, z0]), cov=cov)
