"""Any dynamic load model's collapsed log-density, from its design matrices alone.

:class:`DesignProblem` is what the sampler and the NLS start need of a
:class:`~loadbayes.models.base.DynamicLoadModel` that brings no compiled kernel of its
own: for free coordinates ``u`` it asks the model for each event's response and design
``Z_p(u), Z_q(u)``, sums them (``Z'Z``, ``Z'y``, ``y'y`` per channel) with NumPy and
integrates the linear coefficients out exactly (``inference/condlinear.py``), as
:class:`~loadbayes.fit.composite.problem.CompositeProblem` does for ``zip+motor`` in one
compiled call. It reads the events as point samples with no steps between them and takes
the Gaussian likelihood, white or AR(1) on P and Q; the options beyond those (steps,
Student-t, bounded shares, an estimated torque) are the ``zip+motor`` problem's. A model
of parts with white noise has :meth:`DesignProblem.collapsed` in one compiled call
(``parts_density.py``), the same number as the steps below, to the bit.

**AR(1) noise** (a model whose ``noise`` is ``"ar1"``): P's and Q's rows are whitened
for their coefficients ``rho`` (Prais-Winsten: ``z_k - rho z_k-1``, each segment's first
row scaled by ``sqrt(1 - rho^2)``, segments broken where rows were left out). The sums of
the whitened design are a closed form in ``rho`` (``inference/ar1.ar_moments``,
``whitened``), so the sampler's draw of ``rho`` re-whitens them without solving the model
again (:meth:`DesignProblem.resum`). The negative-sequence current stays white: its rows
are the few where the fault is unbalanced, two parts of one phasor interleaved, too short
a run to place a coefficient of its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from loadbayes.core.kept import Kept
from loadbayes.fit.composite.naming import event_suffix
from loadbayes.fit.composite.parts_density import PartsDensity
from loadbayes.inference.ar1 import RHO_MAX, ar_moments, residual_stats, whitened
from loadbayes.inference.condlinear import (
    GroupSums,
    draw_beta,
    draw_betas,
    log_marginal,
)
from loadbayes.measurements.record import EventRecord

__all__ = ["ARSums", "DesignProblem"]


@dataclass
class DesignProblem:
    """Events, prior and model: the collapsed log-density of the free coordinates.

    ``u`` holds the model's ``free_coordinates``; the full ``theta`` is
    ``inv(scale_free) @ (u, 0)`` (a model whose data see every coordinate has
    ``scale_free`` the identity and no scale left to the prior).
    """

    model: Any
    events: list[EventRecord]
    prior: Any
    evaluations: int = field(default=0, init=False)
    #: No steps between samples and no share coordinates: the sampled vector is ``u``.
    n_steps: int = field(default=0, init=False)
    n_share_coords: int = field(default=0, init=False)
    bounded: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        self.events = list(self.events)
        self.recorded = self.events
        self.free_coordinates = tuple(self.model.free_coordinates)
        self.n_free = len(self.free_coordinates)  # the sampler reads these sizes
        self.n_theta = len(self.model.theta_names)
        self.n_beta = len(self.model.beta_names)
        self.m0 = np.zeros(self.n_beta)
        self.p0 = 1.0 / np.asarray(self.prior.beta_sd, dtype=float) ** 2
        self.positive = getattr(self.prior, "positive", None)
        self.f_hz = float(getattr(self.model, "f_hz", 60.0))
        inv = np.linalg.inv(np.asarray(self.model.scale_free, dtype=float))
        self._to_theta = np.ascontiguousarray(inv[:, : self.n_free].T)
        #: Channels of the likelihood, each with its noise precision: P, Q and any the
        #: model adds (the negative-sequence current: ``tau_i2``).
        self.channel_names = tuple(getattr(self.model, "channel_names", ("p", "q")))
        #: AR(1) noise: the bound of the coefficients' uniform prior (the model's, if any).
        self.rho_max = float(getattr(self.model, "rho_max", RHO_MAX))
        self.n_channels = len(self.channel_names)
        self._thetas = Kept(64)  # theta of the last vectors (theta)
        # A model of parts' density in one compiled call (white noise: collapsed).
        self._density = (PartsDensity(self.model, self.prior, self.events, self.m0, self.p0,
                                      self.positive)
                         if PartsDensity.serves(self) else None)  # fmt: skip

    @property
    def dim(self) -> int:
        """Length of the sampled vector: the model's free coordinates."""
        return self.n_free

    def draw_scale(self, u: np.ndarray, rng: np.random.Generator) -> None:
        """No scale left to the prior: nothing drawn."""
        return None

    def draw_scales(self, u: np.ndarray, rng: np.random.Generator) -> None:
        """No scale left to the prior: nothing drawn."""
        return None

    def theta(self, u: np.ndarray, scale: Any = None) -> np.ndarray:
        """``theta`` of free coordinates ``u`` (..., n_free); a scale, if any, at 0.

        A prior with its own map of the sampled coordinates (``to_theta``: a model of
        parts' motors' ``log T0``, ``models/part_scale.py``) applies it after.
        """
        u = np.asarray(u, dtype=float)
        key = u.tobytes() if u.ndim == 1 else None  # the sampler's one vector: kept
        got = None if key is None else self._thetas.get(key)
        if got is not None:
            return got.copy()
        theta = u[..., : self.n_free] @ self._to_theta
        to_theta = getattr(self.prior, "to_theta", None)
        theta = theta if to_theta is None else to_theta(theta)
        if key is not None:
            self._thetas.keep(key, theta.copy())
        return theta

    def phi(self, u: np.ndarray) -> np.ndarray:
        """No steps: an empty vector of step fractions."""
        return np.zeros(np.shape(u)[:-1] + (0,))

    def in_support(self, u: np.ndarray) -> bool:
        """Finite, and inside the prior's hard limits where it has any."""
        inside = getattr(self.prior, "inside", None)
        return bool(np.isfinite(u).all()) and (inside is None or inside(u[: self.n_free]))

    def start_points(self) -> list[np.ndarray]:
        """Starts of the NLS search besides the prior's centre (the model's, if any)."""
        return [np.asarray(x, dtype=float) for x in getattr(self.model, "starts", ())]

    def coarse(self, events: list[EventRecord]) -> DesignProblem:
        """The same problem on other events (the NLS search's thinned copy)."""
        return DesignProblem(self.model, events, self.prior)

    def channels(self, u: np.ndarray) -> list[list[tuple[np.ndarray, np.ndarray]]] | None:
        """Each event's channels at ``u``: ``[(Z_g, y_g), ...]`` (None where infeasible).

        A model with ``channels(event, theta)`` gives its own (targets that move with
        ``theta``, as a feeder's losses do, or a third channel, the negative sequence);
        any other gives ``design(event, *response)`` on the recorded P and Q.
        """
        self.evaluations += 1
        if not self.in_support(u):
            return None
        theta = self.theta(u)
        own = getattr(self.model, "channels", None)
        out = []
        for ev in self.events:
            if own is not None:
                ch = own(ev, theta)
                if ch is None:
                    return None
            else:
                resp = self.model.response(ev, theta)
                if resp is None:
                    return None
                zp, zq = self.model.design(ev, *resp)
                ch = [(zp, ev.p), (zq, ev.q)]
            if not all(np.isfinite(z).all() for z, _ in ch):
                return None
            out.append(ch)
        return out

    def designs(self, u: np.ndarray) -> list[tuple[np.ndarray, ...]] | None:
        """Each event's design matrices at ``u`` (one per channel), or None."""
        ch = self.channels(u)
        return None if ch is None else [tuple(z for z, _ in c) for c in ch]

    def _extra_targets(self) -> list[np.ndarray]:
        # The targets of the channels past P and Q (they do not move with theta: the
        # recorded negative-sequence current), pooled over the events, at the prior mean.
        ch = self.channels(self.prior.scale_free()[0][: self.n_free])
        if ch is None:
            return [np.zeros(0)] * (self.n_channels - 2)
        return [np.concatenate([c[g][1] for c in ch]) for g in range(2, self.n_channels)]

    def channel_rows(self) -> np.ndarray:
        """The observations of each channel, over the events (the noise precisions' n)."""
        kept = getattr(self.model, "kept", None)
        n = float(sum(e.n if kept is None else kept(e).size for e in self.events))
        return np.array([n, n, *(float(y.size) for y in self._extra_targets())])

    def extra_scales(self) -> list[float]:
        """A first noise sd of each channel past P and Q: its rms (1 where empty)."""
        return [float(np.sqrt(np.mean(y**2))) if y.size else 1.0 for y in self._extra_targets()]

    def sums(self, u: np.ndarray, torque: Any = None) -> list[GroupSums] | None:
        """Each event's sufficient sums of the linear block (None if infeasible)."""
        compiled = getattr(self.model, "event_sums", None)
        if compiled is not None:  # the model's own compiled sums (models/parts_kernel.py)
            self.evaluations += 1
            if not self.in_support(u):
                return None
            theta = self.theta(u)
            out = []
            for ev in self.events:
                got = compiled(ev, theta)
                if got is None:
                    return None
                out.append(GroupSums(*got))
            return out
        ch = self.channels(u)
        if ch is None:
            return None
        return [GroupSums.from_arrays([z for z, _ in c], [y for _, y in c]) for c in ch]

    def log_collapsed(self, sums, u, tau) -> float:
        """``log p(u) + sum_e log p(y_e | u, tau)`` with beta integrated out."""
        if sums is None or not np.isfinite(u).all():
            return -math.inf
        out = self.prior.log_u(np.asarray(u, dtype=float)[: self.n_free])
        for s in sums:
            out += log_marginal(s, tau, self.m0, self.p0, positive=self.positive)
        return float(out)

    def collapsed(self, u, tau, torque=None, rho=None) -> tuple[float, list[GroupSums] | None]:
        """The log-density at ``u`` and the events' sums (``(-inf, None)`` if infeasible).

        ``rho`` (2,): AR(1) noise on P and Q, the sums whitened for it (:class:`ARSums`,
        which :meth:`resum` whitens again for another ``rho``; the log-determinant,
        which does not depend on ``u``, is left out, as the ``zip+motor`` problem does).
        """
        if rho is None and self._density is not None:
            self.evaluations += 1
            return self._density(u, tau)
        if rho is None:
            sums = self.sums(u)
        else:
            sums = self.ar_sums(u)
            sums = None if sums is None else self.resum(sums, rho)
        if sums is None:
            return -math.inf, None
        lp = self.log_collapsed(sums, u, tau)
        return (lp, sums) if math.isfinite(lp) else (-math.inf, None)

    def ar_sums(self, u: np.ndarray) -> ARSums | None:
        """Each event's white sums and P's, Q's AR(1) sums at ``u`` (not yet whitened).

        The model's compiled kernel where it has one (``event_sums(..., ar=True)``), else
        :func:`~loadbayes.inference.ar1.ar_moments` of its channels' arrays, segments
        where the model's ``first_rows`` says (one per event for a model with none).
        """
        compiled = getattr(self.model, "event_sums", None)
        white, moments = [], []
        if compiled is not None:
            self.evaluations += 1
            if not self.in_support(u):
                return None
            theta = self.theta(u)
            for ev in self.events:
                got = compiled(ev, theta, ar=True)
                if got is None:
                    return None
                white.append(GroupSums(*got[0]))
                moments.append(got[1])
            return ARSums(white, white, moments)
        ch = self.channels(u)
        if ch is None:
            return None
        first_rows = getattr(self.model, "first_rows", None)
        for ev, c in zip(self.events, ch, strict=True):
            white.append(GroupSums.from_arrays([z for z, _ in c], [y for _, y in c]))
            n = c[0][1].size
            first = np.zeros(n, dtype=bool) if first_rows is None else first_rows(ev)
            got = [ar_moments(z, y, first) for z, y in c[:2]]
            moments.append((*(np.stack(m) for m in zip(*got, strict=True)),
                            float(max(np.count_nonzero(first[1:]) + 1, 1))))  # fmt: skip
        return ARSums(white, white, moments)

    def resum(self, sums: ARSums, rho: np.ndarray) -> ARSums:
        """The events' sums whitened for AR(1) coefficients ``rho`` (no model solve)."""
        groups = []
        for w, (mzz, mzy, myy, _) in zip(sums.white, sums.moments, strict=True):
            ztz, zty, yty = w.ztz.copy(), w.zty.copy(), w.yty.copy()
            for g in range(2):  # P, Q; a third channel (I2) stays white
                r = float(rho[g])
                ztz[g], zty[g], yty[g] = (whitened(m[g], r) for m in (mzz, mzy, myy))
            groups.append(GroupSums(ztz, zty, yty, w.n))
        return ARSums(groups, sums.white, sums.moments)

    def ar_whitened(self, white: list[GroupSums], moments: list[tuple], rho) -> ARSums:
        """Sums given as :attr:`ARSums.white` and :attr:`ARSums.moments`, whitened for ``rho``."""
        return self.resum(ARSums(white, white, moments), rho)

    def ar_statistics(self, sums: ARSums, betas) -> np.ndarray:
        """P's and Q's residual sums for the AR(1) step (``inference/ar1.draw_rho``'s)."""
        out = np.zeros((2, 4))
        for (mzz, mzy, myy, segments), beta in zip(sums.moments, betas, strict=True):
            for g in range(2):
                out[g] += residual_stats(mzz[g], mzy[g], myy[g], beta, segments)
        return out

    def conditional_moves(self):
        """The model's own steps after the block move, run in turn, or None.

        Its thresholds' (``thresholds.py``), then its shares' (``shares.py``, where the
        model has a basis of its shares and ``share_steps`` is not 0).
        """
        from loadbayes.fit.composite.shares import ShareMoves
        from loadbayes.fit.composite.thresholds import ThresholdMoves

        moves = []
        if getattr(self.model, "thresholds", ()):
            moves.append(ThresholdMoves(self))
        # The shares' basis is the model's (its theta); u must be that theta.
        same = self.n_free == self.n_theta and np.array_equal(self._to_theta, np.eye(self.n_free))
        if getattr(self.model, "share_steps", 0) and hasattr(self.model, "event_basis") and same:
            moves.append(ShareMoves(self))
        if not moves:
            return None
        return moves[0] if len(moves) == 1 else _InTurn(moves)

    def draw_coefficients(self, sums, tau, u, rng: np.random.Generator) -> list[np.ndarray]:
        """Every event's ``beta | u, tau`` (exact)."""
        return [draw_beta(s, tau, self.m0, self.p0, rng, positive=self.positive) for s in sums]

    def draw_coefficient_sets(self, sums, tau, u, rng, size: int) -> list[np.ndarray]:
        """``size`` draws of every event's ``beta | u, tau``, each (size, n_beta)."""
        return [
            draw_betas(s, tau, self.m0, self.p0, rng, size, positive=self.positive) for s in sums
        ]

    def free_names(self) -> list[str]:
        """The parameters the JSON calls free: the model's nonlinear ones."""
        return list(self.model.theta_names)

    def named(self, theta: np.ndarray, betas: np.ndarray, tau: np.ndarray) -> dict:
        """Draws named as the contract says.

        Each event's composition (suffix ``_e{k}``) and ``v0``, the model's ``theta`` and
        physical parameters, the noise precisions ``tau_p, tau_q``.
        """
        out: dict[str, np.ndarray] = {}
        shape = theta.shape[:-1]
        for k, ev in enumerate(self.events):
            sfx = event_suffix(k)
            for name, value in self.model.composition(betas[..., k, :]).items():
                out[f"{name}{sfx}"] = np.broadcast_to(value, shape).copy()
            out[f"v0{sfx}"] = np.full(shape, ev.v0)
        physical = getattr(self.model, "physical", None)
        named = physical(theta) if physical is not None else {}
        for i, name in enumerate(self.model.theta_names):
            out[name] = theta[..., i]
        out.update({n: np.asarray(v) for n, v in named.items()})
        ratings = getattr(self.model, "ratings", None)
        if ratings is not None:  # each motor's rating, per event (it needs the event's p0)
            flat = theta.reshape(-1, theta.shape[-1])
            for k, ev in enumerate(self.events):
                p0 = betas[..., k, 0].reshape(-1)
                for name, value in ratings(ev, flat, p0).items():
                    out[f"{name}{event_suffix(k)}"] = value.reshape(shape)
        rows = self.channel_rows()
        for g, name in enumerate(self.channel_names):
            if rows[g] > 0:  # a channel no event has data for has no noise to report
                out[f"tau_{name}"] = tau[..., g]
        return out


class _InTurn:
    """Several of a model's own steps run one after the other (each keeps the posterior)."""

    def __init__(self, moves) -> None:
        self.moves = moves

    def __getattr__(self, name):  # the first move's attributes (the thresholds' tests)
        if name.startswith("__") or "moves" not in self.__dict__:  # unpickled: not yet set
            raise AttributeError(name)
        return getattr(self.moves[0], name)

    def __call__(self, u, lp, sums, logp, rng, **state):
        for move in self.moves:
            u, lp, sums = move(u, lp, sums, logp, rng, **state)
        return u, lp, sums


@dataclass
class ARSums:
    """The events' whitened :class:`GroupSums`, with the sums they were whitened from.

    Iterates as the plain list does; ``white`` are the unwhitened sums (the third
    channel's are used as they are), ``moments`` each event's ``(mzz, mzy, myy,
    segments)``: P's and Q's ``inference/ar1.ar_moments`` stacks and its segment count.
    """

    groups: list[GroupSums]
    white: list[GroupSums]
    moments: list[tuple]

    def __iter__(self):
        return iter(self.groups)

    def __len__(self) -> int:
        return len(self.groups)

    def __getitem__(self, event: int) -> GroupSums:
        return self.groups[event]
