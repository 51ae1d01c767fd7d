"""An independent feeder for CVR tests: NumPy only, no import of loadbayes.

The yardstick of issue 39: a distribution feeder's head telemetry (V, P, Q every few
minutes) through a conservation-voltage-reduction on/off test, made from physics written
here and nothing of the package, so that a mistake shared by the fit and its data cannot
hide.

The feeder
----------
Per sample ``t`` (time step ``dt``), with ``x = V / 1.0`` the head voltage in per unit:

* resistive loads (lighting, cooking, water kettles): ``P = R occ(t) x^2``;
* constant-power electronics: ``P = E occ(t)``;
* thermostatic heaters and coolers: a population whose share ``N_t`` of units switched on
  follows the heat it must deliver, ``H_t`` (from the temperature), with a lag ``tau``::

      N_t = N_{t-1} + dt / tau (H_t / (R_rated x_t^k) - N_{t-1}),  0 <= N <= 1,
      P_th = N_t R_rated x_t^k

  (``k = 2`` for heaters, ``1`` for coolers): at a voltage step their power moves at once
  with ``x^k``, then their duty cycle lengthens and the energy comes back (over a day the
  heat delivered is the heat asked for, whatever the voltage);
* reactive power: ``Q = qf (R + E) occ(t) x^3 + qc P_cool`` (motors and ballasts);
* behind-the-meter PV (a constant-power inverter): ``P_pv`` from a clear-sky bell times a
  daily cloudiness and fast cloud flicker; the head sees ``P - P_pv`` (reverse flow at
  noon on sunny mild days when the PV is large);
* ``occ(t)``: an occupancy profile by hour (morning and evening peaks), lower on weekends
  and holidays, times a slow growth of the feeder and a day-to-day factor (each day's
  value at its noon, linear in between, as the weather's anomaly and the cloudiness:
  nothing jumps at midnight, when the reduction switches).

The voltage at the head answers to the feeder's load through a source impedance ``z``
(p.u. per MW)::

    V_t = Vs_t - z P_net,t,   Vs_t = 1.0 + tap_t + wander_t - depth [on_t]

solved by fixed-point iteration at each sample. ``on_t`` is the CVR schedule: days in
pairs, one on and one off in a random order, switched at midnight; ``tap_t`` upstream tap
moves (0.625% steps, a few a day), ``wander_t`` a slow AR(1) of the transmission voltage.

Telemetry: noise on V, P, Q; two gaps of several hours; P stuck for three hours; a +9%
spike on V and a +6 MW spike on P.

The truth
---------
The energy CVR factor is the counterfactual: the same 90 days (same weather, sun, taps,
noise-free) run with the reduction on every day and off every day;
``cvr_energy = log(E_off / E_on) / log(V_off / V_on)`` with E the head's net energy and V
the head's mean voltage. The instantaneous factor ``dP/dV`` at V0, per unit of the net
level: ``sum_i k_i P_i / P_net`` at each sample (``sens``, ``p_net`` and the head's ``v``
per sample, so that a test can weigh it where it likes: :func:`dpdv_at_steps`);
``cvr_inst`` is its energy-weighted mean over the record, ``sum(sens) / sum(p_net)``
over the noise-free samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DAY = 86_400.0


@dataclass
class Feeder:
    """A feeder's settings (MW at 1 p.u.; degrees C)."""

    days: int = 90
    step_s: float = 300.0
    start: str = "2026-01-05"  # a Monday
    resistive_mw: float = 1.2
    electronics_mw: float = 1.8
    heat_mw_per_deg: float = 0.12  # heat asked for per degree below heat_set
    cool_mw_per_deg: float = 0.10  # per degree above cool_set
    heat_set: float = 16.0
    cool_set: float = 22.0
    temp_mean: float = 6.0  # the season's mean temperature at the start
    temp_trend: float = 0.12  # degrees per day (spring: heating fades, cooling comes)
    tau_s: float = 3_600.0  # the thermostats' lag
    pv_mw: float = 2.2
    z_pu_per_mw: float = 0.003
    depth: float = 0.03  # the CVR reduction in p.u.
    qf: float = 0.35
    qc: float = 0.5
    v_noise: float = 0.0005
    p_noise: float = 0.004  # relative
    day_sd: float = 0.03  # day-to-day factor of occupancy
    growth: float = 0.05  # over the record
    holidays: tuple[int, ...] = (25, 60)
    glitches: bool = True
    gaps: bool = True
    extra: dict = field(default_factory=dict)


