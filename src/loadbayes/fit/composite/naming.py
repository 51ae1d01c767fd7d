"""The composite fit's naming contract: sampled blocks to named draws and back.

docs/composite.md (the shared naming contract) fixes the names: event 0's quantities
carry the plain names (``p0, f_m, a1, ...``), event ``k``'s the suffix ``_e{k}``; the
motor's physical parameters (``rs, xs, ..., t_prime_s``), its log-parameters
(``THETA_NAMES``), the torque shares ``a, b, c``, the noise precisions ``tau_p, tau_q``
and each step's instant ``t_step{j}`` follow. :func:`named_draws` builds them from the
sampler's blocks, :func:`beta_from_named` rebuilds an event's linear coefficients, and
:func:`coefficient_names` / :func:`free_names` say which of them the JSON summarises.
The names' units and meanings in words, and the rows of the printed table, are the
report's (:mod:`loadbayes.report.composite_names`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np

from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.sampler import ChainResult
from loadbayes.fit.composite.torque import shares
from loadbayes.models.composite import THETA_NAMES, composition, motor_physical
from loadbayes.models.motor_kernel import steady_state

__all__ = [
    "ChainDraws",
    "beta_from_named",
    "coefficient_names",
    "event_suffix",
    "free_names",
    "named_draws",
    "step_draws",
    "step_names",
]


@dataclass
class ChainDraws:
    """The chains' sampled blocks stacked (chain, draw, ...), ready to be named."""

    theta: np.ndarray  # (chain, draw, 6) THETA_NAMES
    betas: np.ndarray  # (chain, draw, events, 7)
    tau: np.ndarray  # (chain, draw, 2)
    phi: np.ndarray | None = None  # (chain, draw, steps), None without steps
    z: np.ndarray | None = None  # (chain, draw, 2) torque log-ratios, when estimated

    @classmethod
    def stack(cls, res: Sequence[ChainResult], *, steps: bool, torque: bool) -> ChainDraws:
        """Stack :class:`ChainResult` fields; ``phi`` with ``steps``, ``z`` with ``torque``."""
        return cls(
            np.stack([r.theta for r in res]),
            np.stack([r.beta for r in res]),
            np.stack([r.tau for r in res]),
            np.stack([r.phi for r in res]) if steps else None,
            np.stack([r.u_extra[:, -2:] for r in res]) if torque else None,
        )

    @cached_property
    def abc(self) -> np.ndarray | None:
        """The torque shares ``(A, B, C)`` of every draw of ``z`` (None when fixed)."""
        if self.z is None:
            return None
        return np.apply_along_axis(lambda x: np.array(shares(x)), -1, self.z)

    def named(self, problem: CompositeProblem, cache: dict | None = None) -> dict[str, np.ndarray]:
        """:func:`named_draws`, with the log-ratios ``log_a_over_c``, ``log_b_over_c``."""
        out = named_draws(problem, self.theta, self.betas, self.tau, phi=self.phi, abc=self.abc,
                          cache=cache)  # fmt: skip
        if self.z is not None:
            for i, name in enumerate(("log_a_over_c", "log_b_over_c")):
                out[name] = self.z[..., i]
        return out


def event_suffix(k: int) -> str:
    """The suffix of event ``k``'s names: none for event 0, ``_e{k}`` after."""
    return "" if k == 0 else f"_e{k}"


