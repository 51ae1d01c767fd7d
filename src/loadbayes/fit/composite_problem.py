"""The composite load's inference problem: prior, collapsed log-density, NLS, the sampler.

Data -> :func:`nls` (``scipy.optimize.least_squares`` on the same model, variable
projection: the linear coefficients solved inside) -> :func:`sample` (Metropolis-within-
Gibbs: an adaptive-Metropolis block on the motor's six log-parameters with the linear
coefficients integrated out, then the linear coefficients and the noise precisions
drawn exactly) -> :class:`~loadbayes.posterior.Posterior` named as docs/composite.md.

Several events share the motor (``THETA_NAMES``) and the noise precisions; each event
has its own seven linear coefficients (its own operating point, ZIP mix and motor
rating). Event 0's quantities carry the plain names (``p0, f_m, a1, ...``), event ``k``'s
the suffix ``_e{k}``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from scipy import optimize

from loadbayes.fit.composite_sums import _design_sums_into, design_sums, x_sums
from loadbayes.inference.adaptive_metropolis import AdaptiveMetropolis, run_chains
from loadbayes.inference.condlinear import (
    GroupSums,
    draw_beta,
    draw_tau,
    log_marginal,
    log_marginal_arrays,
    residual_ss,
)
from loadbayes.inference.factor_slice import FactorSlice
from loadbayes.models.composite import (
    BETA_NAMES,
    SCALE_FREE_MATRIX,
    THETA_NAMES,
    Event,
    design,
    motor_response,
)
from loadbayes.models.composite_steps import StepGrid
from loadbayes.models.motor_kernel import H_MAX_S, _integrate, step_size

__all__ = [
    "CompositePrior",
    "CompositeProblem",
    "DEFAULT_MOVE",
    "MOVES",
    "NLSResult",
    "THETA_PRIOR",
    "nls",
    "sample",
    "theta_of",
]

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
        self._real = np.concatenate(
            [
                self.grid.real[self._starts[k] : self._starts[k + 1]] - self.grid.starts[k]
                for k in range(len(ev))
            ]
        ).astype(np.int64)
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
        t_aug, g = self.grid.times(self.phi(u)), self.grid
        out = []
        tq = self.torque if torque is None else torque
        for k in range(len(self.events)):
            s0, s1 = g.starts[k], g.starts[k + 1]
            aug = Event(t_aug[s0:s1], g.v[s0:s1], g.v[s0:s1], g.v[s0:s1], g.delta[s0:s1])
            r = motor_response(aug, theta, f_hz=self.f_hz, torque=tq, h_max=self.h_max)
            if r is None:
                return None
            real = self._real[self._starts[k] : self._starts[k + 1]]
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


@numba.njit(cache=True, nogil=True)
def _design_sums(x, pm, qm, p, q):  # pragma: no cover - compiled
    ztz = np.zeros((2, 7, 7))
    zty = np.zeros((2, 7))
    yty = np.zeros(2)
    pm0, qm0 = pm[0], qm[0]
    zp = np.zeros(7)
    zq = np.zeros(7)
    for i in range(x.size):
        x2 = x[i] * x[i]
        zp[0], zp[1], zp[2], zp[6] = x2, x[i], 1.0, pm[i] / pm0
        zq[3], zq[4], zq[5], zq[6] = x2, x[i], 1.0, (qm[i] - qm0 * x2) / pm0
        for a in range(7):
            zty[0, a] += zp[a] * p[i]
            zty[1, a] += zq[a] * q[i]
            for b in range(7):
                ztz[0, a, b] += zp[a] * zp[b]
                ztz[1, a, b] += zq[a] * zq[b]
        yty[0] += p[i] * p[i]
        yty[1] += q[i] * q[i]
    return ztz, zty, yty


# ------------------------------------------------------------------------- NLS
@dataclass
class NLSResult:
    """The least-squares point estimate and its Gaussian approximation."""

    u: np.ndarray  # (5 + steps,) scale-free motor coordinates, then each step's fraction phi
    betas: np.ndarray  # (events, 7)
    sigma: np.ndarray  # (2,) residual sd of P and Q
    cov: np.ndarray  # covariance of (u, betas.ravel())
    cost: float
    seconds: float
    nfev: int


def _library_starts() -> list[np.ndarray]:
    from loadbayes.cases.motor_sim import MOTORS

    starts = []
    for m in MOTORS.values():
        starts.append((_T @ np.log([m.rs, m.xp, m.x - m.xp, m.tp_s, m.h_s, 0.6]))[:5])
    return starts


def _project(problem: CompositeProblem, u: np.ndarray, w: np.ndarray):
    resp = problem.responses(u)
    if resp is None:
        return None
    res, betas = [], []
    for ev, (pm, qm) in zip(problem.events, resp, strict=True):
        zp, zq = design(ev, pm, qm)
        z = np.vstack([w[0] * zp, w[1] * zq])
        y = np.concatenate([w[0] * ev.p, w[1] * ev.q])
        # A whisper of the prior keeps the projection defined when a column vanishes.
        ridge = np.sqrt(problem.p0)
        beta = np.linalg.lstsq(np.vstack([z, np.diag(ridge)]), np.append(y, 0 * ridge), None)[0]
        res.append(y - z @ beta)
        betas.append(beta)
    return np.concatenate(res), np.array(betas)


def nls(problem: CompositeProblem, *, starts: Sequence[np.ndarray] | None = None) -> NLSResult:
    """Penalised nonlinear least squares of the composite model (variable projection).

    The motor's five scale-free coordinates are found by ``scipy.optimize.least_squares``
    from the prior median and each library motor (the best start is kept); the linear
    coefficients are solved inside each residual evaluation. The residuals are P and Q
    divided by their noise sds (first guessed from a static ZIP fit, then re-estimated
    once), plus the prior of ``u`` as whitened Tikhonov rows: without them a shallow
    event lets the estimate run off along directions the data do not see (this is the
    MAP of ``u`` with beta profiled out, the usual regularised NLS). The covariance is
    the Gauss-Newton one of ``(u, every event's beta)`` with the prior's precision added.
    """
    t_start = time.perf_counter()
    mean_m, cov_m, _, _ = problem.prior.scale_free()
    # The steps' fractions join the motor's coordinates, bounded to [0, 1] (their
    # uniform prior) and started mid-interval; a Tikhonov row of sd 10 (a negligible
    # pull) keeps the whitening square.
    k = problem.n_steps
    mean_s = np.full(k, 0.5)
    mean_u = np.concatenate([mean_m, mean_s])
    cov_u = np.zeros((problem.dim, problem.dim))
    cov_u[:5, :5] = cov_m
    cov_u[5:, 5:] = np.eye(k) * STEP_PRIOR_SD**2
    sd_u = np.sqrt(np.diag(cov_u))
    white = np.linalg.inv(np.linalg.cholesky(cov_u))
    lo, hi = mean_u - 6 * sd_u, mean_u + 6 * sd_u
    lo[5:], hi[5:] = 0.0, 1.0
    sd_u[5:] = 0.2
    starts = list(starts) if starts is not None else [mean_m, *_library_starts()]
    starts = [np.concatenate([np.asarray(x0)[:5], mean_s]) for x0 in starts]
    nfev = 0

    def run(w, x0, max_nfev=None, prob=problem):
        # The coarse copy may have no steps (d = 5): the prior's whitening is block
        # diagonal (motor, steps), so its leading block serves.
        d = prob.dim
        n_res = 2 * sum(e.n for e in prob.events) + d
        m, wh, lo_d, hi_d = mean_u[:d], white[:d, :d], lo[:d], hi[:d]

        def fun(u):
            out = _project(prob, u, w)
            if out is None:
                return np.full(n_res, 1e3)
            return np.concatenate([out[0], wh @ (u - m)])

        x0 = np.clip(np.asarray(x0)[:d], lo_d + 1e-9, hi_d - 1e-9)
        return optimize.least_squares(
            fun, x0, bounds=(lo_d, hi_d), x_scale=sd_u[:d], max_nfev=max_nfev
        )

    # The multi-start search on a copy thinned to at most ~COARSE_FS samples/s: which
    # start wins and roughly where it ends does not need 960 samples/s (at that rate the
    # search took 7 of the 8 s of the fit); the final fit below uses every sample.
    coarse = _thinned(problem)
    w = 1.0 / _static_sigmas(coarse)
    best = None
    for x0 in starts:
        sol = run(w, x0, max_nfev=60, prob=coarse)
        nfev += sol.nfev
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    x_best = np.concatenate([best.x[:5], mean_s]) if best.x.size < problem.dim else best.x
    if coarse is not problem:
        w = 1.0 / _static_sigmas(problem)
    _, betas = _project(problem, x_best, w)
    w = 1.0 / _sigmas(problem, x_best, betas)
    sol = run(w, x_best)
    nfev += sol.nfev
    u = sol.x
    _, betas = _project(problem, u, w)
    sig = _sigmas(problem, u, betas)
    cov = _gauss_newton_cov(problem, u, betas, 1.0 / sig, np.linalg.inv(cov_u))
    return NLSResult(u, betas, sig, cov, float(sol.cost), time.perf_counter() - t_start, int(nfev))


#: Sample rate (per s) above which the NLS's multi-start search runs on thinned events.
COARSE_FS = 120.0


def _thinned(problem: CompositeProblem) -> CompositeProblem:
    # Every k-th sample, k = floor(COARSE_FS^-1 / median dt); the problem itself if k = 1.
    events = []
    for e in problem.events:
        k = max(1, int(1.0 / (COARSE_FS * float(np.median(np.diff(e.t))))))
        d = None if e.delta is None else e.delta[::k]
        events.append(Event(e.t[::k], e.v[::k], e.p[::k], e.q[::k], d, e.name))
    if all(a.n == b.n for a, b in zip(events, problem.events, strict=True)):
        return problem
    # Without steps: the search only needs where the motor's coordinates roughly are
    # (a thinned record's intervals are not the record's); the final fit places them.
    return CompositeProblem(
        events,
        problem.prior,
        f_hz=problem.f_hz,
        torque=problem.torque,
        h_max=problem.h_max,
        steps=False,
    )


def _static_sigmas(problem) -> np.ndarray:
    # Residual sds of a static ZIP fit (no motor): an upper bound of the noise.
    ssr, n = np.zeros(2), 0
    for ev in problem.events:
        z = np.stack([ev.x**2, ev.x, np.ones(ev.n)], axis=1)
        for g, y in enumerate((ev.p, ev.q)):
            r = y - z @ np.linalg.lstsq(z, y, None)[0]
            ssr[g] += r @ r
        n += ev.n
    return np.sqrt(np.maximum(ssr / n, 1e-30))


def _sigmas(problem, u, betas) -> np.ndarray:
    sums = problem.sums(u)
    ssr = sum(residual_ss(s, b) for s, b in zip(sums, betas, strict=True))
    n = sum(e.n for e in problem.events)
    return np.sqrt(np.maximum(ssr / n, 1e-30))


def _gauss_newton_cov(problem, u, betas, w, prec_u) -> np.ndarray:
    def full(uu, bs):
        resp = problem.responses(uu)
        parts = []
        for ev, (pm, qm), b in zip(problem.events, resp, bs, strict=True):
            zp, zq = design(ev, pm, qm)
            parts += [w[0] * (ev.p - zp @ b), w[1] * (ev.q - zq @ b)]
        return np.concatenate(parts)

    n_ev = len(problem.events)
    d = problem.dim
    k = d + 7 * n_ev
    r0 = full(u, betas)
    jac = np.zeros((r0.size, k))
    for i in range(d):
        h = 1e-5
        up, um = u.copy(), u.copy()
        up[i] += h
        um[i] -= h
        if problem.responses(up) is None or problem.responses(um) is None:
            continue
        jac[:, i] = (full(up, betas) - full(um, betas)) / (2 * h)
    resp = problem.responses(u)
    row = 0
    for e, (ev, (pm, qm)) in enumerate(zip(problem.events, resp, strict=True)):
        zp, zq = design(ev, pm, qm)
        n = ev.n
        jac[row : row + n, d + 7 * e : d + 7 + 7 * e] = -w[0] * zp
        jac[row + n : row + 2 * n, d + 7 * e : d + 7 + 7 * e] = -w[1] * zq
        row += 2 * n
    # The prior's precision (as in the penalised fit): a direction the data do not see
    # gets the prior's spread, not an infinite variance.
    prec = jac.T @ jac
    prec[:d, :d] += prec_u
    prec[d:, d:] += np.diag(np.tile(problem.p0, n_ev))
    return np.linalg.inv(prec)


# ----------------------------------------------------------------------- sampler
#: The u-moves :func:`sample` offers (both physics-free, same ``step`` interface).
MOVES = {"am": AdaptiveMetropolis, "slice": FactorSlice}
#: The default u-move: the better ESS per second on the benchmark (docs/composite.md).
DEFAULT_MOVE = "am"


@dataclass
class ChainResult:
    """One chain's kept draws and acceptance."""

    theta: np.ndarray  # (kept, 6) THETA_NAMES
    beta: np.ndarray  # (kept, events, 7)
    tau: np.ndarray  # (kept, 2)
    acceptance: float
    phi: np.ndarray | None = None  # (kept, steps) fractions of the step intervals
    evaluations_per_iteration: float = 1.0  # collapsed-density evaluations of the u-move
    # Coordinates of u after the motor's five and the steps (estimated torque shares).
    u_extra: np.ndarray | None = None
    # Student-t only (fit.composite_robust): nu draws (kept, 2), mean weights (2, n).
    nu: np.ndarray | None = None
    weight: np.ndarray | None = None
    nu_acceptance: float | None = None


def sample(
    problem: CompositeProblem,
    *,
    start: NLSResult,
    draws: int = 5000,
    burn: int = 2000,
    thin: int = 1,
    chains: int = 4,
    seed: int = 0,
    workers: int | None = None,
    dispersion: float = 2.0,
    move: str = DEFAULT_MOVE,
    student_t: Any = None,
) -> list[ChainResult]:
    """Metropolis-within-Gibbs for the composite model.

    Each iteration: the scale-free motor coordinates ``u | tau`` by adaptive Metropolis
    on the collapsed density (beta integrated out); every event's
    ``beta | u, tau`` exactly; ``tau | u, beta`` (two gammas); ``log T0 | u`` from its
    prior conditional (the likelihood does not depend on it). The proposal starts from
    the Laplace covariance (the NLS one) and adapts during ``burn``, then freezes.
    Chains start ``dispersion`` Laplace sds around the NLS estimate (for R-hat).

    Parameters
    ----------
    problem : CompositeProblem
        Data, prior, settings.
    start : NLSResult
        From :func:`nls`.
    draws, burn, thin, chains : int
        Iterations per chain including burn-in, burn-in, thinning, chains.
    seed : int
        Root seed (chain ``i`` uses child ``i`` of ``SeedSequence(seed)``).
    workers : int, optional
        Threads for the chains.
    dispersion : float
        Spread of the chains' starting points, in Laplace sds.
    move : {"am", "slice"}
        The u-move (:data:`MOVES`): adaptive Metropolis, or factor slice sampling in
        the eigenbasis of the covariance learned in burn-in (docs/composite.md, "Why
        this move").
    student_t : loadbayes.fit.composite_robust.StudentT, optional
        Student-t noise (a weights step each iteration); Gaussian noise when None.

    Returns
    -------
    list of ChainResult
    """
    if not 0 <= burn < draws:
        raise ValueError(f"need 0 <= burn < draws, got burn={burn}, draws={draws}")
    if move not in MOVES:
        raise ValueError(f"move must be one of {sorted(MOVES)}, got {move!r}")
    prior = problem.prior
    # The motor's five, the steps' fractions, then any extra coordinates (torque shares).
    d = dim = problem.dim
    n_base = 5 + problem.n_steps
    lap = start.cov[:d, :d]
    lap = (lap + lap.T) / 2
    # A step the data barely place has a Laplace sd far wider than its [0, 1] support:
    # start its proposal at the support's scale instead (the adaptation takes over).
    shrink = np.ones(d)
    shrink[5:] = np.minimum(1.0, 0.3 / np.sqrt(np.diag(lap)[5:]))
    lap = lap * np.outer(shrink, shrink)
    tau0 = 1.0 / start.sigma**2
    n_tot = np.array([sum(e.n for e in problem.events)] * 2, dtype=float)
    kept_idx = range(burn, draws, thin)
    root = np.linalg.cholesky(lap + 1e-12 * np.eye(dim))

    def chain(index: int, rng: np.random.Generator) -> ChainResult:
        am = MOVES[move](lap, adapt_until=burn, adapt_start=min(200, max(burn // 4, 1)))
        u, sums = start.u, None
        for _ in range(100):
            cand = start.u + dispersion * root @ rng.standard_normal(dim)
            sums = problem.sums(cand)
            if sums is not None:
                u = cand
                break
        if sums is None:
            u, sums = start.u, problem.sums(start.u)
        tau = tau0.copy()
        th_out = np.empty((len(kept_idx), 6))
        phi_out = np.empty((len(kept_idx), problem.n_steps))
        b_out = np.empty((len(kept_idx), len(problem.events), 7))
        t_out = np.empty((len(kept_idx), 2))
        x_out = np.empty((len(kept_idx), dim - n_base))
        j = 0
        # Student-t noise: the weights' state (None for the Gaussian, whose path is unchanged).
        wt = None if student_t is None else student_t.chain(problem, u, tau, len(kept_idx))
        if wt is not None:
            sums = wt.sums
        for it in range(draws):
            if wt is None:
                lp = problem.log_collapsed(sums, u, tau)

                def logp(x, tau=tau):
                    return problem.collapsed(x, tau)

            else:
                lp, logp = wt.current(u, tau), wt.logp(tau)
            u, lp, sums, _ = am.step(u, lp, logp, rng, it, aux=sums)
            betas = [draw_beta(s, tau, problem.m0, problem.p0, rng, positive=_POS) for s in sums]
            if wt is not None:  # (nu, lambda) | u, beta, tau; then tau sees the weighted SSR
                sums = wt.update(sums, betas, tau, rng, it >= burn and (it - burn) % thin == 0)
            ssr = sum(residual_ss(s, b) for s, b in zip(sums, betas, strict=True))
            tau = draw_tau(ssr, n_tot, prior.tau_shape, prior.tau_rate, rng)
            log_t0 = prior.draw_log_t0(u[:5], rng)
            if it >= burn and (it - burn) % thin == 0:
                th_out[j] = theta_of(u[:5], log_t0)
                phi_out[j] = problem.phi(u)
                x_out[j] = u[n_base:]
                b_out[j], t_out[j] = np.array(betas), tau
                j += 1
        robust = {}
        if wt is not None:
            robust = dict(zip(("nu", "weight", "nu_acceptance"), wt.result(), strict=True))
        return ChainResult(
            th_out,
            b_out,
            t_out,
            am.acceptance,
            phi=phi_out,
            evaluations_per_iteration=am.evaluations_per_step,
            u_extra=x_out if dim > n_base else None,
            **robust,
        )

    return run_chains(chain, chains, seed=seed, workers=workers)
