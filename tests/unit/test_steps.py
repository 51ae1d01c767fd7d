"""Voltage steps in a day of data, and the ZIP fit from their windows (issue 22).

The day is made here (not by the package): 1-minute samples, a load level on a daily
profile (3.2 to 6.7 MW) with a slow random walk, a voltage that falls as the load rises
(the confounding that fools a one-level fit), LTC tap steps of 0.625% and a 3% CVR
step for 30 minutes, with 0.05% noise on V, 0.2% on P and 0.5% on Q. True shares
P (0.4, 0.35, 0.25): dP/dV at V0 = 1.15; Q (1.2, 0.8, -1.0): dQ/dV = 3.2.

False alarms: fixed seeds (deterministic). "Within 3.3 posterior sd" fails a correct
fit with probability 1e-3 per quantity (eight here). Over 40 generated days with
random tap times (not in the suite) the 95% intervals of dP/dV and dQ/dV covered the
truth 39 and 39 times, mean error +0.03 and -0.03 posterior sd (docs/zip.md).
"""

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit import fit_zip
from loadbayes.fit.steps import fit_steps
from loadbayes.io.errors import DataError
from loadbayes.measurements.steps import find_steps, steps_table

SH_P = (0.4, 0.35, 0.25)
SH_Q = (1.2, 0.8, -1.0)
DPDV, DQDV = 2 * SH_P[0] + SH_P[1], 2 * SH_Q[0] + SH_Q[1]
TAPS = (95, 260, 410, 433, 579, 752, 1139, 1187, 1290)
CVR = (840, 870)
FAST = SamplerSettings(draws=2500, burn=500, chains=2, seed=3)


def _day(seed=0, n=1440, taps=TAPS, cvr=CVR, gap=None):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 60.0
    if gap is not None:
        t[gap:] += 3600.0  # an hour of telemetry missing
    h = t / 3600
    level = 4.95 - 1.75 * np.cos(2 * np.pi * (h - 3) / 24)
    level = level + 0.1 * np.cumsum(rng.normal(0, 0.01, n))
    tap = np.zeros(n)
    for j, i in enumerate(taps):
        tap[i:] += 0.00625 * (1 if j % 3 != 1 else -1)
    cv = np.zeros(n)
    cv[cvr[0] : cvr[1]] = -0.03
    x = 1.03 - 0.04 * (level - 3.2) / 3.5 + tap + cv + 0.001 * np.sin(2 * np.pi * h / 1.3)
    p = level * np.polyval(SH_P, x) * (1 + 0.002 * rng.standard_normal(n))
    q = 0.3 * level * np.polyval(SH_Q, x) * (1 + 0.005 * rng.standard_normal(n))
    v = x * (1 + 0.0005 * rng.standard_normal(n))
    return t, v, p, q


def test_the_steps_are_found_at_their_sample():
    t, v, p, q = _day()
    steps, info = find_steps(v, p, q, t=t)
    assert [s.index for s in steps] == sorted(TAPS + CVR)
    assert info["noise_sd"] == pytest.approx(0.0005, rel=0.15)
    table = steps_table(steps, time=t)
    cvr = table[table["index"] == CVR[0]].iloc[0]
    assert cvr["dv"] == pytest.approx(-0.03, abs=0.002)
    # the drift is removed from each step: dP/P over dV/V near the true sensitivity
    assert abs(np.median(table["sens_p"]) - DPDV) < 0.25


def test_the_step_fit_covers_what_the_plain_fit_misses():
    t, v, p, q = _day()
    steps, _ = find_steps(v, p, q, t=t)
    post = fit_steps(v, p, q, steps=steps, t=t, sampler=FAST)
    d = post.draws
    for (i, j), truth in ((("a1", "a2"), DPDV), (("a4", "a5"), DQDV)):
        s = 2 * d[i] + d[j]
        assert abs(s.mean() - truth) < 3.3 * s.std()
        assert s.std() < 0.3  # and says something
    for name, truth in zip(("a1", "a2", "a3", "a4", "a5", "a6"), SH_P + SH_Q, strict=True):
        assert abs(d[name].mean() - truth) < 3.3 * d[name].std()
    derived = post.extra_json["derived"]
    assert derived["dP/dV"]["hdi_low"] < DPDV < derived["dP/dV"]["hdi_high"]
    # one level for the whole day: the load's daily rise is read as a voltage effect
    plain = fit_zip(
        {"v": v, "p": p}, sampler=SamplerSettings(draws=2000, burn=500, chains=2, seed=1)
    )
    s = 2 * plain.draws["a1"] + plain.draws["a2"]
    assert s.mean() < 0 and abs(s.mean() - DPDV) > 20 * s.std()


def test_close_steps_and_gaps_shorten_or_drop_windows():
    taps = (300, 302, 600, 700)
    t, v, p, q = _day(taps=taps, gap=702)
    steps, info = find_steps(v, p, q, t=t)
    found = [s.index for s in steps]
    assert 600 in found and 840 in found
    assert 700 not in found and info["too_close"] >= 1  # 2 samples before the gap
    assert not {300, 302} <= set(found)  # two taps 2 samples apart: not both
    for s in steps:
        assert not (s.lo < 702 <= s.hi - 1 and s.index != 702)  # no window across the gap


