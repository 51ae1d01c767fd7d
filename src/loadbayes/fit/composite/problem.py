"""The composite load's inference problem: its collapsed log-density.

:class:`CompositeProblem` holds the events (with the virtual knots of their steps
between samples, models/composite_steps.py) and evaluates ``log p(u) + sum_e log p(y_e |
u, tau)`` with every event's linear coefficients integrated out, in one compiled call.
The NLS start is :mod:`loadbayes.fit.composite.nls`, the sampler
:mod:`loadbayes.fit.composite.sampler`, the driver :mod:`loadbayes.fit.composite.driver`.

Several events share the motor (``THETA_NAMES``) and the noise precisions; each event
has its own seven linear coefficients (its own operating point, ZIP mix and motor
rating). Event 0's quantities carry the plain names (``p0, f_m, a1, ...``), event ``k``'s
the suffix ``_e{k}``. The prior is the model's (``models/composite_prior.py``).

One idea needs these 644 lines: the collapsed log-density of the composite's events,
from the events' layout to the one compiled call that evaluates it, with the conditional
draws of the coefficients the sampler takes from the same sums.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numba
import numpy as np

from loadbayes.fit.composite.bounded import (
    SHARE_COORDS,
    draw_gamma,
    shares_of,
)
from loadbayes.fit.composite.bounded_kernel import bounded_terms, draw_gamma_one, stacked
from loadbayes.fit.composite.sums import (
    ar_residual_sums,
    ar_sums_into,
    design_sums,
    design_sums_into,
    weighted_sums,
    x_sums,
)
from loadbayes.inference.condlinear import (
    GroupSums,
    draw_beta,
    draw_betas,
    log_marginal_arrays,
)
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import (
    BETA_NAMES,
    SCALE_FREE_MATRIX,
    SCALE_FREE_NAMES,
    THETA_NAMES,
    design,
    motor_response,
)
from loadbayes.models.composite_prior import POSITIVE_BETA, CompositePrior
from loadbayes.models.composite_steps import FitSamples, StepGrid, fill_times
from loadbayes.models.motor_kernel import (
    H_MAX_S,
    integrate_into,
    integrate_window_into,
    step_size,
)

__all__ = ["FREE_MOTOR", "CompositeProblem", "KernelResult", "Samples", "theta_of"]

#: The motor's free parameters the JSON lists first (the steps' instants follow).
FREE_MOTOR = ("f_m", "t_prime_s", "x_prime", "x_open", "h_s", "rs", "t0")

_T_INV = np.linalg.inv(SCALE_FREE_MATRIX)
#: The model's sizes: the scale-free motor coordinates sampled, each event's coefficients.
N_FREE, N_BETA = len(SCALE_FREE_NAMES), len(BETA_NAMES)
_T_INV_U = np.ascontiguousarray(_T_INV[:, :N_FREE].T)
_T_INV_T0 = np.ascontiguousarray(_T_INV[:, N_FREE])


def theta_of(u: np.ndarray, log_t0: float | np.ndarray) -> np.ndarray:
    """``THETA_NAMES`` values from the scale-free ``u`` (..., 5) and ``log T0`` (...)."""
    u = np.asarray(u, dtype=float)
    # theta = T^-1 (u, log T0): the first five columns act on u, the last on log T0.
    if type(log_t0) is float:  # one draw's (each kept iteration): the same products
        return u @ _T_INV_U + log_t0 * _T_INV_T0
    return u @ _T_INV_U + np.multiply.outer(np.asarray(log_t0, dtype=float), _T_INV_T0)


@dataclass(frozen=True)
class Samples:
    """The events' real samples concatenated (what the likelihood sees).

    ``starts`` (events + 1): where each event's samples begin, then the total; ``x``
    (``V / v0``), ``p``, ``q``: the samples; ``n`` (events, 2): each event's count, per
    channel (P, Q).
    """

    starts: np.ndarray
    x: np.ndarray
    p: np.ndarray
    q: np.ndarray
    n: np.ndarray

    @property
    def size(self) -> int:
        """Samples over all events."""
        return int(self.x.size)

    def event(self, e: int) -> slice:
        """The slice of event ``e``'s samples."""
        return slice(self.starts[e], self.starts[e + 1])


