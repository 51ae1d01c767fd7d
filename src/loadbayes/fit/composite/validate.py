"""A fitted composite load checked on events it was not fitted to (held-out validation).

Each held-out event's recorded voltage (magnitude and angle) drives the fitted load: every
posterior draw's motor (``THETA_NAMES``, torque shares) and composition (``f_m``, the ZIP
shares ``a1..a6`` of event 0) is set at the held-out event's own operating point, and the
noise of the fit (``tau_p``, ``tau_q``; with AR(1) noise a sample's own precision,
``tau (1 - rho^2)``) is added to give the posterior-predictive band of P and Q. The
recorded P and Q are then scored against it.

The operating point is the held-out event's: ``p0, q0`` are the means of its recorded P
and Q over the steady rows before the voltage first moves (by more than
:data:`~loadbayes.measurements.events.STEADY_DV` of its first sample), and the motor is
initialised in steady state at its first voltage. What carries over from the fit is the
load's make-up (the shares and the motor), not its size: a load that changed its size
between the events is predicted at its new size, one that changed its make-up is not.

The voltage is read linearly between samples (no step instants are estimated for an
event that was not fitted); the samples whose phasor window straddles a step (the
record's ``straddle`` column) are driven but not scored, and counted in ``n_excluded``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from loadbayes.fit.composite.predictive import window_of
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import THETA_NAMES, design, motor_response
from loadbayes.posterior import Posterior

__all__ = [
    "EventValidation",
    "operating_point",
    "read_exclusions",
    "band_scores",
    "gaussian_logl",
    "noise_precision",
    "pointwise_lpd",
    "validate_event",
    "validate_events",
]

#: Posterior draws played through each event (the band's percentiles come from them).
N_DRAWS = 200


@dataclass
class EventValidation:
    """One held-out event scored against the posterior-predictive band.

    ``rms_p``, ``rms_q`` are the RMS of recorded minus the posterior-mean prediction over
    the scored samples, per unit of the fitted P0 (event 0's posterior mean ``p0``);
    ``coverage_p``, ``coverage_q`` the fraction of scored samples inside the ``prob``
    band (model plus the fit's noise). ``band`` holds ``p_lo, p_mid, p_hi, q_lo, q_mid,
    q_hi`` (with noise: a new observation's band), ``p_mean, q_mean`` (the model alone) and
    ``p_spread, q_spread`` (the draws' standard deviation of the model alone) at every
    sample.
    """

    file: str
    n: int
    n_excluded: int
    rms_p: float
    rms_q: float
    coverage_p: float
    coverage_q: float
    event: EventRecord
    scored: np.ndarray
    band: dict[str, np.ndarray] = field(repr=False)
    p0: float = float("nan")
    q0: float = float("nan")
    draws_used: int = 0
    scale: float = float("nan")
    #: Log pointwise predictive density of each scored sample (P and Q together): the
    #: log of the mean over draws of its Gaussian likelihood; its sum is the event's elpd.
    lpd: np.ndarray | None = field(default=None, repr=False)
    #: With the fitted events' playback error (``validate_band.honest_band``): the
    #: fit-noise band's coverage, the band each channel's ``coverage`` is of, and the
    #: playback's error per channel (per unit of the fitted P0).
    coverage_fit_noise_p: float | None = None
    coverage_fit_noise_q: float | None = None
    band_p: str | None = None
    band_q: str | None = None
    playback: dict[str, Any] | None = field(default=None, repr=False)

    @property
    def elpd(self) -> float:
        """The held-out event's expected log predictive density (sum of ``lpd``)."""
        return float(np.sum(self.lpd)) if self.lpd is not None else float("nan")

    def to_dict(self) -> dict[str, Any]:
        """The JSON record of ``loadbayes validate``."""
        return {
            "file": self.file,
            "n": self.n,
            "n_excluded": self.n_excluded,
            "rms_p": self.rms_p,
            "rms_q": self.rms_q,
            "coverage_p": self.coverage_p,
            "coverage_q": self.coverage_q,
            "p0": self.p0,
            "q0": self.q0,
            "draws_used": self.draws_used,
            **self.band_record(),
            "iec_windows": self.window_errors(),
        }

    def band_record(self) -> dict[str, Any]:
        """Which band ``coverage_*`` is of, the fit-noise band's, and the playback error."""
        if self.playback is None:
            return {}
        return {"band_p": self.band_p, "band_q": self.band_q,
                "coverage_fit_noise_p": self.coverage_fit_noise_p,
                "coverage_fit_noise_q": self.coverage_fit_noise_q,
                "fitted_playback": self.playback}  # fmt: skip

    def window_errors(self) -> dict[str, Any]:
        """ME, MAE, MXE of the posterior-mean P, Q in the dip's windows (``windows.py``)."""
        from loadbayes.fit.composite.windows import window_errors

        ev = self.event
        return window_errors(ev.t, ev.v, {"p": ev.p, "q": ev.q},
                             {"p": self.band["p_mean"], "q": self.band["q_mean"]},
                             scale=self.scale, scored=self.scored)  # fmt: skip


def operating_point(event: EventRecord, scored: np.ndarray | None = None) -> tuple[float, float]:
    """Mean recorded ``(P, Q)`` over the steady rows before the voltage first moves."""
    from loadbayes.measurements.events import STEADY_DV

    moved = np.flatnonzero(np.abs(event.v / event.v0 - 1.0) > STEADY_DV)
    k = int(moved[0]) if moved.size else event.n
    rows = np.arange(max(k, 1))
    if scored is not None and scored[rows].any():
        rows = rows[scored[rows]]
    return float(np.mean(event.p[rows])), float(np.mean(event.q[rows]))


def noise_precision(d: dict, channel: str, i: int) -> float:
    """Draw ``i``'s precision of one sample's noise: ``tau`` (white) or ``tau (1 - rho^2)``.

    With AR(1) noise ``tau`` is the innovations'; a sample's own (stationary) variance is
    ``1 / (tau (1 - rho^2))``, which the pointwise band and log-likelihood read.
    """
    tau = d[f"tau_{channel}"][i]
    rho = d.get(f"rho_{channel}")
    return tau if rho is None else tau * (1.0 - rho[i] ** 2)


def _draws(post: Posterior) -> dict[str, np.ndarray]:
    need = [*THETA_NAMES, "f_m", "a1", "a2", "a3", "a4", "a5", "a6", "tau_p", "tau_q", "p0"]
    missing = [n for n in need if n not in post.draws]
    if missing:
        raise ValueError(
            "the posterior holds no draws of " + ", ".join(missing) + ": not a composite fit"
        )
    return {n: np.asarray(v, dtype=float).reshape(-1) for n, v in post.draws.items()}


def validate_event(
    post: Posterior,
    event: EventRecord,
    *,
    exclude: np.ndarray | None = None,
    f_hz: float | None = None,
    window_s: float | None = None,
    n_draws: int = N_DRAWS,
    prob: float = 0.95,
    seed: int = 0,
) -> EventValidation:
    """Play one event's voltage through the posterior and score its P and Q.

    Parameters
    ----------
    post : Posterior
        A composite posterior (``fit_composite(...).posterior`` or read from its NetCDF).
    event : EventRecord
        The held-out event (per unit on the fit's bases).
    exclude : ndarray of bool, optional
        Samples driven but not scored (their phasor window straddles a step).
    f_hz : float, optional
        Nominal frequency; by default the fit's (``f_hz`` draws or settings).
    window_s : float, optional
        The phasor window the samples are read with (0: point samples); by default the
        fit's (``settings["samples"]``).
    n_draws, prob, seed
        Posterior draws used, the band's probability and the seed picking the draws and
        the noise.

    Returns
    -------
    EventValidation
    """
    d = _draws(post)
    if f_hz is None:
        f_hz = float(d["f_hz"][0]) if "f_hz" in d else float(post.settings.get("f_hz", 60.0))
    if window_s is None:
        window_s = window_of(post.settings)
    rng = np.random.default_rng(seed)
    total = d["f_m"].size
    pick = rng.choice(total, size=min(n_draws, total), replace=False)
    scored = np.ones(event.n, dtype=bool) if exclude is None else ~np.asarray(exclude, bool)
    if scored.shape != (event.n,):
        raise ValueError(f"exclude has {scored.size} entries for {event.n} samples")
    if not scored.any():
        raise ValueError(f"{event.name or 'the event'}: every sample is excluded: nothing to score")
    p0n, q0n = operating_point(event, scored)
    delta = None if event.delta is None else event.delta - event.delta[0]
    ev = EventRecord(event.t - event.t[0], event.v, event.p, event.q, delta, event.name)
    theta = np.stack([d[n] for n in THETA_NAMES], -1)
    abc = (
        np.stack([d[n] for n in ("a", "b", "c")], -1)
        if all(n in d for n in ("a", "b", "c"))
        else np.tile([1.0, 0.0, 0.0], (total, 1))
    )
    means_p, means_q, noisy_p, noisy_q, logl = [], [], [], [], []
    for i in pick:
        r = motor_response(ev, theta[i], f_hz=f_hz, torque=tuple(abc[i]), window_s=window_s)
        if r is None or not (np.all(np.isfinite(r[0])) and abs(r[0][0]) > 0):
            continue
        zp, zq = design(ev, *r)
        pz = p0n * (1.0 - d["f_m"][i])
        beta = np.array(
            [pz * d["a1"][i], pz * d["a2"][i], pz * d["a3"][i],
             q0n * d["a4"][i], q0n * d["a5"][i], q0n * d["a6"][i], d["f_m"][i] * p0n]
        )  # fmt: skip
        mp, mq = zp @ beta, zq @ beta
        means_p.append(mp)
        means_q.append(mq)
        tau_p, tau_q = noise_precision(d, "p", i), noise_precision(d, "q", i)
        noisy_p.append(mp + rng.standard_normal(ev.n) / np.sqrt(tau_p))
        noisy_q.append(mq + rng.standard_normal(ev.n) / np.sqrt(tau_q))
        logl.append(gaussian_logl(event, mp, mq, tau_p, tau_q))
    if not means_p:
        raise ValueError(
            f"{event.name or 'the event'}: no posterior draw has a steady state at its first "
            f"voltage ({event.v0:.4g} p.u.): the motor stalls there"
        )
    scale = float(np.mean(d["p0"]))
    band, out = band_scores(event, scored, (noisy_p, noisy_q), (means_p, means_q), scale, prob)
    return EventValidation(
        file=event.name,
        n=event.n,
        n_excluded=int(event.n - scored.sum()),
        event=event,
        scored=scored,
        band=band,
        p0=p0n,
        q0=q0n,
        draws_used=len(means_p),
        scale=scale,
        lpd=pointwise_lpd(logl, scored),
        **out,
    )


def band_scores(event: EventRecord, scored: np.ndarray, noisy, means, scale: float,
                prob: float) -> tuple[dict[str, np.ndarray], dict[str, float]]:  # fmt: skip
    """The band of P and Q over the draws (with noise) and the event's scores against it.

    ``noisy``, ``means``: each channel's per-draw predictions with and without the fit's
    noise. Returns the band (``p_lo, p_mid, p_hi, p_mean, p_spread``, the same for ``q``:
    ``p_spread`` the draws' standard deviation of the response alone) and the
    RMS (per unit of ``scale``) and coverage of the scored samples.
    """
    lo, hi = 50 * (1 - prob), 50 * (1 + prob)
    band: dict[str, np.ndarray] = {}
    for ch, noisy_ch, mean in zip(("p", "q"), noisy, means, strict=True):
        band[f"{ch}_lo"], band[f"{ch}_mid"], band[f"{ch}_hi"] = np.percentile(
            np.array(noisy_ch), [lo, 50, hi], axis=0
        )
        band[f"{ch}_mean"] = np.mean(np.array(mean), axis=0)
        # The draws' spread of the response alone (fit/composite/model_error.py reads it).
        band[f"{ch}_spread"] = np.std(np.array(mean), axis=0)
    out = {}
    for ch in ("p", "q"):
        x = getattr(event, ch)[scored]
        out[f"rms_{ch}"] = float(np.sqrt(np.mean((x - band[f"{ch}_mean"][scored]) ** 2)) / scale)
        inside = (x >= band[f"{ch}_lo"][scored]) & (x <= band[f"{ch}_hi"][scored])
        out[f"coverage_{ch}"] = float(np.mean(inside))
    return band, out


def gaussian_logl(event: EventRecord, mp, mq, tau_p: float, tau_q: float) -> np.ndarray:
    """Each sample's log-likelihood of the recorded P and Q under one draw (Gaussian)."""
    return (
        -0.5 * tau_p * (event.p - mp) ** 2 - 0.5 * tau_q * (event.q - mq) ** 2
        + 0.5 * np.log(tau_p * tau_q) - np.log(2 * np.pi)
    )  # fmt: skip


def pointwise_lpd(logl: list[np.ndarray], scored: np.ndarray) -> np.ndarray:
    """``log mean_draws exp(logl)`` at each scored sample."""
    from scipy.special import logsumexp

    x = np.array(logl)[:, scored]
    return logsumexp(x, axis=0) - np.log(x.shape[0])


def validate_events(
    post: Posterior,
    events: Sequence[EventRecord],
    *,
    exclude: Sequence[np.ndarray | None] | None = None,
    **kw: Any,
) -> list[EventValidation]:
    """:func:`validate_event` for each event (``exclude`` one mask or None per event)."""
    masks = list(exclude) if exclude is not None else [None] * len(events)
    return [validate_event(post, e, exclude=m, **kw) for e, m in zip(events, masks, strict=True)]


_TRUE = {"true", "1", "1.0", "yes"}
_FALSE = {"false", "0", "0.0", "no", ""}


def read_exclusions(path: str, column: str | None, n: int) -> np.ndarray | None:
    """The boolean ``column`` of an event file (CSV or Parquet), or None when it is absent.

    Accepts booleans, 0/1 and ``true``/``false`` (any case); anything else is a
    :class:`~loadbayes.io.errors.DataError` naming the file, the column and the row.
    """
    from pathlib import Path

    import pandas as pd

    from loadbayes.io.errors import DataError

    if not column:
        return None
    if Path(path).suffix.lower() in (".parquet", ".pq"):
        import pyarrow.parquet as pq

        if column not in pq.read_schema(path).names:
            return None
        values = pd.read_parquet(path, columns=[column])[column]
    else:
        head = pd.read_csv(path, nrows=0)
        if column not in head.columns:
            return None
        values = pd.read_csv(path, usecols=[column], dtype=str, keep_default_na=False)[column]
    text = values.astype(str).str.strip().str.lower().to_numpy()
    bad = np.flatnonzero(~np.isin(text, list(_TRUE | _FALSE)))
    if bad.size:
        k = int(bad[0])
        raise DataError(f"{text[k]!r} is not true/false (or 1/0)", path, column, k + 1)
    if text.size != n:
        raise DataError(f"{text.size} rows, but the event has {n} samples", path, column)
    return np.isin(text, list(_TRUE))
