"""How the composite fit's residuals run in time: their lag-1 autocorrelation.

The likelihood takes the noise on P and Q as independent from sample to sample. On an
event the model describes (a simulation with white noise) the residuals are; on a real
or third-party recording the model misses something systematic (a load that is not
exactly ZIP + one motor, a recorder's filter, the other simulator's details), and the
residuals then run in long stretches of one sign. An independent-noise likelihood then
counts each sample as new information when it is not: the intervals come out too
narrow. For residuals that behave like an AR(1) series with coefficient ``r``, the
variance of a mean is ``(1 + r) / (1 - r)`` times the independent one, so the intervals
are too narrow by about ``sqrt((1 + r) / (1 - r))`` (1.7 at r = 0.5, 3 at r = 0.8).

:func:`residual_autocorrelation` measures ``r`` per channel over posterior draws (each
event's residuals at the draw, the lag-1 sample autocorrelation, averaged over events
and draws); the fit records it and warns above :data:`WARN_LAG1`.

With ``--noise ar1`` the fit models that error as AR(1) instead. Its coefficient can go
so near 1 that the error's memory outlasts the motor's own dynamics: then the error term
can take over part of the load's response, and the motor's parameters are fitted beside
it rather than from the data alone (the real record's first fault: rho 0.97 per 5 ms
sample, a memory of 0.17 s, and T' 0.026 s against 0.11 s with white noise).
:func:`ar1_memory_warning` says so.
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.models.composite import SCALE_FREE_MATRIX, SCALE_FREE_NAMES, design

__all__ = [
    "N_DRAWS",
    "WARN_LAG1",
    "ar1_memory_warning",
    "residual_autocorrelation",
    "residual_warning",
]

#: Lag-1 autocorrelation above which the fit warns (intervals too narrow by more than
#: sqrt((1 + r) / (1 - r)) = 1.35 at 0.3). White noise on n samples gives r within
#: +-2/sqrt(n) (0.08 at 600 samples): 0.3 is not a false alarm.
WARN_LAG1 = 0.3


def _lag1(e: np.ndarray) -> float:
    e = e - e.mean()
    den = float(e @ e)
    return float(e[1:] @ e[:-1]) / den if den > 0 else 0.0


#: Posterior draws the lag-1 autocorrelation is averaged over. On the real record's first
#: fault one draw's lag-1 of P has an sd of 0.067 across draws: over 20 draws the mean
#: moved by 0.015 (one standard error) with the draws picked, and two machines printed
#: 0.49 and 0.51; over 200 its standard error is 0.005, for 200 playbacks of the fit.
N_DRAWS = 200


def residual_autocorrelation(
    problem, theta: np.ndarray, phi: np.ndarray | None, betas: np.ndarray, *,
    n_draws: int = N_DRAWS, seed: int = 0, abc: np.ndarray | None = None,
    mcse: dict[str, float] | None = None,
) -> dict[str, float]:  # fmt: skip
    """Mean lag-1 autocorrelation of the P and Q residuals over ``n_draws`` draws.

    ``theta`` (chain, draw, 6), ``phi`` (chain, draw, steps) or None, ``betas``
    (chain, draw, events, 7), ``abc`` (chain, draw, 3) estimated torque shares or None.
    ``mcse``, where given, is filled with each mean's standard error over the draws
    picked (their sd over the square root of their number).
    """
    rng = np.random.default_rng(seed)
    th = theta.reshape(-1, theta.shape[-1])
    bt = betas.reshape(-1, *betas.shape[-2:])
    ph = None if phi is None else phi.reshape(-1, phi.shape[-1])
    ab = None if abc is None else abc.reshape(-1, 3)
    pick = rng.choice(th.shape[0], size=min(n_draws, th.shape[0]), replace=False)
    r = {"p": [], "q": []}
    for i in pick:
        u = (SCALE_FREE_MATRIX @ th[i])[: len(SCALE_FREE_NAMES)]
        if ph is not None and ph.shape[-1]:
            u = np.concatenate([u, ph[i]])
        resp = problem.responses(u, None if ab is None else tuple(ab[i]))
        if resp is None:
            continue
        for e, (ev, (pm, qm)) in enumerate(zip(problem.events, resp, strict=True)):
            zp, zq = design(ev, pm, qm)
            r["p"].append(_lag1(ev.p - zp @ bt[i, e]))
            r["q"].append(_lag1(ev.q - zq @ bt[i, e]))
    if mcse is not None:
        mcse.update({k: float(np.std(v) / math.sqrt(len(v))) if v else math.nan
                     for k, v in r.items()})  # fmt: skip
    return {k: float(np.mean(v)) if v else math.nan for k, v in r.items()}


def residual_warning(lag1: dict[str, float]) -> str | None:
    """The plain-words warning when the residuals run in stretches (lag-1 > WARN_LAG1)."""
    high = {k: v for k, v in lag1.items() if math.isfinite(v) and v > WARN_LAG1}
    if not high:
        return None
    worst = max(high.values())
    factor = math.sqrt((1 + worst) / (1 - worst)) if worst < 1 else math.inf
    parts = ", ".join(f"{k.upper()} {v:.2f}" for k, v in high.items())
    return (
        f"the residuals run in stretches (lag-1 autocorrelation {parts}): the model misses "
        "something systematic in the recording, and the intervals, which take the noise "
        f"as independent from sample to sample, are too narrow by about {factor:.1f}x: "
        "refit with --noise ar1 (noise='ar1') to model it, and compare the fit with the "
        "recording in the figure (--plot)"
    )


def ar1_memory_warning(draws: dict[str, np.ndarray], dt_s: float) -> str | None:
    """The plain-words warning when the AR(1) error remembers longer than the motors.

    ``draws``: the fit's named draws (``rho_p``, ``rho_q`` and every motor's
    ``t_prime_s*``); ``dt_s``: the sample interval (s). The error's memory is the time
    its correlation falls to 1/e, ``dt / -ln(rho)`` at the posterior median of ``rho``;
    the warning fires where it is longer than the slowest motor's median T'.
    """
    tps = [float(np.median(v)) for n, v in draws.items() if n.startswith("t_prime_s")]
    if not tps or not dt_s > 0:
        return None
    slowest = max(tps)
    slow = {}
    for ch in ("p", "q"):
        rho = draws.get(f"rho_{ch}")
        if rho is None:
            continue
        r = float(np.median(rho))
        memory = dt_s / -math.log(r) if 0 < r < 1 else (math.inf if r >= 1 else 0.0)
        if memory > slowest:
            slow[ch] = (r, memory)
    if not slow:
        return None
    said = ", ".join(
        f"{ch.upper()} rho {r:.3f} per sample, {m:.3g} s" for ch, (r, m) in slow.items()
    )
    return (
        f"the AR(1) model error remembers longer than the motor ({said}, the time its "
        f"correlation falls to 1/e, against T' {slowest:.3g} s): an error that slow can take "
        "over part of the load's own response, so the motor's parameters are fitted beside "
        "it, not from the data alone; compare them with the fit with --noise white, and "
        "read a difference as the model lacking what the recording holds"
    )
