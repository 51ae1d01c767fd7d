"""A year (or any span) of feeder SCADA written here, with NumPy only (issue 39).

Independent of the package: nothing here imports loadbayes. What it makes, every
``dt_s`` seconds:

* a load level with a season (a winter peak, +/-20%), a daily profile with a morning
  bump and an evening peak (weekends lower and later), and a slow random wander (an
  Ornstein-Uhlenbeck process on the log-level: about 0.2% a minute at short range,
  about 3% over days);
* a voltage with its own daily cycle of +/-1% (its phase not the load's: the source's
  own profile), a slow wander of its own (OU, 0.3% over hours), tap steps of 0.625% at
  random times (about 120 a year) that pull it back toward 1 p.u., and no measurement
  noise unless ``v_noise`` is given (0.01% is a 1-minute mean of a class 0.2 transducer);
* P = level x (a1 x^2 + a2 x + a3) and Q = 0.4 level x (a4 x^2 + a5 x + a6), x = V/v0,
  with 0.3% noise on each; the truth dP/dV = 2 a1 + a2 at v0 = 1 (per unit of the level
  per unit of V), dQ/dV = 2 a4 + a5.

The voltage does not answer to the load here (no source impedance): V is an outside
cause of P at every time scale, and only its daily cycle shares the load's period.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Year:
    """The generator's knobs (the defaults: the issue's independent year)."""

    days: int = 365
    dt_s: float = 60.0
    taps_per_year: float = 120.0
    v_cycle: float = 0.01
    v_wander: float = 0.003
    load_wander: float = 0.03
    load_fast: float = 0.01
    p_noise: float = 0.003
    v_noise: float = 0.0
    a: tuple[float, float] | None = None  # (a1, a2); drawn when None
    first_weekday: int = 0  # 0 = Monday


def _ou(rng, n, dt_s, sd, tau_s):
    """An Ornstein-Uhlenbeck path of stationary sd ``sd`` and time constant ``tau_s``."""
    phi = np.exp(-dt_s / tau_s)
    eps = rng.normal(0.0, sd * np.sqrt(1 - phi * phi), n)
    out = np.empty(n)
    x = rng.normal(0.0, sd)
    for i in range(n):  # a recursion: 0.3 s for a year at 1 min
        x = phi * x + eps[i]
        out[i] = x
    return out


def year(seed: int, cfg: Year = Year()):
    """Times (s), V (p.u.), P, Q (MW, Mvar) and the truth, for one seed.

    Returns
    -------
    t, v, p, q : ndarray
    truth : dict
        ``dP/dV``, ``dQ/dV``, ``a`` (a1..a6) and ``taps`` (the count).
    """
    rng = np.random.default_rng(seed)
    n = int(round(cfg.days * 86_400 / cfg.dt_s))
    t = np.arange(n) * cfg.dt_s
    day = t / 86_400.0
    hour = (t / 3600.0) % 24
    weekend = ((np.floor(day).astype(int) + cfg.first_weekday) % 7) >= 5
    season = 1.0 + 0.2 * np.cos(2 * np.pi * (day - 15) / 365)

    def bump(center, width):
        d = (hour - center + 12) % 24 - 12
        return np.exp(-0.5 * (d / width) ** 2)

    prof_wd = 0.55 + 0.25 * bump(7.5, 1.5) + 0.6 * bump(19.0, 2.0) + 0.1 * bump(13.0, 3.0)
    prof_we = 0.55 + 0.15 * bump(10.0, 2.5) + 0.5 * bump(19.5, 2.2) + 0.1 * bump(14.0, 3.0)
    # the day type changes over four hours around midnight (a load does not jump)
    k = max(int(round(4 * 3600 / cfg.dt_s)), 1)
    c = np.r_[0.0, np.cumsum(weekend.astype(float))]
    lo = np.clip(np.arange(n) - k // 2, 0, n)
    hi = np.clip(lo + k, 0, n)
    share = (c[hi] - c[lo]) / np.maximum(hi - lo, 1)
    profile = share * prof_we + (1 - share) * prof_wd
    wander = _ou(rng, n, cfg.dt_s, cfg.load_wander, 2 * 86_400.0)
    fast = _ou(rng, n, cfg.dt_s, cfg.load_fast, 3600.0)  # weather, appliances: 1% over an hour
    level = 5.0 * season * profile * np.exp(wander + fast)

    # the voltage: its own daily cycle (lowest before dawn, highest mid-afternoon), a
    # wander, and taps at random times that pull it toward 1 p.u.
    v = 1.0 + cfg.v_cycle * np.sin(2 * np.pi * (hour - 9.0) / 24)
    v = v + _ou(rng, n, cfg.dt_s, cfg.v_wander, 6 * 3600.0)
    n_taps = rng.poisson(cfg.taps_per_year * cfg.days / 365)
    at = np.sort(rng.choice(np.arange(1, n), size=n_taps, replace=False))
    tap = np.zeros(n)
    offset = 0.0
    for i in at:
        offset -= 0.00625 * np.sign(v[i] + offset - 1.0 + 1e-12)
        offset = float(np.clip(offset, -0.05, 0.05))
        tap[i:] = offset
    v = v + tap
    if cfg.a is None:
        a1, a2 = rng.uniform(-0.5, 1.0), rng.uniform(0.0, 1.5)
    else:
        a1, a2 = cfg.a
    a4, a5 = 2.0, 1.0
    pv = a1 * v**2 + a2 * v + 1 - a1 - a2
    qv = a4 * v**2 + a5 * v + 1 - a4 - a5
    p = level * pv * (1 + rng.normal(0, cfg.p_noise, n))
    q = 0.4 * level * qv * (1 + rng.normal(0, cfg.p_noise, n))
    vm = v + rng.normal(0, cfg.v_noise, n)
    truth = {"dP/dV": 2 * a1 + a2, "dQ/dV": 2 * a4 + a5,
             "a": (a1, a2, 1 - a1 - a2, a4, a5, 1 - a4 - a5), "taps": int(n_taps)}  # fmt: skip
    return t, vm, p, q, truth