def _motor_p0_q0(
    problem: CompositeProblem,
    theta: np.ndarray,
    abc: np.ndarray | None = None,
    cache: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    # The motor's own-base P, Q at each event's first sample, per draw (and per-draw
    # torque shares when they are estimated). With ``cache`` (one fit's dict), the draws
    # a previous call saw at the head of every chain are not solved again: the rounds of
    # a run until converged extend the chains, and each round named them all (a bounded
    # fit of 5 rounds solved 174,000 steady states for 71,000 draws, 0.85 s).
    if cache is not None and abc is None and theta.ndim == 3:
        old = cache.get("theta")
        k = 0
        if (old is not None and old.shape[0] == theta.shape[0]
                and old.shape[1] <= theta.shape[1]
                and np.array_equal(old, theta[:, : old.shape[1]])):  # fmt: skip
            k = old.shape[1]
        pm0, qm0 = _motor_p0_q0(problem, theta[:, k:])
        if k:
            pm0 = np.concatenate([cache["pm0"], pm0], axis=1)
            qm0 = np.concatenate([cache["qm0"], qm0], axis=1)
        cache.update(theta=np.array(theta), pm0=pm0, qm0=qm0)
        return pm0, qm0
    # One compiled loop over the draws: the until-converged rule names every draw so far
    # after each round (2 x 38,400 draws, 0.6 s a call in the Python loop this replaced).
    flat = theta.reshape(-1, len(THETA_NAMES))
    e = np.exp(flat)
    wb = 2.0 * math.pi * problem.f_hz
    if abc is None:
        abc_flat = np.empty((flat.shape[0], 3))
        abc_flat[:] = np.asarray(problem.torque, dtype=float)
    else:
        abc_flat = np.ascontiguousarray(abc.reshape(-1, 3), dtype=float)
    v0 = np.array([float(ev.v0) for ev in problem.events])
    n_ev = v0.size
    pm0 = np.full((flat.shape[0], n_ev), np.nan)
    qm0 = np.full((flat.shape[0], n_ev), np.nan)
    _steady_pq_into(e, abc_flat, wb, v0, pm0, qm0)
    shape = theta.shape[:-1] + (n_ev,)
    return pm0.reshape(shape), qm0.reshape(shape)


@numba.njit(cache=True, nogil=True)
def _steady_pq_into(e, abc, wb, v0, pm0, qm0):  # pragma: no cover - compiled
    # The motor's steady P, Q of draw i (exp of its log parameters e[i]) at event k's v0.
    for i in range(e.shape[0]):
        rs, xp, dx, tp, t0 = e[i, 0], e[i, 1], e[i, 2], e[i, 3], e[i, 5]
        for k in range(v0.size):
            out = steady_state(rs, xp, dx, tp, wb, v0[k], t0, abc[i, 0], abc[i, 1], abc[i, 2])
            pm0[i, k], qm0[i, k] = out[3], out[4]


def named_draws(
    problem: CompositeProblem,
    theta: np.ndarray,
    betas: np.ndarray,
    tau: np.ndarray,
    phi: np.ndarray | None = None,
    abc: np.ndarray | None = None,
    cache: dict | None = None,
) -> dict[str, np.ndarray]:
    """Draws named as the contract says, from the sampled blocks.

    Parameters
    ----------
    problem : CompositeProblem
        Events and settings.
    theta : ndarray, shape (chain, draw, 6)
        Log motor parameters.
    betas : ndarray, shape (chain, draw, events, 7)
        Linear coefficients of every event.
    tau : ndarray, shape (chain, draw, 2)
        Noise precisions of P and Q.
    phi : ndarray, shape (chain, draw, steps), optional
        Fractions of the step intervals (``models/composite_steps.py``): reported as
        each step's instant ``t_step{j}`` (s, on the event's clock; ``j`` counts the
        event's steps).
    abc : ndarray, shape (chain, draw, 3), optional
        Draws of the torque shares when estimated (else ``problem.torque``).
    cache : dict, optional
        One fit's store of the motor's steady P, Q per draw: a later call on the same
        chains, extended, solves only the new draws (the same numbers).

    Returns
    -------
    dict of str to ndarray (chain, draw)
    """
    if not isinstance(problem, CompositeProblem):  # another model: its own composition
        return problem.named(theta, betas, tau)
    pm0, qm0 = _motor_p0_q0(problem, theta, abc, cache)
    phys = motor_physical(theta, f_hz=problem.f_hz)
    shape = theta.shape[:-1]
    out: dict[str, np.ndarray] = {}
    for k, ev in enumerate(problem.events):
        sfx = event_suffix(k)
        comp = composition(betas[..., k, :], pm0[..., k], qm0[..., k])
        out[f"p0{sfx}"] = comp["p0"]
        out[f"q0{sfx}"] = comp["q0"]
        out[f"v0{sfx}"] = np.full(shape, ev.v0)
        for name in ("a1", "a2", "a3", "a4", "a5", "a6", "f_m", "mva_m", "q_c"):
            out[f"{name}{sfx}"] = comp[name]
    for name in ("rs", "xs", "xm", "rr", "xr", "h_s"):
        out[name] = phys[name]
    for i, (name, val) in enumerate(zip(("a", "b", "c"), problem.torque, strict=True)):
        out[name] = np.full(shape, float(val)) if abc is None else abc[..., i]
    out["t0"] = phys["t0"]
    for name in ("x_prime", "x_open", "t_prime_s"):
        out[name] = phys[name]
    out["f_hz"] = np.full(shape, float(problem.f_hz))
    out["tau_p"], out["tau_q"] = tau[..., 0], tau[..., 1]
    for i, name in enumerate(THETA_NAMES):
        out[name] = theta[..., i]
    if phi is not None and phi.shape[-1]:
        out.update(step_draws(problem, phi))
    return out


def step_names(problem: CompositeProblem) -> list[str]:
    """Names of the steps' instants: ``t_step{j}`` in event 0, ``t_step{j}_e{k}`` in k."""
    g, names = problem.grid, []
    for i, k in enumerate(g.event_of):
        j = int(np.sum(g.event_of[:i] == k))
        names.append(f"t_step{j}" + event_suffix(k))
    return names


def step_draws(problem: CompositeProblem, phi: np.ndarray) -> dict[str, np.ndarray]:
    """Each step's instant (s) from draws of its fraction of the interval."""
    times = problem.grid.step_time(phi)
    return {n: times[..., i] for i, n in enumerate(step_names(problem))}


def free_names(problem: CompositeProblem) -> list[str]:
    """The parameters the JSON calls free: the model's (the motor's), then the steps' instants."""
    steps = step_names(problem) if problem.n_steps else []
    return [*problem.free_names(), *steps]


def coefficient_names(draws: dict[str, np.ndarray]) -> list[str]:
    """The named draws the JSON summarises: all but the precisions, shares, f and v0."""
    return [
        n
        for n in draws
        if not n.startswith("tau") and n not in ("a", "b", "c", "f_hz") and not n.startswith("v0")
    ]


def beta_from_named(draws: dict[str, np.ndarray], event: int = 0) -> np.ndarray:
    """The linear coefficients (..., 7) of one event, rebuilt from the named draws."""
    sfx = event_suffix(event)
    p0, q0, f_m = draws[f"p0{sfx}"], draws[f"q0{sfx}"], draws[f"f_m{sfx}"]
    pz = p0 * (1 - f_m)
    cols = [pz * draws[f"a{i}{sfx}"] for i in (1, 2, 3)]
    cols += [q0 * draws[f"a{i}{sfx}"] for i in (4, 5, 6)]
    cols.append(f_m * p0)
    return np.stack(cols, axis=-1)
