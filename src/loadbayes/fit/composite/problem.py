"""The composite load's inference problem: its prior and its collapsed log-density.

:class:`CompositeProblem` holds the events (with the virtual knots of their steps
between samples, models/composite_steps.py) and evaluates ``log p(u) + sum_e log p(y_e |
u, tau)`` with every event's linear coefficients integrated out, in one compiled call.
The NLS start is :mod:`loadbayes.fit.composite.nls`, the sampler
:mod:`loadbayes.fit.composite.sampler`, the driver :mod:`loadbayes.fit.composite.driver`.

Several events share the motor (``THETA_NAMES``) and the noise precisions; each event
has its own seven linear coefficients (its own operating point, ZIP mix and motor
rating). Event 0's quantities carry the plain names (``p0, f_m, a1, ...``), event ``k``'s
the suffix ``_e{k}``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from loadbayes.fit.composite.sums import _design_sums_into, design_sums, x_sums
from loadbayes.inference.condlinear import (
    GroupSums,
    log_marginal,
    log_marginal_arrays,
)
from loadbayes.models.composite import (
    BETA_NAMES,
    SCALE_FREE_MATRIX,
    THETA_NAMES,
    Event,
    motor_response,
)
from loadbayes.models.composite_steps import StepGrid
from loadbayes.models.motor_kernel import H_MAX_S, _integrate, step_size

__all__ = ["CompositePrior", "CompositeProblem", "THETA_PRIOR", "theta_of"]

#: Default prior of the motor's log-parameters: (median, sd of the log). Centred on the
#: library's typical motors (models/motor.md) with a wide spread: a factor e^sd either way.
THETA_PRIOR: dict[str, tuple[float, float]] = {
    "log_rs": (math.log(0.02), 1.0),
    "log_x_prime": (math.log(0.15), 0.7),
    "log_dx": (math.log(2.5), 0.7),
    "log_t_prime": (math.log(0.5), 1.2),
    "log_h": (math.log(0.8), 0.6),
    "log_t0": (math.log(0.6), 0.5),
}
_POS = BETA_NAMES.index("p_m0")
#: Sd of the Gaussian stand-in for a step fraction's uniform prior in the NLS start and
#: its Laplace covariance: wide, so that the data alone place the step.
STEP_PRIOR_SD = 10.0
_T = SCALE_FREE_MATRIX
_T_INV = np.linalg.inv(SCALE_FREE_MATRIX)
_T_INV5 = np.ascontiguousarray(_T_INV[:, :5])
# Priors are frozen dataclasses holding arrays (not hashable): cache by their bytes.
_SCALE_FREE_CACHE: dict[Any, Any] = {}


def theta_of(u: np.ndarray, log_t0: float | np.ndarray) -> np.ndarray:
    """``THETA_NAMES`` values from the scale-free ``u`` (..., 5) and ``log T0`` (...)."""
    u = np.asarray(u, dtype=float)
    full = np.concatenate(
        [u, np.expand_dims(np.asarray(log_t0, dtype=float) + 0 * u[..., 0], -1)], -1
    )
    return full @ _T_INV.T


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
    def default(cls, events: Sequence[Event], *, scale: float = 10.0) -> CompositePrior:
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


@dataclass
class CompositeProblem:
    """Events, prior and settings: the log-densities the samplers and NLS use."""

    events: list[Event]
    prior: CompositePrior
    f_hz: float = 60.0
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0)
    h_max: float = H_MAX_S
    steps: bool = True
    evaluations: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        self.m0 = np.zeros(7)
        self.p0 = 1.0 / self.prior.beta_sd**2
        ev = self.events
        self._starts = np.cumsum([0] + [e.n for e in ev]).astype(np.int64)
        deltas = [np.zeros(e.n) if e.delta is None else e.delta - e.delta[0] for e in ev]
        # The kernel's input: the samples plus two virtual knots in every step interval
        # (models/composite_steps.py); the likelihood sees the real samples only.
        self.grid = StepGrid.build([e.t for e in ev], [e.v for e in ev], deltas, detect=self.steps)
        self._real = np.concatenate([self.grid.real_local(k) for k in range(len(ev))]).astype(
            np.int64
        )
        self._x = np.concatenate([e.x for e in ev])
        self._p = np.concatenate([e.p for e in ev])
        self._q = np.concatenate([e.q for e in ev])
        self._n = np.array([[e.n, e.n] for e in ev], dtype=float)
        mean_u, cov_u, _, _ = self.prior.scale_free()
        self._mean_u, self._prec_u = mean_u, np.linalg.inv(cov_u)
        # The design's voltage-only sums do not depend on the motor: once per problem.
        self._xsums = np.stack([x_sums(e.x, e.p, e.q) for e in ev])

    @property
    def n_steps(self) -> int:
        """Step intervals over all events: each adds its ``phi`` to the sampled vector."""
        return self.grid.n_steps

    @property
    def dim(self) -> int:
        """Length of the sampled vector: five scale-free motor coordinates, then the steps."""
        return 5 + self.grid.n_steps

    def phi(self, u: np.ndarray) -> np.ndarray:
        """The steps' fractions of their intervals (sampled as they are, in [0, 1]).

        A motor-only vector (five entries) puts every step mid-interval.
        """
        u = np.asarray(u, dtype=float)
        if u.shape[-1] == 5 and self.n_steps:
            return np.full(u.shape[:-1] + (self.n_steps,), 0.5)
        if u.shape[-1] < 5 + self.n_steps:
            raise ValueError(
                f"expected at least {5 + self.n_steps} sampled coordinates, got {u.shape[-1]}"
            )
        return u[..., 5 : 5 + self.n_steps]

    def in_support(self, u: np.ndarray) -> bool:
        """Whether every step's fraction lies in [0, 1] (the prior is uniform there).

        The fractions are sampled directly, and a proposal outside is rejected (zero
        density): a valid Metropolis move even with a correlated proposal, and it keeps
        a step at an interval's very edge (a fault at a sample instant, as simulators
        put it) reachable, where a logit would send it to infinity.
        """
        phi = np.asarray(u, dtype=float)[5 : 5 + self.n_steps]
        return bool(np.all((phi >= 0.0) & (phi <= 1.0)))

    def collapsed(
        self, u: np.ndarray, tau: np.ndarray, torque: tuple[float, float, float] | None = None
    ) -> tuple[float, list[GroupSums] | None]:
        """``log p(u) + sum_e log p(y_e | u, tau)`` and the events' sums, in one compiled call.

        The same value as :meth:`log_collapsed` of :meth:`sums` (tested); ``(-inf, None)``
        when the motor has no steady state or the linear block is singular. ``torque``
        overrides ``self.torque`` for this call (estimated shares, fit.composite_torque).
        """
        self.evaluations += 1
        n_ev = len(self.events)
        ztz, zty, yty = np.zeros((n_ev, 2, 7, 7)), np.zeros((n_ev, 2, 7)), np.zeros((n_ev, 2))
        if not np.all(np.isfinite(u)) or not self.in_support(u):
            return -math.inf, None
        a, b, c = self.torque if torque is None else torque
        u = np.asarray(u, dtype=float)
        try:
            lp = _collapsed(
                u[:5],
                np.exp(theta_of(u[:5], 0.0)),
                np.asarray(tau, dtype=float),
                self.grid.times(self.phi(u)),
                self.grid.v,
                self.grid.delta,
                self.grid.starts,
                self._real,
                self._x,
                self._p,
                self._q,
                self._starts,
                self._n,
                self._mean_u,
                self._prec_u,
                _T_INV5,
                self.m0,
                self.p0,
                _POS,
                2.0 * math.pi * self.f_hz,
                float(a),
                float(b),
                float(c),
                float(self.h_max),
                self._xsums,
                ztz,
                zty,
                yty,
            )
        except np.linalg.LinAlgError:
            return -math.inf, None
        if not math.isfinite(lp):
            return -math.inf, None
        return lp, [GroupSums(ztz[e], zty[e], yty[e], self._n[e]) for e in range(n_ev)]

    def responses(
        self, u: np.ndarray, torque: tuple[float, float, float] | None = None
    ) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """The motor's P, Q in every event for scale-free ``u`` (None if no steady state).

        Simulated on the base where ``T0 = 1``; P and Q on any other base are these
        divided by the base ratio, which the linear block's ``p_m0`` absorbs exactly.
        """
        self.evaluations += 1
        u = np.asarray(u, dtype=float)
        if u.size > 5 and not self.in_support(u):
            return None
        theta = theta_of(u[:5], 0.0)
        t_aug = self.grid.times(self.phi(u))
        out = []
        tq = self.torque if torque is None else torque
        for k in range(len(self.events)):
            aug, real = self.grid.motor_input(k, t_aug)
            r = motor_response(aug, theta, f_hz=self.f_hz, torque=tq, h_max=self.h_max)
            if r is None:
                return None
            out.append((r[0][real], r[1][real]))
        return out

    def sums(
        self, u: np.ndarray, torque: tuple[float, float, float] | None = None
    ) -> list[GroupSums] | None:
        """Each event's sufficient sums for the linear block (None if infeasible)."""
        resp = self.responses(u, torque)
        if resp is None:
            return None
        out = []
        for ev, (pm, qm) in zip(self.events, resp, strict=True):
            # Compiled sums of the two designs (models.composite.design), without forming
            # them: the sampler needs only Z'Z, Z'y and y'y. The same arithmetic as
            # _collapsed (the log marginal is ill-conditioned in Z'Z: the columns x^2, x,
            # 1 are nearly collinear, so a different summation order moves it by ~1e-8).
            ztz, zty, yty = design_sums(ev.x, pm, qm, ev.p, ev.q)
            out.append(GroupSums(ztz, zty, yty, np.array([ev.n, ev.n], dtype=float)))
        return out

    def log_collapsed(self, sums: list[GroupSums] | None, u, tau) -> float:
        """``log p(u) + sum_e log p(y_e | u, tau)`` with beta integrated out."""
        if sums is None or not np.all(np.isfinite(u)):
            return -math.inf
        if u.size > 5 and not self.in_support(u):
            return -math.inf
        out = self.prior.log_u(u[:5])
        for s in sums:
            out += log_marginal(s, tau, self.m0, self.p0, positive=_POS)
        return out


