"""The CVR factor of a feeder from an on/off test: ``loadbayes cvr`` and ``loadbayes.cvr``.

Conservation voltage reduction is judged by the energy CVR factor: the percentage change
of energy per percentage change of voltage, measured by switching the reduction on and
off on alternating days. This module answers that question from head telemetry (V, P,
optionally Q, every few seconds to minutes) and says how sure the answer is:

1. glitches (spikes in V and P, stuck values) are found and left out, and counted; rows
   where the net load reverses (behind-the-meter PV) are flagged
   (:mod:`loadbayes.fit.cvr_data`);
2. the on and off periods come from a schedule column when given, otherwise from the
   voltage by the step finder (the result says which);
3. the energy factor, with its 95% interval, by a Bayesian regression of daily energy on
   the on/off switching with the calendar, the weather and a drifting level, divided by
   the voltage change the switching caused (:mod:`loadbayes.fit.cvr_energy`);
4. beside it the instantaneous factor, dP/dV per unit of the level at the steps' median
   voltage (where the feeder runs, not carried to V0 by a ZIP curve), from the windows
   around the voltage steps (:func:`loadbayes.fit.steps.fit_steps`), each with a
   recovery term so that the jump is the load's response at the step's instant, before
   its thermostats take the power back (a lag of 1 h, assumed: docs/zip.md measures
   what a feeder of another lag reads, and why the lag is not averaged over a prior
   here); one dP/dV for
   steps whose own differ (the thermostatic share follows the hour) is their mean
   weighted by dV^2, so mostly that of the on/off switching itself;
5. whether the head voltage answers to the feeder's own load (the source impedance) and
   what a regression on the measured voltage would have said; the design's power (the
   on/off days an interval of +/-0.1 needs); and why the two factors differ when they do.

Both factors are fitted from outside causes of V only (the switching, the steps), so a
voltage that sags with the load does not bias them.

One idea needs these lines: the CVR answer as one sequence (steps 1-5 above, each the
call of its own module), with the result's words and the design's power beside it; the
data, the energy regression and the words are the modules named above.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.core.parallel import chain_generators, one_blas_thread
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.cvr_data import (
    daily_table,
    find_glitches,
    read_telemetry,
    relabel_days,
    schedule_from_steps,
    voltage_answers_to_load,
)
from loadbayes.fit.cvr_energy import LAMBDAS, design, direct_factor, sample_regression
from loadbayes.io.errors import DataError

__all__ = ["CVR_DEFAULTS", "cvr", "fit_cvr", "interval"]

#: Draws per chain (exact draws: no burn-in needed; the step fit uses its own defaults).
CVR_DEFAULTS = SamplerSettings(draws=4_000, burn=0, chains=2, seed=0)
#: The smallest voltage step taken for a CVR switch when the schedule is found from V.
MIN_SWITCH = 0.015
#: The most voltage steps the instantaneous fit takes (the largest).
MAX_STEPS = 120
#: A step counts as in the dark when the PV column is under this share of its largest.
PV_DARK = 0.02
#: The most data rows of each kind of flagged sample the JSON lists.
FLAGGED_ROWS = 100
#: The interval half-width the design's power is worked out for.
TARGET = 0.1


def interval(d: np.ndarray, prob: float = 0.95) -> dict[str, float]:
    """Mean, sd and the central ``prob`` interval of draws."""
    flat = np.asarray(d, dtype=float).reshape(-1)
    lo, hi = np.quantile(flat, [(1 - prob) / 2, (1 + prob) / 2])
    return {"mean": float(flat.mean()), "sd": float(flat.std(ddof=1)), "low": float(lo),
            "high": float(hi)}  # fmt: skip


def cvr(
    data: Any,
    *,
    t_col: str = "time",
    v_col: str = "v",
    p_col: str = "p",
    q_col: str | None = None,
    q_required: bool = True,
    v_base: float | None = None,
    s_base: float | None = None,
    schedule_col: str | None = None,
    weather_col: str | None = None,
    holiday_col: str | None = None,
    pv_col: str | None = None,
    instrument_col: str | None = None,
    v0: float = 1.0,
    knot_days: float = 7.0,
    min_switch: float = MIN_SWITCH,
    drop_against: bool = False,
    instant: bool = True,
    sampler: SamplerSettings | None = None,
    step_sampler: SamplerSettings | None = None,
    drop_invalid: bool = False,
) -> dict[str, Any]:
    """The energy and instantaneous CVR factors of an on/off test (module notes).

    Parameters
    ----------
    data : str, path or DataFrame
        Head telemetry, one row per sample: a time, V, P and optionally Q.
    t_col, v_col, p_col, q_col : str
        Column names (``q_col`` None: P only).
    q_required : bool
        False: Q is read only when its column is there.
    v_base, s_base : float, optional
        Bases that turn V into per unit (kV) and P, Q into per unit (MW, Mvar).
    schedule_col : str, optional
        The on/off schedule, 1 where the reduction is on; found from V's steps if None.
    weather_col : str, optional
        Outdoor temperature (C): heating and cooling degrees from 18 C enter the regression.
    holiday_col : str, optional
        1 on holidays (treated as a day of their own).
    pv_col : str, optional
        PV output or an irradiance proxy: its daily mean enters the regression.
    instrument_col : str, optional
        An outside cause of V the user names (a tap position, the upstream voltage): its
        daily mean takes the place of the on/off switching as the instrument.
    knot_days : float
        The drifting level's knots, in days.
    min_switch : float
        The smallest step of V (p.u.) taken for a switch when the schedule is found.
    drop_against : bool
        Leave out the steps where P moved against V from the instantaneous fit (off by
        default: on small steps that selects the noise that agrees, and leans dP/dV up).
    instant : bool
        Fit the instantaneous factor from the voltage steps too.
    sampler, step_sampler : SamplerSettings, optional
        The energy regression's draws (:data:`CVR_DEFAULTS`) and the step fit's.

    Returns
    -------
    dict
        The JSON of ``loadbayes cvr`` (see :func:`fit_cvr`).
    """
    path, cols, ext, rows, secs, stamps, note = read_telemetry(
        data, t_col=t_col, v_col=v_col, p_col=p_col, q_col=q_col, q_req=q_required, v_base=v_base,
        s_base=s_base, extra=(schedule_col, weather_col, holiday_col, pv_col, instrument_col),
        drop_invalid=drop_invalid,
    )  # fmt: skip
    given = {"schedule": schedule_col, "weather": weather_col, "holiday": holiday_col,
             "pv": pv_col, "instrument": instrument_col}  # fmt: skip
    named = {k: (None if c is None else ext[c]) for k, c in given.items()}
    try:
        out = fit_cvr(stamps, secs, cols["v"] / v0, cols["p"], cols.get("q"), **named,
                      knot_days=knot_days, min_switch=min_switch, drop_against=drop_against,
                      instant=instant, sampler=sampler, step_sampler=step_sampler,
                      s_base=s_base or 1.0)  # fmt: skip
    except DataError as exc:  # from the arrays: the file is named here
        if exc.path is not None:
            raise
        raise DataError(exc.message, path=path) from None
    if note:
        out["notes"].append(note)
    for key, idx in out["draws"]["flagged"].items():  # the data rows, as the file counts them
        where = out["reverse_flow"] if key == "reverse" else out["glitches"]
        where[f"{key}_rows"] = rows[idx[:FLAGGED_ROWS]].tolist()
    dpdv = out["instantaneous"].get("dP/dV", {})
    if "steps_at" in dpdv:  # the data rows (1-based) of the steps used
        dpdv["step_rows"] = rows[dpdv.pop("steps_at")].tolist()
    names = {"t": t_col, "v": v_col, "p": p_col, "q": q_col, **given}
    out["data"] = {"file": path, "rows": int(rows.size), "columns": names, "v_base": v_base,
                   "s_base": s_base, "v0": v0}  # fmt: skip
    return out


@one_blas_thread  # a few hundred coefficients; OpenBLAS's threads cost 3-4x the CPU
def fit_cvr(
    stamps: np.ndarray,
    t: np.ndarray,
    x: np.ndarray,
    p: np.ndarray,
    q: np.ndarray | None = None,
    *,
    schedule: np.ndarray | None = None,
    weather: np.ndarray | None = None,
    holiday: np.ndarray | None = None,
    pv: np.ndarray | None = None,
    knot_days: float = 7.0,
    min_switch: float = MIN_SWITCH,
    drop_against: bool = False,
    instant: bool = True,
    sampler: SamplerSettings | None = None,
    step_sampler: SamplerSettings | None = None,
    s_base: float = 1.0,
    instrument: np.ndarray | None = None,
) -> dict[str, Any]:
    """The CVR fit on arrays: ``x = V / V0`` per sample, ``p`` (``q``) per unit.

    Returns a dict: ``energy`` (the factor for P, and Q when given: mean, sd, 95%
    interval), ``instantaneous`` (dP/dV, dQ/dV from the steps, at ``at_v_pu``), ``schedule`` (its
    source and what was seen), ``days`` (one row per day kept, and those left out),
    ``glitches``, ``reverse_flow``, ``source_impedance``, ``direct`` (the factor from
    regressing on V itself), ``power`` (days needed for +/-0.1), ``why`` (the words when
    the two factors differ), ``warnings`` and ``notes``; ``draws`` (the factors' draws,
    for figures) is removed by the command before writing.
    """
    from loadbayes.fit.cvr_words import explain, impedance_words

    sampler = sampler or CVR_DEFAULTS
    kept = len(range(sampler.burn, sampler.draws, sampler.thin))
    gens = chain_generators(sampler.seed, 4 * sampler.chains)
    n = x.size
    warnings: list[str] = []
    notes: list[str] = []
    gl = find_glitches(x, p, q)
    good = ~gl.bad
    step_s = float(np.median(np.diff(t))) if n > 1 else 1.0
    if schedule is not None:
        on = (np.asarray(schedule, dtype=float) > 0.5).astype(np.int8)
        sched = {"source": "column", "switches": int(np.sum(np.diff(on) != 0))}
    else:
        xs = np.where(good, x, np.nan)
        keep = np.flatnonzero(good)
        state, info, doubt_k = schedule_from_steps(xs[keep], p[keep], t[keep], min_step=min_switch)
        on = np.zeros(n, dtype=np.int8)
        on[keep] = state
        doubt = np.zeros(n, dtype=bool)
        doubt[keep] = doubt_k
        on, flipped = relabel_days(stamps, x, on, good, doubt)
        sched = {"source": "voltage steps (the step finder)", **info, "days_relabelled": flipped}
        if info["steps"] < 2:
            raise DataError(
                f"no on/off switching found in the voltage (steps of {min_switch:g} p.u. "
                f"or more: {info['steps']}); give the schedule (--schedule-col) or lower "
                "--min-switch"
            )
        if info["repeats"] and not flipped:
            warnings.append(
                f"two voltage steps in a row went the same way at {info['repeats']} places: "
                "a switch may have been missed or a tap taken for one; give the schedule "
                "(--schedule-col) to be sure"
            )
    chans = {"p": p} if q is None else {"p": p, "q": q}
    days = daily_table(stamps, x, chans, on, good=good, step_s=step_s, weather=weather,
                       holiday=holiday, pv=pv)  # fmt: skip
    n_on, n_off = int(days.on.sum()), int((1 - days.on).sum())
    if n_on < 2 or n_off < 2:
        raise DataError(
            f"{n_on} day(s) with the reduction on and {n_off} off were usable: an energy "
            "factor needs at least two of each (a day counts when the reduction is on or "
            "off all day and 80% of its samples are there)"
        )
    treat, cause = None, "the on/off switching"
    if instrument is not None:
        treat, cause = days.instrument, "the instrument column"
    des = design(days, knot_days=knot_days, treat=treat, name="on")
    if des.z.shape[1] >= days.v.size:
        raise DataError(f"{days.v.size} days are too few for the {des.z.shape[1]} terms of "
                        "the regression (a longer test, or larger --knot-days)")  # fmt: skip
    dv = sample_regression(des, np.log(days.v), gens[: sampler.chains], kept)["on"]
    energy, draws, adjusted = {}, {}, None
    for k, (ch, e) in enumerate(days.energy.items()):
        if np.any(e <= 0):
            notes.append(f"the {ch.upper()} energy is not positive on every day: no energy "
                         f"factor for {ch.upper()}")  # fmt: skip
            continue
        g = gens[(k + 1) * sampler.chains : (k + 2) * sampler.chains]
        reg = sample_regression(des, np.log(e), g, kept)
        draws[ch] = reg["on"] / dv
        if ch == "p":  # the days with the calendar, weather and level taken out (figures)
            mean = reg.coef.reshape(-1, len(reg.names)).mean(axis=0)
            other = np.array([nm != "on" for nm in reg.names])
            adjusted = np.log(e) - des.z[:, other] @ mean[other]
        energy[ch] = interval(draws[ch])
        energy[ch]["lambda_posterior"] = dict(zip(map(str, LAMBDAS), reg.weights.tolist(),
                                                  strict=True))  # fmt: skip
    dv_i = interval(dv)
    direct = interval(direct_factor(days, np.log(days.energy["p"]), gens[3 * sampler.chains :],
                                    kept, knot_days))  # fmt: skip
    reverse = (p < 0) & good
    rev_days = np.unique(stamps[reverse].astype("datetime64[D]")).size if reverse.any() else 0
    if reverse.any():
        warnings.append(
            f"the net load reverses (behind-the-meter PV) at {int(reverse.sum())} samples "
            f"on {rev_days} day(s): the energy factor is per cent of the net energy at the "
            "head, and dP/dV per unit of the net level"
        )
    steps_at, inst, inst_draws = np.array([], int), {}, {}
    if instant:
        inst, steps_at, inst_draws, w = _instant(x, p, q, t, good, reverse, pv, drop_against,
                                                 step_sampler)  # fmt: skip
        warnings += w
    else:  # the steps are still left out of the load's own moves of V
        from loadbayes.measurements.steps import find_steps

        keep = np.flatnonzero(good)
        found, _ = find_steps(x[keep], p[keep], t=t[keep])
        steps_at = keep[[s.index for s in found]] if found else steps_at
    imp = voltage_answers_to_load(x, p, good, steps_at)
    if imp:
        imp = {k: (v / s_base if k in ("z", "low", "high") else v) for k, v in imp.items()}
    said = impedance_words(imp, direct, energy.get("p"))
    if said:
        notes.append(said)
    hw = 0.5 * (energy["p"]["high"] - energy["p"]["low"]) if "p" in energy else float("nan")
    used = int(days.v.size)
    need = int(np.ceil(used * (hw / TARGET) ** 2)) if np.isfinite(hw) else None
    power = {"days_used": used, "on_days": n_on, "off_days": n_off, "half_width": hw,
             "target_half_width": TARGET, "days_needed": need,
             "words": (f"the energy factor's 95% interval is +/-{hw:.2f} from {used} days; "
                       f"+/-{TARGET:g} needs about {need} on/off days of this feeder")}  # fmt: skip
    why = explain(energy.get("p"), inst.get("dP/dV"), draws.get("p"), inst_draws.get("dP/dV"))
    if "steps_used" in inst_draws:  # the samples (0-based, of the arrays) the steps begin at
        inst["dP/dV"]["steps_at"] = inst_draws.pop("steps_used").tolist()
    return {
        "energy": energy,
        "instantaneous": inst,
        "voltage_change": {"log_dv": dv_i, "percent": 100 * (np.exp(dv_i["mean"]) - 1)},
        "schedule": sched,
        "outside_cause": cause,
        "days": {"kept": used, **days.dropped, "table": days.rows()},
        "glitches": gl.counts(),
        "reverse_flow": {"samples": int(reverse.sum()), "days": int(rev_days)},
        "source_impedance": imp,
        "direct": direct,
        "power": power,
        "why": why,
        "warnings": warnings,
        "notes": notes,
        "settings": {
            "knot_days": knot_days,
            "min_switch": min_switch,
            "chains": sampler.chains,
            "draws": sampler.draws,
            "seed": str(sampler.seed),
            "interval": "central 95% (2.5% and 97.5% quantiles of the draws)",
        },
        "draws": {
            "energy": draws,
            "instantaneous": inst_draws,
            "days": days,
            "adjusted_log_energy": adjusted if "p" in energy else None,
            "flagged": {
                "spike_v": np.flatnonzero(gl.spike_v),
                "spike_p": np.flatnonzero(gl.spike_p),
                "stuck": np.flatnonzero(gl.stuck),
                "reverse": np.flatnonzero(reverse),
            },
        },
    }


def _rescaled(steps, v_op):
    """The steps with their voltages in units of ``v_op``."""
    from dataclasses import replace

    return [replace(s, dv=s.dv / v_op, v_before=s.v_before / v_op) for s in steps]


def _instant(x, p, q, t, good, reverse, pv, drop_against, step_sampler):
    """dP/dV (dQ/dV) at V0 from the voltage steps, the steps' positions and the warnings.

    Behind-the-meter PV makes the net level at the head small at noon, and dP/dV per unit
    of it large and erratic (measured on a generated feeder: 100 daytime tap steps gave
    -0.3 +/- 18 for a true 0.94). So with a PV column only the steps where PV is under
    ``PV_DARK`` of its largest are used; without one, when the net load reverses somewhere,
    the steps where the net level is under half its median are left out.
    """
    from loadbayes.fit.steps import RECOVERY_LAG_S, STEP_DEFAULTS, fit_steps
    from loadbayes.measurements.steps import find_steps

    keep = np.flatnonzero(good)
    xs, ps, ts = x[keep], p[keep], t[keep]
    qs = None if q is None else q[keep]
    found, _ = find_steps(xs, ps, qs, t=ts)
    at = keep[[s.index for s in found]] if found else np.array([], int)
    warnings = []
    if pv is not None:
        pvs = np.asarray(pv, dtype=float)[keep]
        dark = PV_DARK * max(float(np.max(pvs)), 1e-12)
        pos = [s for s in found if pvs[s.lo : s.hi].max() <= dark]
        why = "in daylight (PV moves the net level)"
    elif reverse.any():
        half = 0.5 * float(np.median(ps))
        pos = [s for s in found if ps[s.lo : s.hi].min() > half]
        why = ("where the net level was under half its median (PV; give --pv-col to use "
               "the dark hours)")  # fmt: skip
    else:
        pos = [s for s in found if ps[s.lo : s.hi].min() > 0]
        why = "where the net load was not positive"
    if len(pos) < len(found):
        warnings.append(f"{len(found) - len(pos)} of {len(found)} voltage steps {why} left "
                        "out of dP/dV")  # fmt: skip
    if drop_against:
        against = [s for s in pos if s.dv * s.dp < 0]
        if against:
            warnings.append(
                f"{len(against)} of {len(pos)} voltage steps where P moved against V left "
                "out of dP/dV (--drop-against; this leans dP/dV up when the steps are small)"
            )
        pos = [s for s in pos if s.dv * s.dp >= 0]
    if len(pos) > MAX_STEPS:  # the largest carry the most; the fit's cost grows as k^3
        pos = sorted(sorted(pos, key=lambda s: -abs(s.dv))[:MAX_STEPS], key=lambda s: s.index)
    if len(pos) < 2:
        warnings.append(f"{len(pos)} usable voltage step(s): no instantaneous factor")
        return {}, at, {}, warnings
    samp = step_sampler or STEP_DEFAULTS.with_(draws=3_000, burn=500)
    # at the steps' own voltage: a ZIP curve carried from there to V0 adds its
    # curvature's error (measured: 0.88 for a true 1.23 with the steps near 0.96 p.u.)
    v_op = float(np.median([s.v_before + 0.5 * s.dv for s in pos]))
    # recovery: thermostats have moved back by the first sample after a step, and the
    # jump alone reads dP/dV low (the 3% switches of the tests' feeders: 0.037 low, se
    # 0.009, over six; tests/statistical/test_cvr_coverage.py)
    post = fit_steps(xs / v_op, ps, qs, steps=_rescaled(pos, v_op), t=ts, v0=1.0, sampler=samp,
                     recovery=RECOVERY_LAG_S)  # fmt: skip
    out, draws = {}, {"steps_used": keep[[s.index for s in pos]]}
    for name, (i, j) in (("dP/dV", ("a1", "a2")), ("dQ/dV", ("a4", "a5"))):
        if i in post.draws:
            draws[name] = 2.0 * post.draws[i] + post.draws[j]
            out[name] = {**interval(draws[name]), "steps": len(pos), "at_v_pu": v_op,
                         "recovery_lag_s": RECOVERY_LAG_S}  # fmt: skip
    against = sum(1 for s in pos if s.dv * s.dp < 0)
    if against:
        warnings.append(f"at {against} of {len(pos)} voltage steps used P moved against V "
                        "(noise on small steps, or a load switching at the moment)")  # fmt: skip
    warnings += [w for w in post.warnings if "against V" not in w and "told apart" not in w]
    return out, at, draws, warnings
