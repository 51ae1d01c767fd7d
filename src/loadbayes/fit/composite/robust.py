"""Student-t noise for the composite load: the weights step of the sampler.

The scale-mixture form (:mod:`loadbayes.inference.student_weights`): sample ``k`` of
channel ``g`` (P or Q) has a latent weight ``lambda_gk ~ Gamma(nu_g/2, rate nu_g/2)`` and
noise ``N(0, 1/(tau_g lambda_gk))``. Given the weights the model is the Gaussian one with
weighted sums, so the sampler of :mod:`loadbayes.fit.composite.problem` keeps its
structure and gains one step:

1. ``u | tau, lambda``: adaptive Metropolis on the collapsed density computed from
   ``Z'WZ``, ``Z'Wy``, ``y'Wy`` plus ``sum log lambda / 2`` (:func:`collapsed_weighted`:
   the Gaussian's compiled loop, :meth:`CompositeProblem.kernel`, given the weights; the
   default path reads none, so it is exactly as fast and gives the same draws);
2. ``beta | u, tau, lambda`` exactly (the same code, on the weighted sums);
3. ``(nu_g, lambda_g) | u, beta, tau`` (:class:`StudentTChain.update`);
4. ``tau_g | u, beta, lambda``: the same gamma, with the weighted SSR.

``nu`` is fixed or estimated (``"auto"``: Gamma(2, 0.1) prior on [1, 1000], as the ZIP
fit's ``--likelihood student-t``), one per channel (``nu_p``, ``nu_q``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np

from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.sums import weighted_sums
from loadbayes.inference.condlinear import GroupSums, log_marginal_arrays
from loadbayes.inference.student_weights import draw_weights, step_nu
from loadbayes.models.composite_prior import POSITIVE_BETA

__all__ = ["StudentT", "StudentTChain", "WeightedSums", "collapsed_weighted", "robust_outputs"]


@dataclass
class WeightedSums:
    """The events' weighted :class:`GroupSums`, with the motor response they came from.

    Iterates over the events' sums as the Gaussian path's list does (the sampler reads
    either); ``pm``, ``qm`` are the motor's P, Q at every sample (events concatenated),
    which the weights step needs for the residuals.
    """

    groups: list[GroupSums]
    pm: np.ndarray
    qm: np.ndarray

    def __iter__(self) -> Iterator[GroupSums]:
        return iter(self.groups)

    def __len__(self) -> int:
        return len(self.groups)

    def __getitem__(self, event: int) -> GroupSums:
        return self.groups[event]


@dataclass(frozen=True)
class StudentT:
    """Student-t noise on P and Q: ``nu`` fixed (a number >= 1) or ``"auto"`` (sampled)."""

    nu: float | Literal["auto"] = "auto"
    #: Starting value of a sampled ``nu``.
    nu_start: float = 10.0

    def __post_init__(self) -> None:
        if self.nu != "auto" and not (
            isinstance(self.nu, int | float) and math.isfinite(self.nu) and self.nu > 0
        ):
            raise ValueError(f"nu must be a positive number or 'auto', got {self.nu!r}")

    def chain(self, problem: CompositeProblem, u: np.ndarray, tau: np.ndarray) -> StudentTChain:
        """A chain's weights state, started at weight 1 (the Gaussian) at ``u``."""
        return StudentTChain(problem, self, u, tau)


def collapsed_weighted(
    problem: CompositeProblem, u: np.ndarray, tau: np.ndarray, lam: np.ndarray
) -> tuple[float, WeightedSums | None]:
    """``log p(u) + sum_e log p(y_e | u, tau, lambda)`` with beta integrated out.

    ``lam`` (2, n) holds the weights of P and Q for the events' samples concatenated.
    Includes ``sum log lambda / 2`` (the likelihood's log-determinant), so the value is
    the exact log-density of ``y`` given the weights (tested against a direct one). The
    compiled loop is the Gaussian one's (:meth:`CompositeProblem.kernel`), with weights.
    """
    u = np.asarray(u, dtype=float)
    torque, extra = None, 0.0
    n_base = 5 + problem.n_steps
    if u.size > n_base and np.all(np.isfinite(u)):
        # Estimated torque shares (fit.composite_torque): u = (.., z).
        from loadbayes.fit.composite.torque import log_prior_z, shares

        torque, extra = shares(u[n_base:]), log_prior_z(u[n_base:])
        u = u[:n_base]
    k = problem.kernel(u, tau, torque, weights=lam)
    if k is None:
        return -math.inf, None
    return k.lp + extra, WeightedSums(problem.group_sums(k), k.pm, k.qm)


def _residuals(problem: CompositeProblem, sums: WeightedSums, betas) -> np.ndarray:
    # (2, n) residuals of P and Q given the motor response and each event's beta.
    d = problem.samples
    x, pm, qm = d.x, sums.pm, sums.qm
    out = np.empty((2, x.size))
    for e, beta in enumerate(betas):
        sl = d.event(e)
        xe, pme, qme = x[sl], pm[sl], qm[sl]
        x2 = xe * xe
        fit_p = beta[0] * x2 + beta[1] * xe + beta[2] + beta[6] * pme / pme[0]
        fit_q = beta[3] * x2 + beta[4] * xe + beta[5] + beta[6] * (qme - qme[0] * x2) / pme[0]
        out[0, sl] = d.p[sl] - fit_p
        out[1, sl] = d.q[sl] - fit_q
    return out


