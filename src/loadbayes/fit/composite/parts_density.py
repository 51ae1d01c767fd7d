"""A model of parts' collapsed log-density in one compiled call per proposal.

:class:`~loadbayes.fit.composite.design.DesignProblem` evaluates a model of parts'
density in Python around its compiled kernels: the support and the prior, ``theta``, the
parts' constants and shares, each event's solve (``parts_kernel.event_parts``) and sums
(``event_sums``), the marginal over the coefficients (``inference/condlinear``). On
``cmld-lite`` and the real record's first fault that Python cost as much as the solve
(about 45 us of 122 per proposal, measured). :func:`log_density` runs the whole chain in
one compiled call, from the same functions (``models/parts_state.py``, the kernels,
``log_marginal_arrays``), so its number is the Python path's to the bit
(``tests/unit/test_parts_density.py``): the block move's proposals, a dozen an
iteration, cost their solve and little more.

It serves white noise (the default); AR(1) noise, whose sums are whitened again at each
draw of ``rho``, keeps the Python path. A proposal's solve is not kept for the steps
after the block move (``models/parts_sums.py``'s store): the shares' steps solve the
accepted state once an iteration.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.inference.condlinear import GroupSums, log_marginal_arrays
from loadbayes.models.parts_kernel import event_parts, event_sums
from loadbayes.models.parts_state import (
    feeder_of,
    parts_constants,
    prior_log_u,
    shares_of,
    theta_of,
)
from loadbayes.models.parts_sums import event_arrays

__all__ = ["PartsDensity", "log_density"]


@numba.njit(cache=True, nogil=True)
def log_density(u, tau, prior, model, flags, events, likelihood):  # pragma: no cover - compiled
    """``(lp, ztz, zty, yty, nn)``: the log-density at ``u`` and each event's sums.

    ``prior``: ``PartsPrior.packed``; ``model``: ``(k, inv_sf, torques, d_base)``
    (``parts_state.model_constants``) and ``flags``: ``(rx, window_s, frcel, motor D,
    electronics)``; ``events``: every event's kept arrays end to end with their offsets
    (:class:`PartsDensity`); ``likelihood``: ``(m0, p0, positive, channels)``. ``lp`` is
    -inf where ``u`` is outside the support or the model has no solution; the sums are
    (events, channels, ...) as ``event_sums`` fills them.
    """
    t, v, delta, p, q, gap, steps, v2, i2, rows, offs, step_offs, event_flags = events
    m0, p0, positive, n_ch = likelihood
    rx, window_s, frcel, d_on, el_on = flags
    k_const, inv_sf, torques, d_base = model
    n_ev = offs.size - 1
    ztz = np.zeros((n_ev, n_ch, 4, 4))
    zty = np.zeros((n_ev, n_ch, 4))
    yty = np.zeros((n_ev, n_ch))
    nn = np.zeros((n_ev, n_ch))
    for i in range(u.size):
        if not math.isfinite(u[i]):
            return -math.inf, ztz, zty, yty, nn
    lp = prior_log_u(u, prior[0], prior[1], prior[2], prior[3], prior[4], prior[5])
    if not math.isfinite(lp):
        return -math.inf, ztz, zty, yty, nn
    theta = theta_of(u, prior[2])
    x_load, motors, d_params, vd1, vd2 = parts_constants(theta, k_const, inv_sf, torques, d_base)
    f, a_p = shares_of(theta, int(k_const[13]), int(k_const[14]))
    n_m = motors.shape[0]
    no_ar = (np.zeros((2, 4, 4, 4)), np.zeros((2, 4, 4)), np.zeros((2, 4)))
    for e in range(n_ev):
        a, b = offs[e], offs[e + 1]
        x = feeder_of(x_load, p[a], q[a])
        r = rx * x
        solved = event_parts(t[a:b], v[a:b], delta[a:b], event_flags[e, 0], p[a:b], q[a:b],
                             gap[a:b], steps[step_offs[e] : step_offs[e + 1]], v2[a:b], i2[a:b],
                             r, x, motors, window_s, d_on, d_params, el_on, vd1, vd2,
                             frcel)  # fmt: skip
        if not solved[0]:
            return -math.inf, ztz, zty, yty, nn
        parts = (solved[1], solved[2], solved[3], solved[4], solved[5], solved[6], solved[7])
        ok = event_sums(parts, gap[a:b], v2[a:b], i2[a:b], rows[a:b], r, x, n_m, d_on, f, a_p,
                        event_flags[e, 1], ztz[e], zty[e], yty[e], nn[e], False, no_ar[0],
                        no_ar[1], no_ar[2])  # fmt: skip
        if not ok:
            return -math.inf, ztz, zty, yty, nn
        try:
            lp += log_marginal_arrays(ztz[e], zty[e], yty[e], nn[e], tau, m0, p0, positive)
        except Exception:  # A not positive definite: log_marginal's -inf
            return -math.inf, ztz, zty, yty, nn
    if not math.isfinite(lp):
        return -math.inf, ztz, zty, yty, nn
    return lp, ztz, zty, yty, nn


class PartsDensity:
    """:func:`log_density` for one problem: its prior, model and events packed once.

    Called as ``density(u, tau)``: ``(lp, sums)`` as ``DesignProblem.collapsed`` returns
    them (``(-inf, None)`` where infeasible), the sums a list of
    :class:`~loadbayes.inference.condlinear.GroupSums`, one per event.
    """

    def __init__(self, model, prior, events, m0, p0, positive) -> None:
        fixed = [event_arrays(model, ev) for ev in events]
        offs = np.cumsum([0] + [f[0].size for f in fixed]).astype(np.int64)
        step_offs = np.cumsum([0] + [f[7].size for f in fixed]).astype(np.int64)
        n_ch = len(model.channel_names)
        flags = np.array([[f[3], n_ch == 3 and bool(f[10].any())] for f in fixed], dtype=bool)

        def joined(i, dtype):
            return np.ascontiguousarray(np.concatenate([f[i] for f in fixed]), dtype=dtype)

        self.events = (joined(0, float), joined(1, float), joined(2, float), joined(4, float),
                       joined(5, float), joined(6, bool), joined(7, float), joined(8, complex),
                       joined(9, complex), joined(10, bool), offs, step_offs,
                       flags.reshape(-1, 2))  # fmt: skip
        self.prior = prior.packed
        self.model = model.constants
        self.flags = (float(model.rx), float(model.window_s), float(model.frcel),
                      bool(model.motor_d), bool(model.electronics))  # fmt: skip
        self.likelihood = (np.asarray(m0, dtype=float), np.asarray(p0, dtype=float),
                           -1 if positive is None else int(positive), n_ch)  # fmt: skip

    def __call__(self, u, tau) -> tuple[float, list[GroupSums] | None]:
        """``(lp, sums)`` at ``u`` for noise precisions ``tau`` (the class docstring)."""
        lp, ztz, zty, yty, nn = log_density(np.asarray(u, dtype=float),
                                            np.asarray(tau, dtype=float), self.prior,
                                            self.model, self.flags, self.events,
                                            self.likelihood)  # fmt: skip
        if not math.isfinite(lp):
            return -math.inf, None
        return lp, [GroupSums(ztz[e], zty[e], yty[e], nn[e]) for e in range(ztz.shape[0])]

    @staticmethod
    def serves(problem) -> bool:
        """Whether ``problem`` (a ``DesignProblem``) is a model of parts this density is."""
        model, prior = problem.model, problem.prior
        return (hasattr(model, "constants") and hasattr(prior, "packed")
                and problem.n_free == problem.n_theta
                and np.array_equal(problem._to_theta, np.eye(problem.n_free)))  # fmt: skip
