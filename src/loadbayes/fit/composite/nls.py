"""The composite fit's start and point-estimate baseline: penalised nonlinear least squares.

:func:`nls` runs ``scipy.optimize.least_squares`` on the same model as the sampler
(variable projection: the linear coefficients solved inside each residual evaluation),
the motor's scale-free coordinates and the steps' fractions as its unknowns; its
Gauss-Newton covariance starts the sampler's proposal and is the baseline's Gaussian
approximation (docs/composite.md, "The NLS baseline").
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np
from scipy import optimize

from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.inference.condlinear import (
    residual_ss,
)
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite_prior import STEP_PRIOR_SD

__all__ = ["COARSE_FS", "NLSResult", "nls", "penalty"]


@dataclass
class NLSResult:
    """The least-squares point estimate and its Gaussian approximation."""

    u: np.ndarray  # (n_free + steps,) the model's free coordinates, then each step's fraction
    betas: np.ndarray  # (events, n_beta)
    sigma: np.ndarray  # (2,) residual sd of P and Q
    cov: np.ndarray  # covariance of (u, betas.ravel())
    cost: float
    seconds: float
    nfev: int
    #: Further least-squares optima some chains start from (a model of parts whose
    #: likelihood has a channel beyond P and Q: the fit with that channel left out).
    others: tuple[np.ndarray, ...] = ()


def _project(problem: CompositeProblem, u: np.ndarray, w: np.ndarray):
    chans = problem.channels(u)
    if chans is None:
        return None
    res, betas = [], []
    for ch in chans:
        z = np.vstack([wg * zg for wg, (zg, _) in zip(w, ch, strict=True)])
        y = np.concatenate([wg * yg for wg, (_, yg) in zip(w, ch, strict=True)])
        # A whisper of the prior keeps the projection defined when a column vanishes.
        ridge = np.sqrt(problem.p0)
        beta = np.linalg.lstsq(np.vstack([z, np.diag(ridge)]), np.append(y, 0 * ridge), None)[0]
        res.append(y - z @ beta)
        betas.append(beta)
    return np.concatenate(res), np.array(betas)


def _rows(problem) -> int:
    # Residual rows where no point has been feasible yet: P and Q of every sample, and
    # the rows of any other channel (the negative sequence) as the model declares them.
    rows = getattr(problem, "channel_rows", None)
    return 2 * sum(e.n for e in problem.events) if rows is None else int(rows().sum())


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
    nf = problem.n_free
    mean_m, _, _, _ = problem.prior.scale_free()
    mean_s = np.full(problem.n_steps, 0.5)
    mean_u, cov_u, white, (lo, hi), sd_u = penalty(problem)
    starts = list(starts) if starts is not None else [mean_m, *problem.start_points()]
    starts = [np.concatenate([np.asarray(x0)[:nf], mean_s]) for x0 in starts]
    nfev = 0

    def run(w, x0, max_nfev=None, prob=problem):
        # The coarse copy may have no steps (d = 5): the prior's whitening is block
        # diagonal (motor, steps), so its leading block serves.
        d = prob.dim
        n_res = [None]
        m, wh, lo_d, hi_d = mean_u[:d], white[:d, :d], lo[:d], hi[:d]

        def fun(u):
            out = _project(prob, u, w)
            if out is None:
                if n_res[0] is None:  # the rows of a feasible point (P and Q: 2 n)
                    n_res[0] = _rows(prob)
                return np.full(n_res[0] + d, 1e3)
            n_res[0] = out[0].size
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
    x_best = np.concatenate([best.x[:nf], mean_s]) if best.x.size < problem.dim else best.x
    if coarse is not problem:
        w = 1.0 / _static_sigmas(problem)
    _, betas = _projected(problem, x_best, w)
    w = 1.0 / _sigmas(problem, x_best, betas)
    sol = run(w, x_best)
    nfev += sol.nfev
    u = sol.x
    others = ()
    if _has_third_channel(problem):
        # The same fit with the channels beyond P and Q (the negative sequence) given no
        # weight: where the record's P and Q alone lead. A model of parts can have one
        # mode that fits that channel and one that leaves it to its noise (restart.py);
        # some chains start here so that both can be reached.
        w_pq = w.copy()
        w_pq[2:] = 0.0
        alt = run(w_pq, x_best)
        nfev += alt.nfev
        if np.max(np.abs(alt.x - u) / sd_u) > DISTINCT_SD:
            others = (alt.x,)
    _, betas = _projected(problem, u, w)
    sig = _sigmas(problem, u, betas)
    cov = _gauss_newton_cov(problem, u, betas, 1.0 / sig, np.linalg.inv(cov_u))
    return NLSResult(u, betas, sig, cov, float(sol.cost), time.perf_counter() - t_start,
                     int(nfev), others)  # fmt: skip


def penalty(problem: CompositeProblem):
    """The prior of ``u`` as the NLS's Tikhonov rows: ``(mean, cov, whitening, bounds, scale)``.

    The steps' fractions join the motor's coordinates, bounded to [0, 1] (their uniform
    prior) and centred mid-interval; a row of sd ``STEP_PRIOR_SD`` (a negligible pull)
    keeps the whitening square. ``bounds`` are six prior sds about the mean (the
    fractions' [0, 1]); ``scale`` is ``least_squares``'s ``x_scale``.
    """
    nf, k = problem.n_free, problem.n_steps
    mean_m, cov_m, _, _ = problem.prior.scale_free()
    mean_u = np.concatenate([mean_m, np.full(k, 0.5)])
    cov_u = np.zeros((problem.dim, problem.dim))
    cov_u[:nf, :nf] = cov_m
    cov_u[nf:, nf:] = np.eye(k) * STEP_PRIOR_SD**2
    sd_u = np.sqrt(np.diag(cov_u))
    white = np.linalg.inv(np.linalg.cholesky(cov_u))
    lo, hi = mean_u - 6 * sd_u, mean_u + 6 * sd_u
    lo[nf:], hi[nf:] = 0.0, 1.0
    sd_u[nf:] = 0.2
    return mean_u, cov_u, white, (lo, hi), sd_u


#: Two least-squares optima are distinct where some coordinate differs by more than this
#: many prior sds (the P-and-Q-only optimum of a model of parts, :func:`nls`).
DISTINCT_SD = 0.5


def _has_third_channel(problem) -> bool:
    # A model of parts that restarts chains in a lower mode, with rows in a third channel.
    model = getattr(problem, "model", None)
    rows = getattr(problem, "channel_rows", None)
    if not getattr(model, "restart_modes", False) or rows is None:
        return False
    return bool(np.sum(rows()[2:]) > 0)


#: Sample rate (per s) above which the NLS's multi-start search runs on thinned events.
COARSE_FS = 120.0


def _projected(problem: CompositeProblem, u: np.ndarray, w: np.ndarray):
    # _project, or one line saying why there is no start (this was a TypeError traceback,
    # "cannot unpack non-iterable NoneType", on data in kV and MW).
    out = _project(problem, u, w)
    if out is None:
        from loadbayes.io.errors import DataError

        names = ", ".join(e.name for e in problem.events if e.name) or "the events"
        raise DataError(
            f"{names}: the least-squares start found no motor whose response can be "
            f"computed for these data: are V, P and Q per unit (--v-base, --s-base) and "
            f"is --f-hz {problem.f_hz:g} the system's frequency?"
        )
    return out


def _thinned(problem: CompositeProblem) -> CompositeProblem:
    # Every k-th sample, k = floor(COARSE_FS^-1 / median dt); the problem itself if k = 1.
    events = []
    for e in problem.events:
        k = max(1, int(1.0 / (COARSE_FS * float(np.median(np.diff(e.t))))))
        events.append(thin_event(e, k))
    if all(a.n == b.n for a, b in zip(events, problem.events, strict=True)):
        return problem
    # Without steps: the search only needs where the motor's coordinates roughly are
    # (a thinned record's intervals are not the record's); the final fit places them.
    return problem.coarse(events)


def thin_event(e: EventRecord, k: int) -> EventRecord:
    """Every ``k``-th sample of ``e``, every per-sample array of it kept (v2, i2 too)."""
    if k == 1:
        return e
    arrays = {f.name: getattr(e, f.name) for f in fields(e)}
    return replace(e, **{n: a[::k] for n, a in arrays.items() if isinstance(a, np.ndarray)})


def _static_sigmas(problem) -> np.ndarray:
    # Residual sds of a static ZIP fit (no motor): an upper bound of the noise of P and
    # Q; any further channel (the negative-sequence current) its rms about zero.
    ssr, n = np.zeros(2), 0
    for ev in problem.events:
        z = np.stack([ev.x**2, ev.x, np.ones(ev.n)], axis=1)
        for g, y in enumerate((ev.p, ev.q)):
            r = y - z @ np.linalg.lstsq(z, y, None)[0]
            ssr[g] += r @ r
        n += ev.n
    out = list(np.sqrt(np.maximum(ssr / n, 1e-30)))
    extra = getattr(problem, "extra_scales", None)
    if extra is not None:
        out += list(extra())
    return np.array(out)


def _sigmas(problem, u, betas) -> np.ndarray:
    sums = problem.sums(u)
    ssr = sum(residual_ss(s, b) for s, b in zip(sums, betas, strict=True))
    n = sum(s.n for s in sums)
    return np.sqrt(np.maximum(ssr / np.maximum(n, 1), 1e-30))


def _gauss_newton_cov(problem, u, betas, w, prec_u) -> np.ndarray:
    def full(uu, bs):
        parts = []
        for ch, b in zip(problem.channels(uu), bs, strict=True):
            parts += [wg * (y - z @ b) for wg, (z, y) in zip(w, ch, strict=True)]
        return np.concatenate(parts)

    n_ev = len(problem.events)
    d = problem.dim
    k = d + problem.n_beta * n_ev
    r0 = full(u, betas)
    jac = np.zeros((r0.size, k))
    for i in range(d):
        h = 1e-5
        up, um = u.copy(), u.copy()
        up[i] += h
        um[i] -= h
        if problem.channels(up) is None or problem.channels(um) is None:
            continue
        jac[:, i] = (full(up, betas) - full(um, betas)) / (2 * h)
    row = 0
    for e, ch in enumerate(problem.channels(u)):
        cols = slice(d + problem.n_beta * e, d + problem.n_beta * (e + 1))
        for wg, (z, _) in zip(w, ch, strict=True):
            jac[row : row + z.shape[0], cols] = -wg * z
            row += z.shape[0]
    # The prior's precision (as in the penalised fit): a direction the data do not see
    # gets the prior's spread, not an infinite variance.
    prec = jac.T @ jac
    prec[:d, :d] += prec_u
    prec[d:, d:] += np.diag(np.tile(problem.p0, n_ev))
    return np.linalg.inv(prec)
