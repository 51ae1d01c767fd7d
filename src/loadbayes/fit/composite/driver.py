"""Fit the composite load (ZIP + motor) to recorded events: NLS start, sampler, Posterior.

:func:`fit_composite` runs the penalised NLS (the start and the point-estimate baseline,
returned as a :class:`~loadbayes.posterior.Posterior` of its Gaussian approximation),
then the Metropolis-within-Gibbs sampler of :mod:`loadbayes.fit.composite.problem`, and
names the draws as docs/composite.md (the shared naming contract) says. It also writes
the plain-words identifiability section: which motor parameters the events determine,
which stay close to their prior, which lie on a ridge, and what would help.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.fit.composite.checks import sampling_warnings
from loadbayes.fit.composite.nls import NLSResult, nls
from loadbayes.fit.composite.problem import CompositePrior, CompositeProblem, theta_of
from loadbayes.fit.composite.sampler import DEFAULT_MOVE, sample
from loadbayes.models.composite import (
    SCALE_FREE_MATRIX,
    SCALE_FREE_NAMES,
    THETA_NAMES,
    Event,
    composition,
    motor_physical,
)
from loadbayes.models.motor_kernel import H_MAX_S, steady_state
from loadbayes.posterior import Posterior, gaussian_draws

__all__ = [
    "CompositeFit",
    "beta_from_named",
    "fit_composite",
    "identifiability",
    "named_draws",
    "predictive_band",
]

#: Plain names of the sampled (scale-free) coordinates, for the identifiability section.
#: The rating is unknown, so impedances are read on the base of the motor's own initial
#: load torque (T0 = 1): that is what an event can determine.
_PLAIN = {
    "log_rs_t0": "stator resistance Rs",
    "log_x_prime_t0": "transient reactance X'",
    "log_dx_t0": "X - X' (open-circuit minus transient reactance)",
    "log_t_prime": "transient time constant T'",
    "log_h_over_t0": "inertia H",
}
_METHOD = {"am": "mwg-adaptive-metropolis", "slice": "mwg-factor-slice"}
_MOVE_NAME = {"am": "adaptive Metropolis", "slice": "factor slice sampling"}
#: Posterior sd / prior sd (on the log scale) above which a parameter is "prior-driven",
#: and below which it is "determined by the data".
PRIOR_DRIVEN, DETERMINED = 0.7, 0.3
#: |posterior correlation| above which two sampled parameters are said to form a ridge.
RIDGE_CORR = 0.9


@dataclass
class CompositeFit:
    """What :func:`fit_composite` returns."""

    posterior: Posterior
    baseline: Posterior
    problem: CompositeProblem
    start: NLSResult
    seconds: dict[str, float]


def _motor_p0_q0(
    problem: CompositeProblem, theta: np.ndarray, abc: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    # The motor's own-base P, Q at each event's first sample, per draw (and per-draw
    # torque shares when they are estimated).
    flat = theta.reshape(-1, 6)
    e = np.exp(flat)
    wb = 2.0 * math.pi * problem.f_hz
    abc_flat = None if abc is None else abc.reshape(-1, 3)
    n_ev = len(problem.events)
    pm0 = np.full((flat.shape[0], n_ev), np.nan)
    qm0 = np.full((flat.shape[0], n_ev), np.nan)
    for i, (rs, xp, dx, tp, _h, t0) in enumerate(e):
        a, b, c = problem.torque if abc_flat is None else abc_flat[i]
        for k, ev in enumerate(problem.events):
            out = steady_state(rs, xp, dx, tp, wb, ev.v0, t0, a, b, c)
            pm0[i, k], qm0[i, k] = out[3], out[4]
    shape = theta.shape[:-1] + (n_ev,)
    return pm0.reshape(shape), qm0.reshape(shape)


def named_draws(
    problem: CompositeProblem,
    theta: np.ndarray,
    betas: np.ndarray,
    tau: np.ndarray,
    phi: np.ndarray | None = None,
    abc: np.ndarray | None = None,
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

    Returns
    -------
    dict of str to ndarray (chain, draw)
    """
    pm0, qm0 = _motor_p0_q0(problem, theta, abc)
    phys = motor_physical(theta, f_hz=problem.f_hz)
    shape = theta.shape[:-1]
    out: dict[str, np.ndarray] = {}
    for k, ev in enumerate(problem.events):
        sfx = "" if k == 0 else f"_e{k}"
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
        names.append(f"t_step{j}" + ("" if k == 0 else f"_e{k}"))
    return names


