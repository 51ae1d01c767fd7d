"""The example of ``loadbayes example cvr``: a feeder's 90-day CVR on/off test, truth known.

A 12.47 kV feeder seen from its head every 5 minutes, in kV, MW and Mvar (fit with
``--v-base 12.47 --s-base 10``): resistive loads (``P ~ V^2``), constant-power
electronics, and thermostatic heaters whose share switched on follows the heat asked for
with a one-hour lag (at a lower voltage each draws less and runs longer: their energy
comes back); winter weather; behind-the-meter PV; the reduction (3%) on one day of each
pair, switched at midnight; the head voltage ``V = Vs - z P`` with z = 0.003 p.u./MW;
two telemetry gaps, a V spike, a P spike and two hours of stuck P. Columns: ``time``,
``v_kv``, ``p_mw``, ``q_mvar``, ``temp_c``, ``irradiance``, ``holiday``, ``cvr_on``.

The truth (:func:`cvr_truth`) is counterfactual: the same 90 days run with the reduction
on every day and off every day, ``log(E_off / E_on) / log(V_off / V_on)`` for the energy
factor; the instantaneous dP/dV at V0 per unit of the net level is ``sum k_i P_i / P``,
averaged over the dark hours' samples weighted by P (the hours the fit's steps come from
when a PV column is given). The tests check ``loadbayes cvr`` on feeders written apart
from this module (tests/cvr_generator.py); this one makes the README's example.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["FEEDER_KV", "FEEDER_MVA", "cvr_frame", "cvr_truth"]

FEEDER_KV = 12.47
FEEDER_MVA = 10.0
DAY = 86_400.0
STEP = 300.0
DAYS = 90


def _inputs(seed: int):
    rng = np.random.default_rng(seed)
    n = int(DAYS * DAY / STEP)
    t = np.arange(n) * STEP
    day = (t // DAY).astype(int)
    hour = (t % DAY) / 3600.0
    noon = (np.arange(DAYS) + 0.5) * DAY
    weekend = ((day % 7) >= 5) | np.isin(day, (20, 61))

    def bump(centre, width):  # periodic in the hour: nothing jumps at midnight
        return np.exp(-0.5 * (((hour - centre + 12.0) % 24.0 - 12.0) / width) ** 2)

    occ = (0.45 + 0.3 * bump(7.5, 1.5) + np.where(weekend, 0.45, 0.6) * bump(19.0, 2.0)
           + np.where(weekend, 0.35, 0.2) * bump(13.0, 3.5))  # fmt: skip
    occ *= np.interp(t, noon, np.exp(0.03 * rng.standard_normal(DAYS)))
    anomaly = np.zeros(DAYS)
    for d in range(1, DAYS):
        anomaly[d] = 0.7 * anomaly[d - 1] + 2.5 * rng.standard_normal()
    temp = 5.0 + 0.1 * t / DAY + np.interp(t, noon, anomaly)
    temp += 4.0 * np.cos(2 * np.pi * (hour - 15.0) / 24.0)
    sun = np.clip(np.cos(np.pi * (hour - 12.5) / 12.0), 0, None) ** 2
    sun *= np.interp(t, noon, rng.uniform(0.25, 1.0, DAYS))
    sun *= np.clip(1 + 0.15 * rng.standard_normal(n), 0.3, 1.2)
    on = np.zeros(DAYS, dtype=int)
    for d in range(0, DAYS, 2):
        on[d + int(rng.random() < 0.5)] = 1
    taps = np.cumsum(np.where(rng.random(n) < 2.0 / 288, rng.choice([-1, 1], n), 0))
    vs = 1.0 + 0.00625 * np.clip(taps - np.round(np.convolve(taps, np.ones(577) / 577, "same")),
                                 -2, 2)  # fmt: skip
    return rng, t, day, occ, temp, sun, on, vs


def _run(occ, temp, sun, vs_day, z=0.003):
    """Head V, net P, Q and the instantaneous sensitivity, sample by sample."""
    heat = 0.12 * np.maximum(16.0 - temp, 0.0)
    rated = 2.5 * heat.max()
    share = heat[0] / rated
    n = occ.size
    v, p, q, sens = (np.empty(n) for _ in range(4))
    x, a = 1.0, STEP / 3600.0
    for i in range(n):
        for _ in range(4):
            s_i = min(max(share + a * (heat[i] / (rated * x * x) - share), 0.0), 1.0)
            res, el, th = 1.2 * occ[i] * x * x, 1.8 * occ[i], s_i * rated * x * x
            pn = res + el + th - 2.2 * sun[i]
            x = vs_day[i] - z * pn
        share = s_i
        v[i], p[i], q[i] = x, pn, 0.35 * (res / (x * x) + el) * x**3
        sens[i] = 2 * res + 2 * th
    return v, p, q, sens


#: The generated samples left out of the telemetry (two gaps).
GAPS = ((3000, 3040), (19000, 19020))


def _kept(n: int) -> np.ndarray:
    keep = np.ones(n, dtype=bool)
    for a, b in GAPS:
        keep[a:b] = False
    return keep


def cvr_truth(seed: int = 39, step_rows=None) -> dict[str, float]:
    """The example's energy and instantaneous factors (module notes).

    With ``step_rows`` (the 1-based data rows of the steps a fit used, as ``loadbayes
    cvr``'s JSON lists them) also ``dp_dv_at_steps``: ``sum k_i P_i / P`` at those
    instants, each weighted by its voltage change squared, what a fit of one dP/dV from
    those steps estimates when their own dP/dV differ (the thermostatic share follows
    the hour: a 3% switch at midnight weighs 23 times a 0.625% tap of the day).
    """
    _, t, day, occ, temp, sun, on, vs = _inputs(seed)
    v1, p1, q1, _ = _run(occ, temp, sun, vs - 0.03)
    v0, p0, q0, _ = _run(occ, temp, sun, vs)
    v, p, _, sens = _run(occ, temp, sun, vs - 0.03 * on[day])
    dark = sun < 0.02 * sun.max()
    lv = np.log(v0.mean() / v1.mean())
    extra = {}
    if step_rows is not None:
        idx = np.flatnonzero(_kept(t.size))[np.asarray(step_rows, dtype=int) - 1]
        w = (v[idx] - v[idx - 1]) ** 2
        extra["dp_dv_at_steps"] = float(np.sum(w * sens[idx] / p[idx]) / np.sum(w))
    return {
        **extra,
        "cvr_energy_p": float(np.log(p0.sum() / p1.sum()) / lv),
        "cvr_energy_q": float(np.log(q0.sum() / q1.sum()) / lv),
        "dp_dv_dark_hours": float(sens[dark].sum() / p[dark].sum()),
        "z_pu_per_mw": 0.003,
    }


def cvr_frame(seed: int = 39) -> pd.DataFrame:
    """The example's telemetry (module notes)."""
    rng, t, day, occ, temp, sun, on, vs = _inputs(seed)
    v, p, q, _ = _run(occ, temp, sun, vs - 0.03 * on[day])
    n = t.size
    v = v + 0.0005 * rng.standard_normal(n)
    p = p * (1 + 0.004 * rng.standard_normal(n))
    q = q * (1 + 0.004 * rng.standard_normal(n))
    v[4000] *= 1.09
    p[15000] += 6.0
    p[9000:9024] = p[9000]
    keep = _kept(n)
    stamps = pd.Timestamp("2026-01-05") + pd.to_timedelta(t, unit="s")
    frame = pd.DataFrame({
        "time": stamps.strftime("%Y-%m-%dT%H:%M:%S"),
        "v_kv": np.round(FEEDER_KV * v, 4),
        "p_mw": np.round(p, 4),
        "q_mvar": np.round(q, 4),
        "temp_c": np.round(temp, 1),
        "irradiance": np.round(1000 * sun, 0),
        "holiday": np.isin(day, (20, 61)).astype(int),
        "cvr_on": on[day],
    })  # fmt: skip
    return frame[keep].reset_index(drop=True)