def test_fewer_than_two_steps_is_said_in_words():
    t, v, p, q = _day(taps=(), cvr=(0, 0))
    steps, _ = find_steps(v, p, q, t=t)
    assert steps == []
    with pytest.raises(DataError, match="0 voltage step"):
        fit_steps(v, p, q, steps=steps, t=t, sampler=FAST)


def test_the_recovery_term_reads_the_response_at_the_step_instant():
    # Thermostat-like loads (made here): at each step the power moves with x^2 at once,
    # then the duty cycle brings back the heat asked for with a 1 h lag, sampled every
    # 5 min (the first sample after a step already 1/12 of the way back). 60 steps of
    # +/-3%: the response at the step's instant is dP/dV = 2 per unit of the level.
    rng = np.random.default_rng(7)
    n, dt, a = 60 * 24, 300.0, 300.0 / 3600.0
    t = np.arange(n) * dt
    x = 1.015 - 0.03 * ((np.arange(n) // 24) % 2)  # a step every 2 h, about V0
    x = x + rng.normal(0, 0.0003, n)
    duty, p = 0.5, np.empty(n)
    for i in range(n):
        duty += a * (0.5 / x[i] ** 2 - duty)
        p[i] = duty * x[i] ** 2
    p = p * (1 + rng.normal(0, 0.001, n))
    found, _ = find_steps(x, p, t=t)
    assert len(found) >= 50
    kw = dict(steps=found, t=t, sampler=FAST)
    plain = fit_steps(x, p, **kw).extra_json["derived"]["dP/dV"]
    rec = fit_steps(x, p, **kw, recovery=3600.0).extra_json["derived"]["dP/dV"]
    # without the term the jumps read the response 1/12 recovered, and the window's
    # recovery on top: low by many sd (measured 1.891 +/- 0.020); with it the instant's
    # response (measured 2.004 +/- 0.007)
    assert plain["mean"] < 2.0 - 5 * plain["sd"]
    assert abs(rec["mean"] - 2.0) < 3.3 * rec["sd"], (plain, rec)


def _thermostats(lag, seed=7):
    # As above (made here), with the duty cycle's lag as given (exact per 5-min sample).
    rng = np.random.default_rng(seed)
    n, dt = 60 * 24, 300.0
    a = -np.expm1(-dt / lag)
    t = np.arange(n) * dt
    x = 1.015 - 0.03 * ((np.arange(n) // 24) % 2) + rng.normal(0, 0.0003, n)
    duty, p = 0.5, np.empty(n)
    for i in range(n):
        duty += a * (0.5 / x[i] ** 2 - duty)
        p[i] = duty * x[i] ** 2
    return t, x, p * (1 + rng.normal(0, 0.001, n))


def test_the_recovery_lag_is_averaged_over_its_prior_not_assumed():
    # Thermostats with a 30 min and a 2 h lag, not the 1 h the fixed term assumes. The
    # fixed lag reads the 30 min feeder's dP/dV low by many sd (measured on seeds 7, 8, 9:
    # z -9.4, -11.8, -8.7; on the 2 h feeder z +2.2, -0.2, +3.1: it misses 2 of 3); the
    # mixture over RECOVERY_LAGS_S covers both on all three (z +0.5, -1.8, +1.8 and +0.7,
    # -0.8, +0.8), and puts weight 1.00 on 30 min for the first.
    kw = dict(sampler=SamplerSettings(draws=1500, burn=300, chains=2, seed=3))
    for lag in (1800.0, 7200.0):
        t, x, p = _thermostats(lag)
        found, _ = find_steps(x, p, t=t)
        fixed = fit_steps(x, p, steps=found, t=t, recovery=3600.0, **kw)
        mixed = fit_steps(x, p, steps=found, t=t, recovery="prior", **kw)
        f, m = (r.extra_json["derived"]["dP/dV"] for r in (fixed, mixed))
        assert m["hdi_low"] < 2.0 < m["hdi_high"], (lag, m)
        assert abs(m["mean"] - 2.0) < 3.3 * m["sd"], (lag, m)
        rec = mixed.extra_json["recovery"]
        w = dict(zip(rec["lags_s"], rec["weights"], strict=True))
        assert mixed.settings["recovery_lag_weights"] == rec["weights"]
        if lag == 1800.0:
            assert f["mean"] < 2.0 - 5 * f["sd"], f  # the fixed lag misses
            assert w[1800.0] > 0.9 and "favour a recovery lag of 30 min" in rec["words"]
        else:
            assert w[900.0] + w[1800.0] < 0.05, w
    # a fixed lag is as before; a sequence of lags is a mixture over them
    assert fixed.extra_json.get("recovery") is None
    two = fit_steps(x, p, steps=found, t=t, recovery=(3600.0, 7200.0), **kw)
    assert two.extra_json["recovery"]["lags_s"] == [3600.0, 7200.0]
    with pytest.raises(ValueError, match="recovery"):
        fit_steps(x, p, steps=found, t=t, recovery="guess", **kw)