def step_draws(problem: CompositeProblem, phi: np.ndarray) -> dict[str, np.ndarray]:
    """Each step's instant (s) from draws of its fraction of the interval."""
    times = problem.grid.step_time(phi)
    return {n: times[..., i] for i, n in enumerate(step_names(problem))}


def identifiability(
    theta: np.ndarray, f_m: np.ndarray, prior: CompositePrior, n_events: int
) -> dict[str, Any]:
    """Plain-words identifiability of the motor from posterior draws against the prior.

    Judged on the scale-free coordinates (``SCALE_FREE_NAMES``: Rs, X', X - X', H on the
    base of the motor's load torque, and T'), the only ones the data can inform; the
    loading ``T0`` itself (equivalently the rating) is always the prior's.

    Parameters
    ----------
    theta : ndarray, shape (..., 6)
        Draws of the log motor parameters (``THETA_NAMES``).
    f_m : ndarray
        Draws of the motor share (event 0).
    prior : CompositePrior
        The prior the draws came from.
    n_events : int
        Number of events fitted.

    Returns
    -------
    dict
        ``parameters`` (per coordinate: the sd ratio and a verdict), ``ridges``,
        ``motor_share`` and ``summary`` / ``what_would_help`` sentences.
    """
    flat = theta.reshape(-1, 6) @ SCALE_FREE_MATRIX.T
    u = flat[:, :5]
    _, cov_u, _, _ = prior.scale_free()
    ratio = u.std(axis=0) / np.sqrt(np.diag(cov_u))
    params = {}
    for name, r in zip(SCALE_FREE_NAMES, ratio, strict=True):
        verdict = (
            "prior-driven"
            if r > PRIOR_DRIVEN
            else ("determined by the data" if r < DETERMINED else "partly determined")
        )
        params[name] = {"posterior_sd_over_prior_sd": float(r), "verdict": verdict}
    corr = np.corrcoef(u.T)
    ridges = []
    for i in range(5):
        for j in range(i + 1, 5):
            if abs(corr[i, j]) > RIDGE_CORR:
                a, b = SCALE_FREE_NAMES[i], SCALE_FREE_NAMES[j]
                ridges.append(
                    {
                        "pair": [a, b],
                        "correlation": float(corr[i, j]),
                        "words": f"{_PLAIN[a]} and {_PLAIN[b]} trade off (posterior "
                        f"correlation {corr[i, j]:+.2f}): the events fix a combination of "
                        "them, not each one.",
                    }
                )
    fm = f_m.reshape(-1)
    fm_sd = float(np.std(fm))
    fm_ok = fm_sd < 0.1
    weak = [_PLAIN[n] for n, p in params.items() if p["verdict"] == "prior-driven"]
    partly = [_PLAIN[n] for n, p in params.items() if p["verdict"] == "partly determined"]
    good = [_PLAIN[n] for n, p in params.items() if p["verdict"] == "determined by the data"]
    words = [
        f"The motor's share of the initial load is {'well' if fm_ok else 'poorly'} "
        f"determined (f_m = {np.mean(fm):.3f} +- {fm_sd:.3f})."
    ]
    if good:
        words.append("Determined by the data: " + ", ".join(good) + ".")
    if partly:
        words.append("Partly determined (the prior still matters): " + ", ".join(partly) + ".")
    if weak:
        words.append(
            "The data say little about "
            + ", ".join(weak)
            + ": their posterior stays close to the prior, so their values are the prior's."
        )
    words.append(
        "The motor's rating (mva_m) and its loading T0 are never determined by terminal "
        "data, only their product: the per-unit impedances and H are reported on a base "
        "whose size comes from the prior of T0 (give it from nameplate data if known)."
    )
    help_ = []
    if weak or partly or not fm_ok or ridges:
        help_ = [
            "a deeper voltage event (a sag of 20-50% moves the motor's speed and flux "
            "far more than a shallow one)",
            f"more events of the same load fitted jointly (this fit used {n_events})",
            "a prior from nameplate data (rating, H, locked-rotor current) on the "
            "parameters marked prior-driven",
        ]
    return {
        "parameters": params,
        "ridges": ridges,
        "motor_share": {"sd": fm_sd, "well_determined": bool(fm_ok)},
        "summary": " ".join(words),
        "what_would_help": help_,
        "thresholds": {
            "prior_driven_above": PRIOR_DRIVEN,
            "determined_below": DETERMINED,
            "ridge_correlation": RIDGE_CORR,
        },
    }