@dataclass
class KernelResult:
    """What one call of the compiled collapsed density gives back.

    ``lp`` is the log-density (finite), ``ztz``, ``zty``, ``yty`` each event's sums
    (``(events, 2, 7, 7)``, ``(events, 2, 7)``, ``(events, 2)``; weighted when weights
    were given), ``pm``, ``qm`` the motor's P, Q at every real sample (events
    concatenated).
    """

    lp: float
    ztz: np.ndarray
    zty: np.ndarray
    yty: np.ndarray
    pm: np.ndarray
    qm: np.ndarray


@dataclass
class CompositeProblem:
    """Events, prior and settings: the log-densities the samplers and NLS use."""

    events: list[EventRecord]
    prior: CompositePrior
    f_hz: float = 60.0
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0)
    h_max: float = H_MAX_S
    steps: bool = True
    #: The recorder's phasor window (s); None: one cycle of ``f_hz``. Sets how long an
    #: edge can be (models/composite_steps.py), and each sample is read as the motor's
    #: mean over the window centred on its stamp (0: point samples, the values at t_k).
    window_s: float | None = None
    #: Static shares held in [0, 1] (fit/composite/bounded.py): four more sampled
    #: coordinates per event, after the steps' fractions.
    bounded: bool = False
    #: Normal priors ``(share index 0-5, mean, sd)`` on the bounded shares (exact: the
    #: shares are sampled coordinates there).
    share_prior: tuple[tuple[int, float, float], ...] = ()
    evaluations: int = field(default=0, init=False)
    #: The sampled motor coordinates and each event's linear coefficients (the model's).
    n_free: ClassVar[int] = N_FREE
    free_coordinates: ClassVar[tuple[str, ...]] = SCALE_FREE_NAMES
    n_theta: ClassVar[int] = len(THETA_NAMES)
    n_beta: ClassVar[int] = N_BETA

    def __post_init__(self) -> None:
        self.m0 = np.zeros(N_BETA)
        self.p0 = 1.0 / self.prior.beta_sd**2
        # With a phasor window the samples inside a fault's edge are left out (point
        # samples keep them: the edge is a ramp); ``recorded`` keeps the events as given.
        self.recorded = list(self.events)
        self.window = window = 1.0 / self.f_hz if self.window_s is None else float(self.window_s)
        self.fit_samples = FitSamples.find(
            [e.t for e in self.recorded], [e.v for e in self.recorded], window_s=window,
            detect=self.steps,
        )  # fmt: skip
        self.events = [
            _subset(e, k) for e, k in zip(self.recorded, self.fit_samples.keep, strict=True)
        ]
        ev = self.events
        deltas = [np.zeros(e.n) if e.delta is None else e.delta - e.delta[0] for e in ev]
        # The kernel's input: the samples plus two virtual knots in every step interval
        # (models/composite_steps.py); the likelihood sees the real samples only.
        self.grid = StepGrid.build(
            [e.t for e in ev], [e.v for e in ev], deltas, detect=self.steps,
            intervals=self.fit_samples.intervals, ends=self.fit_samples.ends,
        )  # fmt: skip
        self._real = np.concatenate([self.grid.real_local(k) for k in range(len(ev))]).astype(
            np.int64
        )
        # AR(1) noise: where each segment of consecutive samples starts (an event's
        # first sample, and the first after samples left out).
        seg = []
        for keep in self.fit_samples.keep:
            start = np.ones(keep.size, dtype=bool)
            start[1:] = np.diff(keep) != 1
            seg.append(start)
        self.seg = np.concatenate(seg)
        self.samples = Samples(
            np.cumsum([0] + [e.n for e in ev]).astype(np.int64),
            np.concatenate([e.x for e in ev]),
            np.concatenate([e.p for e in ev]),
            np.concatenate([e.q for e in ev]),
            np.array([[e.n, e.n] for e in ev], dtype=float),
        )
        mean_u, cov_u, _, _ = self.prior.scale_free()
        self._mean_u, self._prec_u = mean_u, np.linalg.inv(cov_u)
        # The design's voltage-only sums do not depend on the motor: once per problem.
        self._xsums = np.stack([x_sums(e.x, e.p, e.q) for e in ev])
        # What every kernel call passes unchanged (kernel runs each iteration): once.
        d, g, self._n_steps = self.samples, self.grid, self.grid.n_steps
        self._kernel_data = (g.t, g.pos, g.left, g.width, g.pos_b, g.last, g.right, g.v_a,
                             g.v_l, g.v_b, g.v, g.delta, g.starts, self._real, d.x, d.p, d.q,
                             d.starts, d.n, self._mean_u, self._prec_u, self.m0, self.p0,
                             POSITIVE_BETA, 2.0 * math.pi * self.f_hz)  # fmt: skip
        self._torque = tuple(float(x) for x in self.torque)
        self._n_rows = list(d.n)  # each event's (n, n), as GroupSums takes it
        self._log_u_last: tuple[bytes, float] | None = None

    @property
    def n_steps(self) -> int:
        """Step intervals over all events: each adds its ``phi`` to the sampled vector."""
        return self.grid.n_steps

    @property
    def n_share_coords(self) -> int:
        """Sampled share coordinates (bounded shares: four per event; else none)."""
        return SHARE_COORDS * len(self.events) if self.bounded else 0

    @property
    def dim(self) -> int:
        """Length of the sampled vector: the motor's five, the steps, any share coordinates."""
        return N_FREE + self.grid.n_steps + self.n_share_coords

    def draw_scale(self, u: np.ndarray, rng: np.random.Generator) -> float:
        """``log T0 | u`` from its prior conditional (the sampler draws it each iteration).

        ``log T0`` sets the motor's base, which the terminal data never see.
        """
        return self.prior.draw_log_t0(np.asarray(u, dtype=float)[:N_FREE], rng)

    def draw_scales(self, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """:meth:`draw_scale` of each row of ``u`` (n, n_free), in one call."""
        return self.prior.draw_log_t0s(np.asarray(u, dtype=float)[:, :N_FREE], rng)

    def theta(self, u: np.ndarray, scale: float | np.ndarray = 0.0) -> np.ndarray:
        """``THETA_NAMES`` of the free coordinates ``u`` and the scale ``log T0``."""
        return theta_of(np.asarray(u, dtype=float)[..., :N_FREE], scale)

    def start_points(self) -> list[np.ndarray]:
        """Starts of the NLS search besides the prior's centre: each library motor's."""
        from loadbayes.models.motor_library import MOTORS

        return [
            (SCALE_FREE_MATRIX @ np.log([m.rs, m.xp, m.x - m.xp, m.tp_s, m.h_s, 0.6]))[:N_FREE]
            for m in MOTORS.values()
        ]

    def coarse(self, events: list[EventRecord]) -> CompositeProblem:
        """The problem on other events, without steps (the NLS search's thinned copy)."""
        return CompositeProblem(
            events, self.prior, f_hz=self.f_hz, torque=self.torque, h_max=self.h_max, steps=False
        )

    def designs(self, u: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """Each event's design matrices (``models.composite.design``) at ``u``, or None."""
        resp = self.responses(u)
        if resp is None:
            return None
        return [design(ev, pm, qm) for ev, (pm, qm) in zip(self.events, resp, strict=True)]

    #: P and Q: the channels of the likelihood, each with its noise precision.
    n_channels: ClassVar[int] = 2

    def channels(self, u: np.ndarray) -> list[list[tuple[np.ndarray, np.ndarray]]] | None:
        """Each event's ``[(Z_p, p), (Z_q, q)]`` at ``u`` (the NLS's view), or None."""
        zs = self.designs(u)
        if zs is None:
            return None
        return [[(zp, ev.p), (zq, ev.q)] for ev, (zp, zq) in zip(self.events, zs, strict=True)]

    def free_names(self) -> list[str]:
        """The motor's free parameters the JSON lists first (naming.FREE_MOTOR order)."""
        return list(FREE_MOTOR)

    def share_z(self, u: np.ndarray) -> np.ndarray:
        """The bounded shares' log-ratio coordinates in ``u``, (events, 4)."""
        i = N_FREE + self.grid.n_steps
        return np.asarray(u, dtype=float)[i : i + self.n_share_coords].reshape(-1, SHARE_COORDS)

    def share_arguments(self, tau, groups) -> tuple:
        """The compiled share terms' arguments after ``z`` (``bounded_kernel.py``)."""
        arrays = groups.arrays if isinstance(groups, _Stacked) else stacked(groups)
        return (*arrays, np.asarray(tau, dtype=float), *self._share_fixed())

    def _share_fixed(self) -> tuple:
        # gamma's prior precisions p0[[0, 3, 6]] and the share priors, made once.
        fixed = self.__dict__.get("_share_fixed_arrays")
        if fixed is None:
            sp = self.share_prior
            fixed = self.__dict__["_share_fixed_arrays"] = (
                np.asarray(self.p0, dtype=float)[[0, 3, 6]],
                np.array([i for i, _, _ in sp], dtype=np.int64),
                np.array([m for _, m, _ in sp], dtype=float),
                np.array([d for _, _, d in sp], dtype=float),
            )
        return fixed

    def _bounded_lp(self, u: np.ndarray, tau, groups) -> float:
        # The collapsed density of the bounded model (fit/composite/bounded.py), its
        # share terms compiled (fit/composite/bounded_kernel.py).
        z = np.ascontiguousarray(self.share_z(u))
        terms = bounded_terms(z, *self.share_arguments(tau, groups))
        return float(self._log_u(u) + terms)

    def _log_u(self, u: np.ndarray) -> float:
        # The motor's prior term of the current state, asked each iteration with a new
        # tau (log_collapsed): kept for the last u (its bytes; a rejected step keeps u).
        u5 = np.asarray(u, dtype=float)[:N_FREE]
        key, last = u5.tobytes(), self._log_u_last
        if last is not None and last[0] == key:
            return last[1]
        out = self.prior.log_u(u5)
        self._log_u_last = (key, out)
        return out

    def draw_coefficients(self, sums, tau, u, rng: np.random.Generator) -> list[np.ndarray]:
        """Every event's ``beta | u, tau`` (exact; bounded shares: fit/composite/bounded.py)."""
        if not self.bounded:
            return [draw_beta(s, tau, self.m0, self.p0, rng, positive=POSITIVE_BETA) for s in sums]
        # Compiled (bounded_kernel.draw_gamma_one): draw_gamma's arithmetic and draws.
        gamma_p0 = self._share_fixed()[0]
        tau = np.asarray(tau, dtype=float)
        return [
            draw_gamma_one(shares_of(z), g.ztz, g.zty, tau, gamma_p0, rng)
            for z, g in zip(self.share_z(u), sums, strict=True)
        ]

    def draw_coefficient_sets(self, sums, tau, u, rng, size: int) -> list[np.ndarray]:
        """``size`` draws of every event's ``beta | u, tau``, each (size, 7)."""
        if not self.bounded:
            return [
                draw_betas(s, tau, self.m0, self.p0, rng, size, positive=POSITIVE_BETA)
                for s in sums
            ]
        gamma_p0 = np.asarray(self.p0, dtype=float)[[0, 3, 6]]
        return [
            draw_gamma(g.ztz, g.zty, tau, shares_of(z), gamma_p0, rng, size)
            for z, g in zip(self.share_z(u), sums, strict=True)
        ]

    def phi(self, u: np.ndarray) -> np.ndarray:
        """The steps' fractions of their intervals (sampled as they are, in [0, 1]).

        A motor-only vector (five entries) puts every step mid-interval.
        """
        u, ns = np.asarray(u, dtype=float), self._n_steps
        if u.shape[-1] == N_FREE and ns:
            return np.full(u.shape[:-1] + (ns,), 0.5)
        if u.shape[-1] < N_FREE + ns:
            raise ValueError(
                f"expected at least {N_FREE + ns} sampled coordinates, got {u.shape[-1]}"
            )
        return u[..., N_FREE : N_FREE + ns]

    def in_support(self, u: np.ndarray) -> bool:
        """Whether every step's fraction lies in [0, 1] (the prior is uniform there).

        The fractions are sampled directly, and a proposal outside is rejected (zero
        density): a valid Metropolis move even with a correlated proposal, and it keeps
        a step at an interval's very edge (a fault at a sample instant, as simulators
        put it) reachable, where a logit would send it to infinity.
        """
        if not self._n_steps:
            return True
        # Plain floats: a handful of fractions, checked every iteration.
        return _in_unit(np.asarray(u, dtype=float)[N_FREE : N_FREE + self._n_steps].tolist())

    def _admissible(self, u: np.ndarray) -> bool:
        # Finite and in_support, from one list of plain floats (every evaluation's check):
        # a finite sum has no inf or nan among its terms; else each term is looked at.
        vals = u.tolist()
        if not math.isfinite(sum(vals)) and not all(map(math.isfinite, vals)):
            return False
        return _in_unit(vals[N_FREE : N_FREE + self._n_steps])

    def kernel(
        self,
        u: np.ndarray,
        tau: np.ndarray,
        torque: tuple[float, float, float] | None = None,
        weights: np.ndarray | None = None,
        rho: np.ndarray | None = None,
    ) -> KernelResult | None:
        """The compiled collapsed density at ``u`` (its motor part and steps), or None.

        ``weights`` (2, n): each sample's Student-t weight on P and Q (events
        concatenated); None for the Gaussian (its compact sums, ``sums.design_sums_into``).
        ``rho`` (2,): AR(1) noise on P and Q, the sums of the whitened designs
        (``sums.ar_sums_into``; the log-determinant, which does not depend on ``u``, is
        left out).
        None is returned outside the support, without a steady state or with a singular
        linear block. Counts one evaluation.
        """
        self.evaluations += 1
        u = np.asarray(u, dtype=float)
        if not self._admissible(u):
            return None
        n_ev, size = len(self.events), self.samples.size
        # Every entry is written by the compiled call (or the result is not returned).
        ztz, zty, yty = (
            np.empty((n_ev, 2, N_BETA, N_BETA)),
            np.empty((n_ev, 2, N_BETA)),
            np.empty((n_ev, 2)),
        )
        pm, qm = np.empty(size), np.empty(size)
        a, b, c = self._torque if torque is None else (float(x) for x in torque)
        weighted = weights is not None
        ns = self._n_steps
        phi = u[N_FREE : N_FREE + ns] if u.size >= N_FREE + ns else self.phi(u)
        u5 = u[:N_FREE]
        try:
            # exp(theta_of(u5, 0.0)): log T0 = 0 adds nothing the exponential can see.
            lp = _collapsed(
                u5, np.exp(u5 @ _T_INV_U), np.asarray(tau, dtype=float), phi,
                *self._kernel_data, a, b, c, float(self.h_max), self._xsums, weighted,
                weights if weighted else _NO_WEIGHTS, pm, qm, ztz, zty, yty,
                rho is not None, _NO_RHO if rho is None else np.asarray(rho, dtype=float),
                self.seg, self.window,
            )  # fmt: skip
        except np.linalg.LinAlgError:
            return None
        if not math.isfinite(lp):
            return None
        return KernelResult(lp, ztz, zty, yty, pm, qm)

    def group_sums(self, k: KernelResult) -> list[GroupSums]:
        """The events' :class:`GroupSums` of one kernel call."""
        out = [GroupSums(k.ztz[e], k.zty[e], k.yty[e], n) for e, n in enumerate(self._n_rows)]
        if not self.bounded:
            return out
        # Bounded shares: the kernel's arrays kept whole for the share terms, which read
        # them three times an iteration (bounded_kernel.stacked rebuilt them each time).
        return _Stacked(out, (k.ztz, k.zty, k.yty, np.asarray(self.samples.n, dtype=float)))

    def collapsed(
        self,
        u: np.ndarray,
        tau: np.ndarray,
        torque: tuple[float, float, float] | None = None,
        rho: np.ndarray | None = None,
    ) -> tuple[float, list[GroupSums] | None]:
        """``log p(u) + sum_e log p(y_e | u, tau)`` and the events' sums, in one compiled call.

        The same value as :meth:`log_collapsed` of :meth:`sums` (tested); ``(-inf, None)``
        when the motor has no steady state or the linear block is singular. ``torque``
        overrides ``self.torque`` for this call (estimated shares, fit.composite_torque).
        """
        k = self.kernel(u, tau, torque, rho=rho)
        if k is None:
            return -math.inf, None
        groups = self.group_sums(k)
        if rho is not None:
            groups = ResponseSums(groups, k.pm, k.qm)
        if self.bounded:
            return self._bounded_lp(np.asarray(u, dtype=float), tau, groups), groups
        return k.lp, groups

    def responses(
        self, u: np.ndarray, torque: tuple[float, float, float] | None = None
    ) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """The motor's P, Q in every event for scale-free ``u`` (None if no steady state).

        Simulated on the base where ``T0 = 1``; P and Q on any other base are these
        divided by the base ratio, which the linear block's ``p_m0`` absorbs exactly.
        """
        self.evaluations += 1
        u = np.asarray(u, dtype=float)
        if u.size > N_FREE and not self.in_support(u):
            return None
        theta = theta_of(u[:N_FREE], 0.0)
        t_aug = self.grid.times(self.phi(u))
        out = []
        tq = self.torque if torque is None else torque
        for k in range(len(self.events)):
            aug, real = self.grid.motor_input(k, t_aug)
            # At the real samples only (window means with a window), as _collapsed does.
            r = motor_response(aug, theta, f_hz=self.f_hz, torque=tq, h_max=self.h_max,
                               window_s=self.window, real=real)  # fmt: skip
            if r is None:
                return None
            out.append(r)
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

    def resum(self, sums: ResponseSums, rho: np.ndarray) -> ResponseSums:
        """The events' sums whitened for AR(1) coefficients ``rho`` (no motor solve)."""
        d, groups = self.samples, []
        for e in range(len(self.events)):
            sl = d.event(e)
            zz, zy, yy = np.zeros((2, N_BETA, N_BETA)), np.zeros((2, N_BETA)), np.zeros(2)
            ar_sums_into(d.x[sl], sums.pm[sl], sums.qm[sl], d.p[sl], d.q[sl], self.seg[sl],
                         np.asarray(rho, dtype=float), zz, zy, yy)  # fmt: skip
            groups.append(GroupSums(zz, zy, yy, d.n[e]))
        return ResponseSums(groups, sums.pm, sums.qm)

    def ar_statistics(self, sums: ResponseSums, betas) -> np.ndarray:
        """Residual sums of every event for the AR(1) step (``sums.ar_residual_sums``)."""
        d, out = self.samples, np.zeros((2, 4))
        for e, beta in enumerate(betas):
            sl = d.event(e)
            out += ar_residual_sums(d.x[sl], sums.pm[sl], sums.qm[sl], d.p[sl], d.q[sl],
                                    self.seg[sl], np.asarray(beta, dtype=float))  # fmt: skip
        return out

    def log_collapsed(self, sums: list[GroupSums] | None, u, tau) -> float:
        """``log p(u) + sum_e log p(y_e | u, tau)`` with beta integrated out."""
        if sums is None or not self._admissible(np.asarray(u, dtype=float)):
            return -math.inf
        if self.bounded:
            return self._bounded_lp(u, tau, sums)
        out = self._log_u(u)
        tau, m0, p0 = np.asarray(tau, dtype=float), self.m0, self.p0
        for s in sums:  # log_marginal's, its wrapper's conversions done once
            try:
                out += float(log_marginal_arrays(s.ztz, s.zty, s.yty, s.n, tau, m0, p0,
                                                 POSITIVE_BETA))  # fmt: skip
            except np.linalg.LinAlgError:
                out += -math.inf
        return out


def _subset(event: EventRecord, keep: np.ndarray) -> EventRecord:
    # The event with only the samples at ``keep`` (all of them: the same record).
    if keep.size == event.n:
        return event
    from dataclasses import replace

    delta = None if event.delta is None else event.delta[keep]
    return replace(event, t=event.t[keep], v=event.v[keep], p=event.p[keep], q=event.q[keep],
                   delta=delta)  # fmt: skip


@dataclass
class ResponseSums:
    """The events' :class:`GroupSums` with the motor's P, Q they came from (AR(1) noise).

    Iterates as the plain list does; :meth:`CompositeProblem.resum` whitens them again
    for a new ``rho`` without solving the motor again.
    """

    groups: list[GroupSums]
    pm: np.ndarray
    qm: np.ndarray

    def __iter__(self):
        return iter(self.groups)

    def __len__(self) -> int:
        return len(self.groups)

    def __getitem__(self, event: int) -> GroupSums:
        return self.groups[event]


class _Stacked(list):
    """The events' :class:`GroupSums` and the same sums as the kernel's arrays (E, G, ...)."""

    def __init__(self, groups, arrays) -> None:
        super().__init__(groups)
        self.arrays = arrays


def _in_unit(phi: list[float]) -> bool:
    """Whether every step's fraction (plain floats) lies in [0, 1]; NaN does not."""
    return all(0.0 <= f <= 1.0 for f in phi)


#: The rho argument of the white-noise kernel call (not read).
_NO_RHO = np.zeros(2)
#: The weights argument of the Gaussian kernel call (not read).
_NO_WEIGHTS = np.ones((2, 0))


@numba.njit(cache=True, nogil=True)
def _collapsed(  # pragma: no cover - compiled
    u, params, tau, phi, t_base, e_pos, e_left, e_width, e_pos_b, e_last, e_right, e_va, e_vl,
    e_vb, v, delta, starts_aug, real, x, p, q, starts, n, mean_u, prec_u,
    m0, p0, pos, wb, a, b, c, h_max, xsums, weighted, lam, pm, qm, ztz, zty, yty,
    ar, rho, seg, window,
):  # fmt: skip
    # The motor on the base where T0 = 1 (log T0 = 0), exponentiated by the caller with
    # NumPy as motor_response does: the log marginal is so ill-conditioned in the design
    # (a one-ulp change of H moves it by ~1e-6) that both paths must agree to the bit.
    # Each event: integrate the augmented input (the steps' virtual knots), keep the real
    # samples' P, Q in pm, qm, and add the log evidence of the event's (weighted) sums;
    # with weights, also sum log lambda / 2 (the likelihood's log-determinant).
    # The augmented times with the steps at fractions phi (StepGrid.times, its arrays e_*).
    t = t_base.copy()
    fill_times(t, e_pos, e_left, e_width, phi, e_pos_b, e_last, e_right, e_va, e_vl, e_vb)
    rs, xp, dx, tp, h, t0 = params[0], params[1], params[2], params[3], params[4], params[5]
    hm = step_size(tp, h_max)
    d = u - mean_u
    lp = -0.5 * (d @ (prec_u @ d))
    for e in range(starts.size - 1):
        s0, s1 = starts[e], starts[e + 1]
        a0, a1 = starts_aug[e], starts_aug[e + 1]
        m = a1 - a0
        idx = real[s0:s1]
        if window > 0.0:
            # Phasor samples: the motor's mean over each real sample's centred window.
            ok = integrate_window_into(
                t[a0:a1], v[a0:a1], delta[a0:a1], idx, window, rs, xp, dx, tp, h, wb, t0,
                a, b, c, hm, pm[s0:s1], qm[s0:s1],
            )  # fmt: skip
            if not ok:
                return -math.inf
        else:
            pa, qa, states = np.empty(m), np.empty(m), np.empty((3, m))
            ok = integrate_into(
                t[a0:a1], v[a0:a1], delta[a0:a1], rs, xp, dx, tp, h, wb, t0, a, b, c, hm,
                pa, qa, states,
            )  # fmt: skip
            if not ok:
                return -math.inf
            for i in range(s1 - s0):
                pm[s0 + i], qm[s0 + i] = pa[idx[i]], qa[idx[i]]
        xe, pme, qme, pe, qe = x[s0:s1], pm[s0:s1], qm[s0:s1], p[s0:s1], q[s0:s1]
        if weighted:
            zz, zy, yy = weighted_sums(xe, pme, qme, pe, qe, lam[0, s0:s1], lam[1, s0:s1])
            ztz[e], zty[e], yty[e] = zz, zy, yy
        elif ar:
            ar_sums_into(xe, pme, qme, pe, qe, seg[s0:s1], rho, ztz[e], zty[e], yty[e])
        else:
            design_sums_into(xe, pme, qme, pe, qe, xsums[e], ztz[e], zty[e], yty[e])
        lp += log_marginal_arrays(ztz[e], zty[e], yty[e], n[e], tau, m0, p0, pos)
    if weighted:
        for g in range(2):
            for i in range(lam.shape[1]):
                lp += 0.5 * math.log(lam[g, i])
    return lp
