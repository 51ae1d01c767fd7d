"""The composite fit's posterior band of P(t), Q(t) for each event (for the figure)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from loadbayes.fit.composite.naming import beta_from_named, event_suffix
from loadbayes.models.composite import THETA_NAMES, EventRecord, design, motor_response
from loadbayes.models.composite_steps import FitSamples, StepGrid
from loadbayes.posterior import Posterior

__all__ = ["predictive_band"]


def predictive_band(
    post: Posterior,
    events: Sequence[EventRecord],
    *,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0),
    n_draws: int = 200,
    prob: float = 0.95,
    seed: int = 0,
) -> list[dict[str, np.ndarray]]:
    """Posterior band of the model's P(t), Q(t) for each event (noise not added).

    Returns, per event, ``p_lo, p_mid, p_hi, q_lo, q_mid, q_hi`` (the ``prob`` central
    interval and the median over ``n_draws`` posterior draws) at the samples the fit
    read, whose times are ``t`` and indices ``k`` (the samples inside a fault's edge
    are left out, as in the fit: models/composite_steps.py).
    """
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
    steps = post.settings.get("steps") or {}
    window = steps.get("window_s") or 1.0 / f_hz
    for k, recorded in enumerate(events):
        beta = beta_from_named(post.draws, k).reshape(-1, 7)
        # The steps where each draw put them (none when the fit read them as ramps).
        sfx = event_suffix(k)
        detect = f"t_step0{sfx}" in post.draws
        fs = FitSamples.find([recorded.t], [recorded.v], window_s=window, detect=detect)
        keep = fs.keep[0]
        ev = replace(
            recorded, t=recorded.t[keep], v=recorded.v[keep], p=recorded.p[keep],
            q=recorded.q[keep], delta=None if recorded.delta is None else recorded.delta[keep],
        )  # fmt: skip
        delta = np.zeros(ev.n) if ev.delta is None else ev.delta - ev.delta[0]
        grid = StepGrid.build([ev.t], [ev.v], [delta], detect=detect, intervals=fs.intervals)
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
        band = {"t": ev.t, "k": keep}
        for name, arr in (("p", np.array(ps)), ("q", np.array(qs))):
            band[f"{name}_lo"], band[f"{name}_mid"], band[f"{name}_hi"] = np.percentile(
                arr, [lo, 50, hi], axis=0
            )
        out.append(band)
    return out