def _bump(hour: np.ndarray, centre: float, width: float) -> np.ndarray:
    """A daily bump, periodic in the hour (no step at midnight)."""
    d = (hour - centre + 12.0) % 24.0 - 12.0
    return np.exp(-0.5 * (d / width) ** 2)


def _occupancy(hour: np.ndarray, weekend: np.ndarray) -> np.ndarray:
    morning = _bump(hour, 7.5, 1.5)
    evening = _bump(hour, 19.0, 2.0)
    day = _bump(hour, 13.0, 3.5)
    work = 0.45 + 0.35 * morning + 0.6 * evening + 0.25 * day
    rest = 0.45 + 0.15 * morning + 0.55 * evening + 0.4 * day
    return np.where(weekend, rest, work)


def _simulate(f: Feeder, rng_parts: dict, on: np.ndarray):
    """Noise-free head V, P, Q and the per-sample sensitivity, for a given schedule."""
    n = f.days * int(round(DAY / f.step_s))
    t = np.arange(n) * f.step_s
    day = (t // DAY).astype(int)
    hour = (t % DAY) / 3600.0
    wd = (np.arange(f.days) % 7)[day]  # start on a Monday
    weekend = (wd >= 5) | np.isin(day, f.holidays)
    grow = 1.0 + f.growth * t / t[-1]
    occ = _occupancy(hour, weekend) * _daily(rng_parts["day_factor"], t) * grow
    temp = rng_parts["temp"]
    heat = f.heat_mw_per_deg * np.maximum(f.heat_set - temp, 0.0)
    cool = f.cool_mw_per_deg * np.maximum(temp - f.cool_set, 0.0)
    rated_h = 2.5 * max(heat.max(), 1e-6)
    rated_c = 2.5 * max(cool.max(), 1e-6)
    pv = f.pv_mw * rng_parts["sun"]
    vs = 1.0 + rng_parts["tap"] + rng_parts["wander"] - f.depth * on[day]
    res0 = f.resistive_mw * occ
    el = f.electronics_mw * occ
    v = np.empty(n)
    p = np.empty(n)
    q = np.empty(n)
    sens = np.empty(n)
    nh = heat[0] / rated_h
    nc = cool[0] / rated_c
    a = f.step_s / f.tau_s
    x = 1.0
    for i in range(n):
        for _ in range(4):  # V = Vs - z P(V): a contraction (z P' << 1)
            nh_i = min(max(nh + a * (heat[i] / (rated_h * x * x) - nh), 0.0), 1.0)
            nc_i = min(max(nc + a * (cool[i] / (rated_c * x) - nc), 0.0), 1.0)
            ph = nh_i * rated_h * x * x
            pc = nc_i * rated_c * x
            pr = res0[i] * x * x
            pn = pr + el[i] + ph + pc - pv[i]
            x = vs[i] - f.z_pu_per_mw * pn
        nh, nc = nh_i, nc_i
        v[i], p[i] = x, pn
        qr = f.qf * (res0[i] + el[i]) * x**3
        q[i] = qr + f.qc * pc
        sens[i] = 2.0 * pr + 2.0 * ph + 1.0 * pc
    return {"t": t, "day": day, "v": v, "p": p, "q": q, "sens": sens, "weekend": weekend,
            "temp": temp, "pv": pv, "hour": hour, "sun": rng_parts["sun"]}  # fmt: skip


def _daily(values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A day's value at its noon, linear in between: no jump at midnight."""
    noon = (np.arange(values.size) + 0.5) * DAY
    return np.interp(t, noon, values)


def _parts(f: Feeder, rng: np.random.Generator) -> dict:
    n = f.days * int(round(DAY / f.step_s))
    t = np.arange(n) * f.step_s
    hour = (t % DAY) / 3600.0
    # weather: a seasonal trend, a daily cycle, and AR(1) day-to-day anomalies
    anom = np.zeros(f.days)
    for d in range(1, f.days):
        anom[d] = 0.7 * anom[d - 1] + 2.5 * rng.standard_normal()
    temp = (f.temp_mean + f.temp_trend * t / DAY + _daily(anom, t)
            + 4.0 * np.cos(2 * np.pi * (hour - 15.0) / 24.0))  # fmt: skip
    cloud = rng.uniform(0.25, 1.0, f.days)
    bell = np.clip(np.cos(np.pi * (hour - 12.5) / 12.0), 0.0, None) ** 2
    flick = np.clip(1.0 + 0.15 * rng.standard_normal(n), 0.3, 1.2)
    sun = bell * _daily(cloud, t) * flick
    # upstream taps: a few moves a day, held near zero
    tap = np.zeros(n)
    level = 0.0
    moves = rng.random(n) < 3.0 / (DAY / f.step_s)
    for i in range(n):
        if moves[i]:
            level += 0.00625 * (1 if rng.random() < 0.5 - 40 * level else -1)
        tap[i] = level
    wander = np.zeros(n)
    e = rng.standard_normal(n) * 0.0004
    for i in range(1, n):
        wander[i] = 0.995 * wander[i - 1] + e[i]
    day_factor = np.exp(f.day_sd * rng.standard_normal(f.days))
    return {"temp": temp, "sun": sun, "tap": tap, "wander": wander, "day_factor": day_factor}


def schedule(days: int, rng: np.random.Generator) -> np.ndarray:
    """Days in pairs, one on (1) and one off (0) in a random order."""
    on = np.zeros(days, dtype=int)
    for d in range(0, days - 1, 2):
        first = int(rng.random() < 0.5)
        on[d], on[d + 1] = first, 1 - first
    if days % 2:
        on[-1] = int(rng.random() < 0.5)
    return on


def feeder(seed: int, f: Feeder | None = None):
    """One generated on/off test: (the telemetry as a dict of columns, the truth).

    Columns: ``time`` (ISO timestamps), ``v_kv`` (12.47 kV base), ``p_mw``, ``q_mvar``,
    ``temp_c``, ``cvr_on`` (the schedule, 0/1), ``holiday`` (0/1), ``irradiance`` (W/m2,
    5% noise: the PV's proxy).
    """
    f = f or Feeder()
    rng = np.random.default_rng(seed)
    on = schedule(f.days, rng)
    parts = _parts(f, rng)
    run = _simulate(f, parts, on)
    all_on = _simulate(f, parts, np.ones(f.days, dtype=int))
    all_off = _simulate(f, parts, np.zeros(f.days, dtype=int))
    cvr_e = np.log(all_off["p"].sum() / all_on["p"].sum()) / np.log(
        all_off["v"].mean() / all_on["v"].mean()
    )
    cvr_q = np.log(all_off["q"].sum() / all_on["q"].sum()) / np.log(
        all_off["v"].mean() / all_on["v"].mean()
    )
    n = run["t"].size
    v = run["v"] + f.v_noise * rng.standard_normal(n)
    p = run["p"] * (1.0 + f.p_noise * rng.standard_normal(n))
    q = run["q"] * (1.0 + f.p_noise * rng.standard_normal(n))
    keep = np.ones(n, dtype=bool)
    glitch = {}
    if f.glitches:
        i = int(rng.integers(n // 10, n // 2))
        v[i] *= 1.09
        j = int(rng.integers(n // 2, 9 * n // 10))
        p[j] += 6.0
        k = int(rng.integers(n // 5, 4 * n // 5))
        w = int(3 * 3600 / f.step_s)
        p[k : k + w] = p[k]
        glitch = {"v_spike_row": i, "p_spike_row": j, "stuck_rows": (k, k + w)}
    if f.gaps:
        for _ in range(2):
            g = int(rng.integers(0, n - 100))
            keep[g : g + int(rng.integers(12, 60))] = False
    start = np.datetime64(f.start + "T00:00:00")
    stamps = start + (run["t"] * 1000).astype("timedelta64[ms]")
    day = run["day"]
    cols = {
        "time": np.datetime_as_string(stamps[keep], unit="s"),
        "v_kv": (12.47 * v)[keep],
        "p_mw": p[keep],
        "q_mvar": q[keep],
        "temp_c": run["temp"][keep],
        "cvr_on": on[day][keep],
        "holiday": np.isin(day, f.holidays).astype(int)[keep],
        "irradiance": (1000.0 * run["sun"] * (1 + 0.05 * rng.standard_normal(n)))[keep],
    }
    clean = run["p"]
    truth = {
        "cvr_energy": float(cvr_e),
        "cvr_energy_q": float(cvr_q),
        "cvr_inst": float(run["sens"].sum() / clean.sum()),
        "sens": run["sens"],
        "p_net": clean,
        "v": run["v"],
        "z_pu_per_mw": f.z_pu_per_mw,
        "on": on,
        "depth": f.depth,
        "reverse_rows": int((p[keep] < 0).sum()),
        "thermostatic_share": float(
            (clean.sum() - _non_thermostatic(f, parts, on).sum()) / clean.sum()
        ),
        "glitches": glitch,
        "kept": keep,
    }
    return cols, truth


def dpdv_at_steps(truth: dict, step_rows) -> float:
    """dP/dV at V0 at the steps a fit used, each weighted by its voltage change squared.

    ``step_rows``: the 1-based data rows of the steps (``loadbayes cvr``'s JSON), whose
    samples are those after each step. The instantaneous response ``sum_i k_i P_i / P`` at
    each step (before the thermostats recover), averaged with the weight each step has in
    the data: a fit of one dP/dV to steps whose own dP/dV differ estimates their mean
    weighted by ``dV^2`` (a 3% CVR switch says 23 times what a 0.625% tap does). Why not
    the plain mean over the steps: the thermostatic share moves with the hour and the
    weather, so the steps' dP/dV spread over 0.75-1.5 on these feeders, and the switches
    at midnight (cold, the heaters on) sit above the taps of the day: on seed 1000 the
    plain mean is 1.177, the 68 switches' 1.226, the weighted mean 1.221.
    """
    at = np.flatnonzero(truth["kept"])[np.asarray(step_rows, dtype=int) - 1]
    w = (truth["v"][at] - truth["v"][at - 1]) ** 2
    return float(np.sum(w * truth["sens"][at] / truth["p_net"][at]) / np.sum(w))


def _non_thermostatic(f: Feeder, parts: dict, on: np.ndarray) -> np.ndarray:
    g = Feeder(**{**f.__dict__, "heat_mw_per_deg": 0.0, "cool_mw_per_deg": 0.0})
    return _simulate(g, parts, on)["p"]


def to_csv(cols: dict, path) -> None:
    """Write the columns as a CSV (header line, then one row per sample)."""
    names = list(cols)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(names) + "\n")
        arrays = [cols[k] for k in names]
        for row in zip(*arrays, strict=True):
            fh.write(",".join(r if isinstance(r, str) else f"{r:.6g}" for r in row) + "\n")


def zip_fleet(n: int, *, days: int = 14, v_noise: float = 0.0005, seed: int = 39):
    """A fleet of ``n`` feeders whose load is a true ZIP, for the drifting-level fleet fit.

    Each feeder is :func:`feeder` (seed ``2000 + i``) with no source impedance (the head
    voltage is an outside cause of P, as the drifting level assumes), no PV, no
    thermostatic loads and no glitches, and resistive and electronic loads in a share
    drawn per feeder (uniform 0.15-0.75 of 3 MW). Its P is ``(R x^2 + E) occ(t)``: the
    level P0(t) is ``(R + E) occ(t)`` and dP/dV at v0 per unit of it is ``2 R / (R + E)``,
    the truth returned. What :func:`feeder` makes for a seed is unchanged.

    Returns
    -------
    (columns with a ``feeder`` column, {feeder: dP/dV at v0})
    """
    rng = np.random.default_rng(seed)
    cols_all: dict[str, list] = {}
    truth = {}
    for i in range(n):
        share = float(rng.uniform(0.15, 0.75))
        f = Feeder(days=days, z_pu_per_mw=0.0, pv_mw=0.0, heat_mw_per_deg=0.0,
                   cool_mw_per_deg=0.0, glitches=False, resistive_mw=3.0 * share,
                   electronics_mw=3.0 * (1.0 - share), v_noise=v_noise)  # fmt: skip
        cols, _ = feeder(2000 + i, f)
        name = f"F{i:02d}"
        cols = {k: cols[k] for k in ("time", "v_kv", "p_mw", "q_mvar")}
        cols["feeder"] = np.full(cols["time"].size, name)
        for k, val in cols.items():
            cols_all.setdefault(k, []).append(val)
        truth[name] = 2.0 * share
    return {k: np.concatenate(v) for k, v in cols_all.items()}, truth