class StudentTChain:
    """One chain's weights, ``nu`` and their records (see the module notes)."""

    def __init__(self, problem: CompositeProblem, spec: StudentT, u: np.ndarray, tau) -> None:
        self.problem = problem
        self.fixed = spec.nu != "auto"
        nu0 = float(spec.nu) if self.fixed else spec.nu_start
        self.nu = np.array([nu0, nu0])
        n = problem.samples.size
        self.lam = np.ones((2, n))
        self.wsum = np.zeros((2, n))
        self.nu_out: list[np.ndarray] = []  # kept nu draws (grows: runs can be extended)
        self.kept = 0
        self.accepted = np.zeros(2)
        self.proposed = 0
        lp, sums = collapsed_weighted(problem, u, tau, self.lam)
        if sums is None:
            raise ValueError("the chain's starting point has no steady state")
        self.sums = sums

    def logp(self, tau: np.ndarray):
        """The collapsed log-density of ``u`` given ``tau`` and the current weights."""
        return lambda x: collapsed_weighted(self.problem, x, tau, self.lam)

    def current(self, u: np.ndarray, tau: np.ndarray) -> float:
        """The collapsed log-density at ``u`` from the stored sums (no ODE solve)."""
        p = self.problem
        if not p.in_support(u):
            return -math.inf
        out = p.prior.log_u(u[:5]) + 0.5 * float(np.sum(np.log(self.lam)))
        n_base = 5 + p.n_steps
        if u.size > n_base:  # estimated torque shares
            from loadbayes.fit.composite.torque import log_prior_z

            out += log_prior_z(u[n_base:])
        for s in self.sums:
            out += float(
                log_marginal_arrays(s.ztz, s.zty, s.yty, s.n, tau, p.m0, p.p0, POSITIVE_BETA)
            )
        return out

    def update(
        self, sums: WeightedSums, betas, tau, rng: np.random.Generator, keep: bool
    ) -> WeightedSums:
        """Draw ``(nu, lambda) | u, beta, tau``; return the sums with the new weights."""
        e2 = _residuals(self.problem, sums, betas) ** 2
        if not self.fixed:
            self.proposed += 1
            for g in range(2):
                self.nu[g], ok = step_nu(float(self.nu[g]), e2[g], float(tau[g]), rng)
                self.accepted[g] += ok
        for g in range(2):
            self.lam[g], mean = draw_weights(e2[g], float(tau[g]), float(self.nu[g]), rng)
            if keep:
                self.wsum[g] += mean
        if keep:
            self.nu_out.append(self.nu.copy())
            self.kept += 1
        d = self.problem.samples
        groups = []
        for e in range(len(self.problem.events)):
            sl = d.event(e)
            zz, zy, yy = weighted_sums(
                d.x[sl], sums.pm[sl], sums.qm[sl], d.p[sl], d.q[sl],
                self.lam[0, sl], self.lam[1, sl],
            )  # fmt: skip
            groups.append(GroupSums(zz, zy, yy, d.n[e]))
        self.sums = WeightedSums(groups, sums.pm, sums.qm)
        return self.sums

    def result(self) -> tuple[np.ndarray, np.ndarray, float | None]:
        """Kept ``nu`` draws (kept, 2), mean weights (2, n), acceptance of the nu step."""
        acc = None if self.fixed else float(self.accepted.mean() / max(self.proposed, 1))
        nus = np.array(self.nu_out).reshape(self.kept, 2)
        return nus, self.wsum / max(self.kept, 1), acc


def robust_outputs(problem: CompositeProblem, res, nu, draws: dict[str, np.ndarray]):
    """Names of a Student-t fit's extra outputs, as the ZIP fit's ``fit_robust`` has them.

    Adds ``nu_p`` and ``nu_q`` to ``draws`` when ``nu`` is sampled (a fixed one is a
    setting). Returns ``(settings, constant, warnings)``: ``constant`` holds each event's
    mean weights ``weight_p``, ``weight_q`` (suffix ``_e{k}`` for event ``k``) and
    ``settings["flagged"]`` the 0-based sample indices flagged per event and channel.
    """
    from loadbayes.inference.robust import FLAG_SIGMAS, NU_BOUNDS, NU_PRIOR, flag_threshold

    nus = np.stack([r.nu for r in res])  # (chain, kept, 2)
    weight = np.mean([r.weight for r in res], axis=0)  # (2, n)
    if nu == "auto":
        draws["nu_p"], draws["nu_q"] = nus[..., 0], nus[..., 1]
    constant: dict[str, np.ndarray] = {}
    flagged: dict[str, list[int]] = {}
    n_flag = 0
    for g, ch in enumerate(("p", "q")):
        thr = flag_threshold(nus[..., g], sigmas=FLAG_SIGMAS)
        for e in range(len(problem.events)):
            sfx = "" if e == 0 else f"_e{e}"
            w = weight[g, problem.samples.event(e)]
            constant[f"weight_{ch}{sfx}"] = w
            flagged[f"{ch}{sfx}"] = np.flatnonzero(w < thr).tolist()
            n_flag += len(flagged[f"{ch}{sfx}"])
    acc = [r.nu_acceptance for r in res]
    settings = {
        "nu": nu,
        "nu_prior": list(NU_PRIOR) if nu == "auto" else None,
        "nu_bounds": list(NU_BOUNDS) if nu == "auto" else None,
        "nu_acceptance": None if nu != "auto" else float(np.mean(acc)),
        "flag_rule": (
            f"mean weight < (nu + 1) / (nu + {FLAG_SIGMAS:g}^2), nu = posterior median "
            f"(or the fixed value): discounted like a {FLAG_SIGMAS:g}-scale residual"
        ),
        "flagged": flagged,
    }
    warn = []
    if n_flag:
        warn.append(
            f"{n_flag} samples of P or Q look like bad data (Student-t weight below the "
            "flag threshold); they are listed under 'flagged'."
        )
    return settings, constant, warn