@numba.njit(cache=True, nogil=True)
def _collapsed(  # pragma: no cover - compiled
    u,
    params,
    tau,
    t,
    v,
    delta,
    starts_aug,
    real,
    x,
    p,
    q,
    starts,
    n,
    mean_u,
    prec_u,
    t_inv,
    m0,
    p0,
    pos,
    wb,
    a,
    b,
    c,
    h_max,
    xsums,
    ztz,
    zty,
    yty,
):
    # The motor on the base where T0 = 1 (log T0 = 0), exponentiated by the caller with
    # NumPy as motor_response does: the log marginal is so ill-conditioned in the design
    # (a one-ulp change of H moves it by ~1e-6) that both paths must agree to the bit.
    rs, xp, dx, tp, h, t0 = params[0], params[1], params[2], params[3], params[4], params[5]
    hm = step_size(tp, h_max)
    d = u - mean_u
    lp = -0.5 * (d @ (prec_u @ d))
    for e in range(starts.size - 1):
        s0, s1 = starts[e], starts[e + 1]
        a0, a1 = starts_aug[e], starts_aug[e + 1]
        m = a1 - a0
        pm, qm, states = np.empty(m), np.empty(m), np.empty((3, m))
        ok = _integrate(
            t[a0:a1],
            v[a0:a1],
            delta[a0:a1],
            rs,
            xp,
            dx,
            tp,
            h,
            wb,
            t0,
            a,
            b,
            c,
            hm,
            pm,
            qm,
            states,
        )
        if not ok:
            return -math.inf
        if m != s1 - s0:  # outputs at the virtual knots are not data
            pm, qm = pm[real[s0:s1]], qm[real[s0:s1]]
        _design_sums_into(x[s0:s1], pm, qm, p[s0:s1], q[s0:s1], xsums[e], ztz[e], zty[e], yty[e])
        zz, zy, yy = ztz[e], zty[e], yty[e]
        lp += log_marginal_arrays(zz, zy, yy, n[e], tau, m0, p0, pos)
    return lp
