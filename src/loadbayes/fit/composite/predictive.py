"""The composite fit's posterior band of P(t), Q(t) for each event, and the events it keeps.

:func:`predictive_band` plays posterior draws through each event: the model's band
(``p_lo, p_mid, p_hi``, ...) and the posterior-predictive band ``p_pred_lo, p_pred_hi,
q_pred_lo, q_pred_hi`` (each draw's noise added: normal with its precision ``tau_p``,
``tau_q``, Student-t with its ``nu_p``, ``nu_q`` when sampled), where a new recording of
the same event would fall; :func:`event_arrays` stores the
recordings in the result (the NetCDF's ``constant_data``) so that the report can draw
them again, and :func:`events_of` reads them back; :func:`fault_times` says where each
event's voltage moved fast (the figure's zooms).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from loadbayes.fit.composite.naming import beta_from_named, event_suffix
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import (
    BETA_NAMES,
    THETA_NAMES,
    design,
    motor_response,
)
from loadbayes.models.composite_steps import FitSamples, StepGrid
from loadbayes.posterior import Posterior

__all__ = ["event_arrays", "events_of", "fault_times", "predictive_band", "window_of"]

#: Prefix of the recordings' arrays in the posterior's constants (``rec_v``, ``rec_v_e1``).
REC = "rec_"


def window_of(settings: dict) -> float:
    """The phasor window (s) a fit read its samples with: 0 for point samples.

    A result written before the window was recorded (no ``samples`` in its settings)
    read point values for the motor: 0 then.
    """
    samples = settings.get("samples")
    if not isinstance(samples, dict):
        return 0.0
    return float(samples.get("window_s") or 0.0)


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
    theta = np.stack([post.draws[n] for n in THETA_NAMES], -1).reshape(-1, len(THETA_NAMES))
    # The draws carry the torque shares (constants unless they were estimated).
    abc = (
        np.stack([post.draws[n] for n in ("a", "b", "c")], -1).reshape(-1, 3)
        if all(n in post.draws for n in ("a", "b", "c"))
        else np.tile(np.asarray(torque, dtype=float), (theta.shape[0], 1))
    )
    pick = rng.choice(theta.shape[0], size=min(n_draws, theta.shape[0]), replace=False)
    out = []
    steps = post.settings.get("steps") or {}
    edge_window = steps.get("window_s")
    edge_window = 1.0 / f_hz if edge_window is None else float(edge_window)
    window = window_of(post.settings)
    for k, recorded in enumerate(events):
        beta = beta_from_named(post.draws, k).reshape(-1, len(BETA_NAMES))
        # The steps where each draw put them (none when the fit read them as ramps).
        sfx = event_suffix(k)
        detect = f"t_step0{sfx}" in post.draws
        fs = FitSamples.find([recorded.t], [recorded.v], window_s=edge_window, detect=detect)
        keep = fs.keep[0]
        ev = replace(
            recorded, t=recorded.t[keep], v=recorded.v[keep], p=recorded.p[keep],
            q=recorded.q[keep], delta=None if recorded.delta is None else recorded.delta[keep],
        )  # fmt: skip
        delta = np.zeros(ev.n) if ev.delta is None else ev.delta - ev.delta[0]
        grid = StepGrid.build([ev.t], [ev.v], [delta], detect=detect, intervals=fs.intervals,
                              ends=fs.ends)  # fmt: skip
        names = [f"t_step{j}{sfx}" for j in range(grid.n_steps)]
        times = np.stack([post.draws[n].ravel() for n in names], -1) if names else None
        ps, qs, used = [], [], []
        for i in pick:
            t_aug = grid.times(grid.phi_of(times[i])) if names else grid.t
            aug, real = grid.motor_input(0, t_aug)
            # Phasor samples: window means at the real samples (as the fit read them).
            r = motor_response(aug, theta[i], f_hz=f_hz, torque=tuple(abc[i]), window_s=window,
                               real=real)  # fmt: skip
            if r is not None:
                zp, zq = design(ev, *r)
                ps.append(zp @ beta[i])
                qs.append(zq @ beta[i])
                used.append(i)
        lo, hi = 50 * (1 - prob), 50 * (1 + prob)
        band = {"t": ev.t, "k": keep}
        for name, arr in (("p", np.array(ps)), ("q", np.array(qs))):
            band[f"{name}_lo"], band[f"{name}_mid"], band[f"{name}_hi"] = np.percentile(
                arr, [lo, 50, hi], axis=0
            )
            noisy = arr + _noise(post, name, np.array(used, dtype=int), arr.shape, rng)
            band[f"{name}_pred_lo"], band[f"{name}_pred_hi"] = np.percentile(
                noisy, [lo, hi], axis=0
            )
        out.append(band)
    return out


def _noise(post: Posterior, ch: str, idx: np.ndarray, shape, rng) -> np.ndarray:
    # Each used draw's own noise: its precision (a sample's own, with AR(1) noise), and its
    # Student-t nu when sampled.
    tau = post.draws.get(f"tau_{ch}")
    if tau is None or idx.size == 0:
        return np.zeros(shape)
    tau = tau.reshape(-1)[idx]
    rho = post.draws.get(f"rho_{ch}")
    if rho is not None:  # AR(1): a sample's own variance is the innovations' / (1 - rho^2)
        tau = tau * (1.0 - rho.reshape(-1)[idx] ** 2)
    sd = 1.0 / np.sqrt(tau)[:, None]
    nu = post.draws.get(f"nu_{ch}")
    if nu is not None:
        return sd * rng.standard_t(nu.reshape(-1)[idx][:, None], size=shape)
    return sd * rng.standard_normal(shape)


def event_arrays(events: Sequence[EventRecord]) -> dict[str, np.ndarray]:
    """The recordings as constants of the result (the NetCDF's ``constant_data``).

    ``rec_t_s, rec_v, rec_p, rec_q`` (and ``rec_delta`` when the event has an angle);
    event ``k``'s with the suffix ``_e{k}``.
    """
    out = {}
    for k, ev in enumerate(events):
        sfx = event_suffix(k)
        for name, arr in (
            ("t_s", ev.t),
            ("v", ev.v),
            ("p", ev.p),
            ("q", ev.q),
            ("delta", ev.delta),
        ):
            if arr is not None:
                out[f"{REC}{name}{sfx}"] = np.asarray(arr, dtype=float)
    return out


def events_of(post: Posterior) -> list[EventRecord]:
    """The recordings a composite result keeps (:func:`event_arrays`).

    Named as in its settings; ``[]`` for a result written before they were kept.
    """
    c = post.constant
    names = [e.get("name", "") for e in post.settings.get("events", [])]
    out = []
    k = 0
    while f"{REC}t_s{event_suffix(k)}" in c:
        sfx = event_suffix(k)
        delta = c.get(f"{REC}delta{sfx}")
        out.append(
            EventRecord(
                np.asarray(c[f"{REC}t_s{sfx}"], dtype=float),
                np.asarray(c[f"{REC}v{sfx}"], dtype=float),
                np.asarray(c[f"{REC}p{sfx}"], dtype=float),
                np.asarray(c[f"{REC}q{sfx}"], dtype=float),
                None if delta is None else np.asarray(delta, dtype=float),
                names[k] if k < len(names) else f"event {k + 1}",
            )
        )
        k += 1
    return out


def fault_times(post: Posterior, events: Sequence[EventRecord]) -> list[list[float]]:
    """Per event, the instants (s) where its voltage starts or stops moving: the sag's edges.

    The fitted steps' instants (posterior medians) when the fit modelled steps, and the
    ends of every run of samples over which the voltage moves by more than 1% of ``v0``
    per interval (or five times the noise of its differences, whichever is larger): a
    step is one such run, a ramp (a recovery) a longer one, zoomed at its start and end.
    """
    out = []
    for k, ev in enumerate(events):
        sfx = event_suffix(k)
        steps = [n for n in post.draws if n.startswith("t_step") and n.endswith(sfx)
                 and (sfx or "_e" not in n)]  # fmt: skip
        found = sorted(float(np.median(post.draws[n])) for n in steps)
        dv = np.diff(ev.v)
        if dv.size:
            noise = 1.4826 * float(np.median(np.abs(dv - np.median(dv))))
            moving = np.flatnonzero(np.abs(dv) > max(0.01 * abs(ev.v0), 5 * noise))
            runs = np.split(moving, np.flatnonzero(np.diff(moving) > 1) + 1) if moving.size else []
            dt = float(np.median(np.diff(ev.t)))
            for run in runs:
                t_a, t_b = float(ev.t[run[0]]), float(ev.t[run[-1] + 1])
                edges = [0.5 * (t_a + t_b)] if run.size == 1 else [t_a, t_b]
                for edge in edges:
                    if all(abs(edge - f) > 1.5 * dt for f in found):
                        found.append(edge)
        out.append(sorted(found))
    return out
