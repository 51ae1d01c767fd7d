"""The AR(1) coefficient of a Gaussian noise series given its residuals (physics-free).

Noise ``e_k = rho e_k-1 + eps_k``, ``eps_k ~ N(0, 1/tau)``, stationary, in segments of
consecutive samples (the first of a segment drawn from the stationary law,
``N(0, 1 / (tau (1 - rho^2)))``). With a uniform prior on (-1, 1) the conditional of
``rho`` given the residuals is

    p(rho | e) ∝ exp(-tau/2 (a rho^2 - 2 b rho)) (1 - rho^2)^(S/2),

with ``b = sum e_k e_k-1``, ``a = sum e_k-1^2 - sum e_s^2`` (``k`` over the samples that
follow one in their segment, ``s`` over the segments' first samples) and ``S`` segments.
:func:`draw_rho` proposes from the Gaussian factor (truncated to (-1, 1), by inverse CDF)
and accepts with the ratio of the remaining factor: an independence Metropolis-Hastings
step that leaves the conditional invariant and is accepted nearly always (the factor
is flat where the residuals put ``rho`` unless ``|rho|`` nears 1).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

__all__ = ["RHO_MAX", "draw_rho"]

#: The proposal stays inside (-RHO_MAX, RHO_MAX): the stationary variance is finite.
RHO_MAX = 0.999


def draw_rho(
    stats: np.ndarray, tau: float, rho: float, rng: np.random.Generator
) -> tuple[float, bool]:
    """One step for ``rho``: ``stats = [b, sum e_k-1^2, sum e_s^2, S]``; (rho, moved)."""
    b, a_ns, a_st, segments = (float(v) for v in stats)
    a = a_ns - a_st
    if not (a > 0 and tau > 0):
        return rho, False
    m, sd = b / a, 1.0 / math.sqrt(tau * a)
    lo, hi = special.ndtr((-RHO_MAX - m) / sd), special.ndtr((RHO_MAX - m) / sd)
    if not hi > lo:
        return rho, False
    w = rng.uniform(lo, hi)
    cand = float(np.clip(m + sd * special.ndtri(w), -RHO_MAX, RHO_MAX))
    log_ratio = 0.5 * segments * (math.log1p(-cand * cand) - math.log1p(-rho * rho))
    if log_ratio >= 0 or rng.uniform() < math.exp(log_ratio):
        return cand, True
    return rho, False