def _baseline(problem: CompositeProblem, start: NLSResult, chains: int, draws: int, seed: int):
    n_ev = len(problem.events)
    rng = np.random.default_rng(seed)
    mean = np.concatenate([start.u, start.betas.ravel()])
    x = gaussian_draws(mean, start.cov, chains, draws, rng)
    d = problem.dim
    u = x[..., :5]
    log_t0 = np.array([problem.prior.draw_log_t0(ui, rng) for ui in u.reshape(-1, 5)])
    theta = theta_of(u, log_t0.reshape(chains, draws))
    betas = x[..., d:].reshape(chains, draws, n_ev, 7)
    tau = np.broadcast_to(1.0 / start.sigma**2, (chains, draws, 2)).copy()
    return named_draws(problem, theta, betas, tau, phi=problem.phi(x[..., :d]))


def fit_composite(
    events: Sequence[Event],
    *,
    prior: CompositePrior | None = None,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] | str = (1.0, 0.0, 0.0),
    draws: int = 16_000,
    burn: int = 4000,
    thin: int = 1,
    chains: int = 4,
    seed: int = 0,
    workers: int | None = None,
    h_max: float = H_MAX_S,
    steps: bool = True,
    settings: dict[str, Any] | None = None,
    move: str = DEFAULT_MOVE,
    likelihood: str = "normal",
    nu: float | str = "auto",
) -> CompositeFit:
    """Fit the composite load to one or more events of the same load.

    Parameters
    ----------
    events : sequence of Event
        Recordings (each its own operating point; the motor is shared).
    prior : CompositePrior, optional
        Default :meth:`CompositePrior.default`.
    f_hz : float
        Nominal frequency (the motor's time base).
    torque : tuple of float or "estimate"
        ``(A, B, C)``, fixed, or ``"estimate"``: a Dirichlet(1, 1, 1) prior
        (fit.composite_torque).
    draws, burn, thin, chains, seed, workers
        Sampler settings (see :func:`loadbayes.fit.composite.sampler.sample`).
    h_max : float
        RK4 sub-step of the motor kernel (s).
    steps : bool
        Model each voltage step between two samples as a step at an unknown instant
        inside its interval (``models/composite_steps.py``); False reads it as a ramp
        across the interval (the plain linear interpolation).
    settings : dict, optional
        Extra provenance stored in the result.
    move : str
        The sampler's u-move (:data:`~loadbayes.fit.composite.sampler.MOVES`).
    likelihood : {"normal", "student-t"}
        Noise on P and Q; Student-t adds latent weights (fit.composite_robust).
    nu : float or "auto"
        Student-t degrees of freedom, fixed or sampled (one per channel).

    Returns
    -------
    CompositeFit
        The posterior, the NLS baseline (Gaussian draws), the problem and timings.
    """
    events = list(events)
    if not events:
        raise ValueError("no events to fit")
    prior = prior or CompositePrior.default(events)
    estimate = isinstance(torque, str)
    if estimate and torque != "estimate":
        raise ValueError(f"torque must be (A, B, C) or 'estimate', got {torque!r}")
    # Estimated shares: NLS (the start) at the prior's centre A = B = C = 1/3.
    fixed = (1 / 3, 1 / 3, 1 / 3) if estimate else tuple(torque)
    problem = CompositeProblem(events, prior, f_hz=f_hz, torque=fixed, h_max=h_max, steps=steps)
    t0 = time.perf_counter()
    start = nls(problem)
    t1 = time.perf_counter()
    sampled, sample_start = problem, start
    if estimate:
        from loadbayes.fit.composite import torque as ct

        sampled = ct.TorqueProblem(events, prior, f_hz=f_hz, torque=fixed, h_max=h_max, steps=steps)
        sample_start = ct.extend_start(start, np.zeros(2))
    student_t = None
    if likelihood == "student-t":
        from loadbayes.fit.composite.robust import StudentT

        student_t = StudentT(nu=nu)
    elif likelihood != "normal":
        raise ValueError(f"likelihood must be 'normal' or 'student-t', got {likelihood!r}")
    res = sample(
        sampled,
        start=sample_start,
        draws=draws,
        burn=burn,
        thin=thin,
        chains=chains,
        seed=seed,
        workers=workers,
        move=move,
        student_t=student_t,
    )
    t2 = time.perf_counter()
    theta = np.stack([r.theta for r in res])
    betas = np.stack([r.beta for r in res])
    tau = np.stack([r.tau for r in res])
    phi = np.stack([r.phi for r in res]) if problem.n_steps else None
    abc = None
    if estimate:
        z = np.stack([r.u_extra for r in res])
        abc = np.apply_along_axis(lambda x: np.array(ct.shares(x)), -1, z)
        draws_named = named_draws(problem, theta, betas, tau, phi=phi, abc=abc)
        for i, name in enumerate(("log_a_over_c", "log_b_over_c")):
            draws_named[name] = z[..., i]
    else:
        draws_named = named_draws(problem, theta, betas, tau, phi=phi)
    common = {
        "n": int(sum(e.n for e in events)),
        "events": [
            {
                "name": e.name,
                "n": e.n,
                "t_span_s": float(e.t[-1] - e.t[0]),
                "v0": e.v0,
                "angle_from": e.angle_from or None,
            }
            for e in events
        ],
        "f_hz": f_hz,
        "torque": "estimate" if estimate else list(torque),
        "torque_prior": "Dirichlet(1, 1, 1) on (a, b, c), sampled in log(a/c), log(b/c)"
        if estimate
        else None,
        "prior": prior.to_dict(),
        "h_max_s": h_max,
        "steps": {
            "modelled": bool(steps),
            "intervals": [
                {"event": int(e), "k": int(k), "t_s": float(t), "dt_s": float(w)}
                for e, k, t, w in zip(
                    problem.grid.event_of,
                    problem.grid.k_of,
                    problem.grid.left,
                    problem.grid.width,
                    strict=True,
                )
            ],
        },
        "shunt": "q_c = mva_m * q_m(0): the motor's initial Q compensated at v0",
        "closure": "xs = xr",
        **(settings or {}),
    }
    free = ["f_m", "t_prime_s", "x_prime", "x_open", "h_s", "rs", "t0", *step_names(problem)]
    coefficients = [
        n
        for n in draws_named
        if not n.startswith("tau") and n not in ("a", "b", "c", "f_hz") and not n.startswith("v0")
    ]
    robust_settings, constant, robust_warn = {}, {}, []
    if student_t is not None:
        from loadbayes.fit.composite.robust import robust_outputs

        robust_settings, constant, robust_warn = robust_outputs(problem, res, nu, draws_named)
    post = Posterior(
        draws_named,
        model="composite",
        method=_METHOD[move] + ("-student-t" if student_t else ""),
        constant=constant,
        warnings=robust_warn,
        coefficients=coefficients,
        free=free,
        observed={"t_s": events[0].t, "v": events[0].v, "p": events[0].p, "q": events[0].q},
        settings={
            **common,
            "draws": draws,
            "burn": burn,
            "thin": thin,
            "seed": seed,
            "scheme": f"metropolis-within-gibbs ({_MOVE_NAME[move]} on theta, beta "
            "integrated out; beta and tau exact)",
            "move": move,
            "acceptance": [r.acceptance for r in res],
            "evaluations_per_iteration": [r.evaluations_per_iteration for r in res],
            "seconds": {"nls": t1 - t0, "sampler": t2 - t1},
            "likelihood": likelihood,
            **robust_settings,
        },
    )
    ident = identifiability(theta, draws_named["f_m"], prior, len(events))
    if abc is not None:
        ident["torque"] = ct.torque_identifiability(abc)
        ident["summary"] += " " + ident["torque"]["summary"]
    post.extra_json["identifiability"] = ident
    weak = [n for n, p in ident["parameters"].items() if p["verdict"] == "prior-driven"]
    if weak:
        post.warnings.append(
            "prior-driven (the events barely inform them): "
            + ", ".join(_PLAIN[n] for n in weak)
            + ". "
            + "; ".join(ident["what_would_help"])
            + " would help."
        )
    post.warnings.extend(sampling_warnings(events, draws_named["t_prime_s"], steps_modelled=steps))
    if chains > 1:
        import warnings as _w

        from loadbayes.posterior import _arviz

        with _w.catch_warnings():
            _w.simplefilter("ignore")
            watch = list(THETA_NAMES[:5]) + (["log_a_over_c", "log_b_over_c"] if estimate else [])
            rhat = {n: float(_arviz().rhat(draws_named[n])) for n in watch}
        slow = [n for n, r in rhat.items() if not r < 1.01]
        if slow:
            post.warnings.append(
                "the chains have not converged for "
                + ", ".join(f"{n} (R-hat {rhat[n]:.3f})" for n in slow)
                + ": run longer (--draws, --burn)"
            )
    bl_draws = _baseline(problem, start, chains, max((draws - burn) // thin, 1), seed)
    baseline = Posterior(
        bl_draws,
        model="composite",
        method="nls-penalised",
        coefficients=coefficients,
        free=free,
        settings={
            **common,
            "nls_seconds": start.seconds,
            "nls_nfev": start.nfev,
            "residual_sd": start.sigma.tolist(),
            "estimate_u": dict(zip(SCALE_FREE_NAMES, start.u[:5].tolist(), strict=True)),
            "estimate_step_fraction": problem.phi(start.u).tolist(),
        },
    )
    return CompositeFit(post, baseline, problem, start, {"nls": t1 - t0, "sampler": t2 - t1})


def beta_from_named(draws: dict[str, np.ndarray], event: int = 0) -> np.ndarray:
    """The linear coefficients (..., 7) of one event, rebuilt from the named draws."""
    sfx = "" if event == 0 else f"_e{event}"
    p0, q0, f_m = draws[f"p0{sfx}"], draws[f"q0{sfx}"], draws[f"f_m{sfx}"]
    pz = p0 * (1 - f_m)
    cols = [pz * draws[f"a{i}{sfx}"] for i in (1, 2, 3)]
    cols += [q0 * draws[f"a{i}{sfx}"] for i in (4, 5, 6)]
    cols.append(f_m * p0)
    return np.stack(cols, axis=-1)


def predictive_band(
    post: Posterior,
    events: Sequence[Event],
    *,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0),
    n_draws: int = 200,
    prob: float = 0.95,
    seed: int = 0,
) -> list[dict[str, np.ndarray]]:
    """Posterior band of the model's P(t), Q(t) for each event (noise not added).

    Returns, per event, ``p_lo, p_mid, p_hi, q_lo, q_mid, q_hi`` (the ``prob`` central
    interval and the median over ``n_draws`` posterior draws).
    """
    from loadbayes.models.composite import design, motor_response
    from loadbayes.models.composite_steps import StepGrid

    rng = np.random.default_rng(seed)
    theta = np.stack([post.draws[n] for n in THETA_NAMES], -1).reshape(-1, 6)
    # The draws carry the torque shares (constants unless they were estimated).
    abc = (
        np.stack([post.draws[n] for n in ("a", "b", "c")], -1).reshape(-1, 3)
        if all(n in post.draws for n in ("a", "b", "c"))
        else np.tile(np.asarray(torque, dtype=float), (theta.shape[0], 1))
    )
    pick = rng.choice(theta.shape[0], size=min(n_draws, theta.shape[0]), replace=False)
    out = []
    for k, ev in enumerate(events):
        beta = beta_from_named(post.draws, k).reshape(-1, 7)
        # The steps where each draw put them (none when the fit read them as ramps).
        sfx = "" if k == 0 else f"_e{k}"
        delta = np.zeros(ev.n) if ev.delta is None else ev.delta - ev.delta[0]
        grid = StepGrid.build([ev.t], [ev.v], [delta], detect=f"t_step0{sfx}" in post.draws)
        names = [f"t_step{j}{sfx}" for j in range(grid.n_steps)]
        times = np.stack([post.draws[n].ravel() for n in names], -1) if names else None
        ps, qs = [], []
        for i in pick:
            t_aug = grid.times(grid.phi_of(times[i])) if names else grid.t
            aug, real = grid.motor_input(0, t_aug)
            r = motor_response(aug, theta[i], f_hz=f_hz, torque=tuple(abc[i]))
            if r is not None:
                zp, zq = design(ev, r[0][real], r[1][real])
                ps.append(zp @ beta[i])
                qs.append(zq @ beta[i])
        lo, hi = 50 * (1 - prob), 50 * (1 + prob)
        band = {}
        for name, arr in (("p", np.array(ps)), ("q", np.array(qs))):
            band[f"{name}_lo"], band[f"{name}_mid"], band[f"{name}_hi"] = np.percentile(
                arr, [lo, 50, hi], axis=0
            )
        out.append(band)
    return out
