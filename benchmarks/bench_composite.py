"""Benchmark: the composite load at the defaults against emcee and NumPyro NUTS (issue 35).

In one run, on each event, on the same posterior:

- ``fit_composite`` at the defaults (``COMPOSITE_DEFAULTS`` read at run time, run on
  until converged, the model reading the event as a user would: point samples said to
  be point samples, phasor rows read as one-cycle window means, the sag's edges as steps
  at unknown instants, the recorded angle), seeds 0-4: wall and CPU seconds, R-hat, ESS;
- the same sampler (defaults, seed 0) on the posterior the peers sample (the
  *comparison* posterior): ``CompositeModel(steps=False, window_s=0)`` on the event
  without its angle, the voltage read as the line between samples;
- emcee 3 (32 walkers, stretch move) on that posterior with the motor integrated by
  ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-6, atol 1e-9) inside each log-density
  call, timed for its seconds per step; its autocorrelation time from a long run on
  the same posterior with the package's compiled kernel inside; its ESS/s is 32 walkers
  / (tau x seconds per step);
- NumPyro NUTS with the ODE solved by diffrax (``composite_peers.py``) on that
  posterior, whitened by the package's own NLS (Laplace) fit, 1,000 warm-up iterations,
  target acceptance 0.9, 2 chains; its R-hat and ESS on its kept draws.

The events: the independent 10 s events at 60/s and 120/s (``tests/independent_composite.py``,
SciPy only); the real record's first fault at transformer #1, four phasors per cycle
(``studies.real_record.events_of``, as the demo's real section cuts it; skipped, saying
why, when the record is absent); a GridDyn CMLD event (``cases.griddyn``, run in its own
environment; skipped, saying why, when it is absent).

ESS is ArviZ's bulk ESS, the minimum over the reported parameters (constants left out).
Targets: ESS/s >= 100x NUTS + diffrax and >= 300x emcee + solve_ivp on every event.

Writes ``benchmarks/results/composite.json`` and prints a table. ``--part library`` runs
instead the older comparison of the package's moves on its own simulated event.

Run: ``python benchmarks/bench_composite.py [--quick] [--output PATH]``.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import math
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

PARAMS = (
    "p0 q0 a1 a2 a3 a4 a5 a6 f_m rs xs xm rr h_s t0 x_prime x_open t_prime_s mva_m q_c tau_p tau_q"
).split()
TRUTH_KEYS = ("f_m", "t_prime_s", "x_prime", "h_s", "p0", "q0", "a1", "a4")


def _event(fs: float, t_end: float, seed: int = 0):
    from loadbayes.cases.composite_sim import simulate_event

    return simulate_event(
        "small_industrial",
        depth=0.3,
        start_s=1.0,
        duration_s=0.2,
        recovery_s=0.3,
        t_end_s=t_end,
        fs=fs,
        noise=0.01,
        seed=seed,
        zip_p=(0.4, 0.2, 0.4),
        zip_q=(0.5, 0.2, 0.3),
    )


def _ess_rhat(draws: dict[str, np.ndarray]) -> tuple[float, float, str]:
    import arviz as az

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # Every reported parameter, the steps' instants included.
        names = [k for k in PARAMS if k in draws] + [k for k in draws if k.startswith("t_step")]
        s = az.summary({k: draws[k] for k in names}, round_to="none")
    worst = s["ess_bulk"].idxmin()
    return float(s["ess_bulk"].min()), float(s["r_hat"].max()), str(worst)


def _clock():
    return time.perf_counter(), time.process_time()


def run_loadbayes(fs, t_end, draws, burn, seed=0, move=None, steps=True, event=None,
                  model=None):  # fmt: skip
    """One fit; ``draws=None``: at the defaults (the sizes, chains and move the user gets).

    ``model``: the CompositeModel (default: ``steps``, point samples, 60 Hz).
    """
    from loadbayes.fit.composite.driver import COMPOSITE_DEFAULTS, fit_composite
    from loadbayes.fit.composite.sampler import DEFAULT_MOVE
    from loadbayes.models.zip_motor import CompositeModel

    move = move or DEFAULT_MOVE
    ev, truth = _event(fs, t_end) if event is None else event
    if draws is None:  # the defaults, as fit_composite takes them when given none
        run = COMPOSITE_DEFAULTS.with_(seed=seed, until_converged=True)
    else:
        run = COMPOSITE_DEFAULTS.with_(draws=draws, burn=burn, chains=4, seed=seed, move=move)
    model = model or CompositeModel(steps=steps, window_s=0)
    t0, c0 = _clock()
    fit = fit_composite(model, [ev], sampler=run)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    ess, rhat, worst = _ess_rhat(fit.posterior.draws)
    post_mean = fit.posterior.mean()
    truth = truth or {}
    return {
        "sampler": ("loadbayes-defaults" if draws is None else f"loadbayes-{move}")
        + ("" if model.steps else "-ramp"),
        "move": run.move or DEFAULT_MOVE,
        "steps": model.steps,
        "window_s": model.window_s,
        "seed": seed,
        "fs": float(round(1.0 / np.median(np.diff(ev.t)))),
        "n": ev.n,
        "settings": "defaults" if draws is None else f"4 chains x {draws} (burn {burn})",
        "wall_s": wall,
        "cpu_s": cpu,
        "nls_s": fit.seconds["nls"],
        "min_ess_bulk": ess,
        "worst": worst,
        "max_r_hat": rhat,
        "ess_per_s": ess / wall,
        "acceptance": float(np.mean(fit.posterior.settings["acceptance"])),
        "draws_per_chain": int(np.asarray(fit.posterior.draws["p0"]).shape[-1]),
        "errors": {k: float(post_mean[k] - truth[k]) for k in TRUTH_KEYS if k in truth},
    }


def run_emcee(fs, t_end, steps, seed=0, seconds=math.inf, motor="solve_ivp", event=None,
              f_hz=60.0):  # fmt: skip
    """emcee (32 walkers) on the comparison posterior, by steps until a step or time budget."""
    import emcee

    from composite_peers import emcee_log_density
    from loadbayes.fit.composite.nls import nls
    from loadbayes.fit.composite.problem import CompositeProblem, theta_of
    from loadbayes.models.composite_prior import CompositePrior

    ev, _ = _event(fs, t_end) if event is None else event
    prior = CompositePrior.default([ev])
    logp = emcee_log_density(ev, prior, f_hz, motor)
    start = nls(CompositeProblem([ev], prior, f_hz=f_hz, steps=False, window_s=0))
    centre = np.concatenate([start.u[:5], start.betas[0], np.log(1 / start.sigma**2)])
    cov = np.zeros((14, 14))
    cov[:12, :12] = start.cov[:12, :12]
    cov[12:, 12:] = np.eye(2) * 0.01
    rng = np.random.default_rng(seed)
    walkers = 32
    w, v = np.linalg.eigh(cov)
    root = v * np.sqrt(np.clip(w, 0, None))
    p0 = centre + (rng.standard_normal((walkers, 14)) @ root.T) * 0.5
    sampler = emcee.EnsembleSampler(walkers, 14, logp)
    sampler._random = np.random.RandomState(seed)  # emcee 3 draws from a RandomState
    t0, c0 = _clock()
    # Steps in blocks until the step budget or the time budget is spent (with solve_ivp
    # a log-density call costs ~0.1 s: a fixed step count would run for hours).
    state, done = p0, 0
    while done < steps and time.perf_counter() - t0 < seconds:
        state = sampler.run_mcmc(state, 5, progress=False)
        done += 5
    steps = done
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    chain = sampler.get_chain()[steps // 2 :]  # (steps, walkers, 14)
    x = np.transpose(chain, (1, 0, 2))
    log_t0 = np.array([prior.draw_log_t0(ui, rng) for ui in x[..., :5].reshape(-1, 5)])
    theta = theta_of(x[..., :5], log_t0.reshape(x.shape[:2]))
    named = _named(ev, theta, x[..., 5:12], np.exp(x[..., 12:]), f_hz)
    try:
        ess, rhat, worst = _ess_rhat(named)
    except Exception:  # too few steps for ArviZ's diagnostics
        ess, rhat, worst = math.nan, math.nan, "n/a"
    kept = walkers * (steps - steps // 2)
    try:  # emcee's integrated autocorrelation time, max over the 14 coordinates
        tau_int = float(np.max(sampler.get_autocorr_time(discard=steps // 2, tol=0)))
    except Exception:  # too few steps even for that
        tau_int = math.nan
    ess_bound = min(ess, kept) if math.isfinite(ess) else float(kept)
    return {
        "sampler": f"emcee-{motor}",
        "steps_done": steps,
        "kept_draws": kept,
        "autocorr_time_max": tau_int,
        "fs": float(round(1.0 / np.median(np.diff(ev.t)))),
        "n": ev.n,
        "settings": f"32 walkers x {steps} (discard {steps // 2})",
        "wall_s": wall,
        "cpu_s": cpu,
        "min_ess_bulk": ess,
        "worst": worst,
        "max_r_hat": rhat,
        "ess_per_s": ess_bound / wall,
        "acceptance": float(np.mean(sampler.acceptance_fraction)),
        "s_per_eval": wall / (walkers * steps),
    }


def _named(ev, theta, beta, tau, f_hz=60.0):
    """Named draws from a joint sampler's (chain, draw, ...) blocks, as the package's."""
    from loadbayes.fit.composite.naming import named_draws
    from loadbayes.fit.composite.problem import CompositeProblem
    from loadbayes.models.composite_prior import CompositePrior

    problem = CompositeProblem([ev], CompositePrior.default([ev]), f_hz=f_hz, steps=False,
                               window_s=0)  # fmt: skip
    return named_draws(problem, theta, beta[:, :, None, :], tau)


def _stationary_rate(em: dict, ek: dict) -> None:
    # emcee + solve_ivp's ESS/s in its stationary phase: walkers / (tau * seconds per
    # step), tau measured on the long run with the kernel (a property of the posterior and
    # the stretch move), seconds per step on the solve_ivp run. Kind to emcee: its
    # burn-in is not charged (loadbayes' is), and tau from 3,000 kept steps (~14 tau,
    # R-hat 1.3) is if anything too small.
    tau = ek["autocorr_time_max"]
    em["ess_per_s_from_long_tau"] = (
        32.0 / (tau * em["wall_s"] / em["steps_done"]) if math.isfinite(tau) else math.nan
    )


def _independent_event(fs: float, t_end: float, seed: int = 0):
    """A 10 s event from tests/independent_composite.py (SciPy only, no loadbayes code).

    The large slow motor (T' 0.70 s, not in the library), f_m 0.4, a 30% sag at
    1.0123 s (inside a sample interval) held 0.2 s with 20 ms ramps, point samples,
    0.5% noise; returned as the package's EventRecord with the generator's truth.
    """
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import independent_composite as ic
    from loadbayes.studies.calibration.composite_independent import event_records

    sag = ic.Sag(1.0123, 0.3, 0.2, 0.02, 0.02)
    df, truth = ic.simulate_event(
        motor="large_slow", f_m=0.4, sags=(sag,), rate_hz=fs, t_end_s=t_end, seed=seed
    )
    return event_records(df, f"independent {fs:g}/s")[0], truth


def _bare(ev):
    """The event as the peers read it: t, V, P, Q alone (no angle, no sequences)."""
    from loadbayes.measurements.record import EventRecord

    return EventRecord(ev.t, ev.v, ev.p, ev.q, None, ev.name)


def _real_event():
    """The real record's first fault at transformer #1, as the demo's real section cuts it."""
    from loadbayes.studies.real_record import BAYS, events_of, find_record

    cfg = find_record(Path(__file__).resolve().parent)
    if cfg is None:
        return None, "the real record is absent (shared/real/xtz.cfg beside the repository)"
    events, _, info = events_of(cfg, BAYS[0][0])  # four phasors per cycle
    return {"event": events[0], "truth": None, "f_hz": info["f_hz"], "window_s": None}, None


def _griddyn_event():
    """A GridDyn CMLD event: the 25% sag of cases.griddyn, one-cycle phasors, 1% noise."""
    from loadbayes.cases.griddyn import cases
    from loadbayes.cases.griddyn.events import griddyn_events
    from loadbayes.measurements.record import EventRecord

    reason = cases.skip_reason()
    if reason is not None:
        return None, reason
    (frame,), truth = griddyn_events((cases.DEPTHS["medium"],), seed_noise=0, noise=0.01)
    t = frame.t_s.to_numpy()
    ev = EventRecord(t - t[0], frame.v.to_numpy(), frame.p.to_numpy(), frame.q.to_numpy(),
                     frame.angle_rad.to_numpy(), "griddyn medium sag")  # fmt: skip
    return {"event": ev, "truth": None, "f_hz": cases.F_HZ, "window_s": None}, None


def _events(quick: bool) -> list[tuple[str, dict | None, str | None]]:
    """(name, spec, why skipped) of every event, in the table's order."""
    t_end = 2.0 if quick else 10.0
    out = []
    for fs in (60.0,) if quick else (60.0, 120.0):
        ev, truth = _independent_event(fs, t_end)
        spec = {"event": ev, "truth": truth, "f_hz": 60.0, "window_s": 0.0}
        out.append((f"independent {fs:g}/s, {t_end:g} s", spec, None))
    if not quick:
        out.append(("real record #1, first fault, 4 phasors/cycle", *_real_event()))
        out.append(("GridDyn CMLD, 25% sag, 60/s", *_griddyn_event()))
        out.append(out.pop(1))  # the costliest (120/s) last: a stopped run keeps the rest
    return out


def run_nuts(ev, f_hz, warmup, draws, seed=0):
    """NumPyro NUTS + diffrax (composite_peers.py) on the comparison posterior."""
    from composite_peers import nuts_diffrax
    from loadbayes.fit.composite.nls import nls
    from loadbayes.fit.composite.problem import CompositeProblem, theta_of
    from loadbayes.models.composite_prior import CompositePrior

    prior = CompositePrior.default([ev])
    st = nls(CompositeProblem([ev], prior, f_hz=f_hz, steps=False, window_s=0))
    r = nuts_diffrax(ev, prior, st, f_hz=f_hz, warmup=warmup, draws=draws, seed=seed)
    rng = np.random.default_rng(seed)
    u = r["u"]
    log_t0 = np.array([prior.draw_log_t0(ui, rng) for ui in u.reshape(-1, 5)])
    theta = theta_of(u, log_t0.reshape(u.shape[:2]))
    ess, rhat, worst = _ess_rhat(_named(ev, theta, r["beta"], r["tau"], f_hz))
    keep = ("wall_s", "cpu_s", "warmup_wall_s", "sampling_wall_s", "sampling_cpu_s",
            "compile_s", "grads_per_iteration", "divergences", "accept_prob", "step_size",
            "chain_method")  # fmt: skip
    return {
        "sampler": "numpyro-nuts-diffrax",
        "fs": float(round(1.0 / np.median(np.diff(ev.t)))),
        "n": ev.n,
        "settings": f"2 chains x {draws} (warm-up {warmup}), target acceptance 0.9, "
        "whitened by the NLS Laplace fit",
        **{k: r[k] for k in keep},
        "min_ess_bulk": ess,
        "worst": worst,
        "max_r_hat": rhat,
        "ess_per_s": ess / r["wall_s"],
        "ess_per_s_sampling": ess / r["sampling_wall_s"] if r["sampling_wall_s"] else math.nan,
    }


def _why(lr: dict, peer: dict, ratio: float, goal: float, walls: list[dict],
         tau: float) -> str:  # fmt: skip
    """The measured cause of a missed target, in words from this run's numbers.

    The comparison row is one seed; the defaults rows give the seeds' spread of the
    worst quantity's ESS on the same draws per chain, and the peer its cost per ESS.
    """
    if not math.isfinite(ratio):
        return "not measured"
    if ratio >= goal:
        return ""
    if lr["max_r_hat"] >= 1.01:
        return f"loadbayes did not converge (R-hat {lr['max_r_hat']:.3f})"
    ess = [r["min_ess_bulk"] for r in walls if r["draws_per_chain"] == lr["draws_per_chain"]]
    spread = (f"; at the same {lr['draws_per_chain']:,} draws per chain the defaults rows' "
              f"min ESS over seeds was {min(ess):.0f}-{max(ess):.0f}") if ess else ""  # fmt: skip
    if peer["sampler"].startswith("emcee"):
        cost = f"emcee tau {tau:.0f} steps at {peer['cpu_s'] / peer['steps_done']:.2f} CPU s a step"
    else:
        cost = f"NUTS {peer['grads_per_iteration']:.0f} gradients an iteration"
    return (
        f"loadbayes' comparison run (one seed) stopped at ESS {lr['min_ess_bulk']:.0f} "
        f"({lr['worst']}) after {lr['draws_per_chain']:,} draws per chain in "
        f"{lr['cpu_s']:.1f} CPU s{spread}; {cost}"
    )


def run_event(name: str, spec: dict, quick: bool, seeds: int, nuts: tuple[int, int],
              keep=None, skip_nuts=None):  # fmt: skip
    """Every sampler on one event: rows, and the two targets' lines.

    ``keep(rows)``, when given, is called with the event's rows after each run.
    """
    from loadbayes.models.zip_motor import CompositeModel

    ev, f_hz, truth = spec["event"], spec["f_hz"], spec["truth"]
    bare = _bare(ev)
    rows = []

    def add(r):
        r["event"] = name
        r["part"] = "events"
        rows.append(r)
        print(_line(r), flush=True)
        if keep is not None:
            keep(rows)
        return r

    # Quick runs (the smoke test): a few hundred iterations instead of the defaults.
    draws, burn = (300, 150) if quick else (None, None)
    default = CompositeModel(f_hz=f_hz, window_s=spec["window_s"])
    for s in range(seeds):
        add(run_loadbayes(f_hz, 0, draws, burn, seed=s, event=(ev, truth), model=default))
    same = CompositeModel(f_hz=f_hz, steps=False, window_s=0)
    add(run_loadbayes(f_hz, 0, draws, burn, event=(bare, truth), model=same))
    emcee_s, long_steps = (2.0, 40) if quick else (60.0, 2000)
    skip_em, skip_nu = _missing("emcee"), skip_nuts or _missing("jax", "numpyro", "diffrax")
    if skip_em:
        em = ek = add({"sampler": "emcee", "n": bare.n, "skipped": skip_em})
    else:
        em = add(run_emcee(f_hz, 0, 10**6, seconds=emcee_s, event=(bare, truth), f_hz=f_hz))
        ek = add(run_emcee(f_hz, 0, long_steps, seconds=900.0, motor="kernel",
                           event=(bare, truth), f_hz=f_hz))  # fmt: skip
        _stationary_rate(em, ek)
    if skip_nu:
        add({"sampler": "numpyro-nuts-diffrax", "n": bare.n, "skipped": skip_nu})
    else:
        add(run_nuts(bare, f_hz, *nuts))
    return rows, *summarise(name, rows)


def summarise(name: str, rows: list[dict]) -> tuple[dict, list[dict]]:
    """One event's line of the table and its two targets, from its runs' rows.

    Rates by wall time (the target's) and by CPU seconds (this process's, all threads;
    on a machine whose load changes between the runs, the fairer of the two).
    """
    by = {r["sampler"]: r for r in rows}
    walls = [r for r in rows if r["sampler"] == "loadbayes-defaults"] or [rows[0]]
    lr = next(r for r in rows if r["sampler"].endswith("-ramp"))
    em = by.get("emcee-solve_ivp") or by.get("emcee", {})
    ek = by.get("emcee-kernel", em)
    nu = by["numpyro-nuts-diffrax"]
    w = np.array([r["wall_s"] for r in walls])
    c = np.array([r["cpu_s"] for r in walls])
    nan = math.nan
    summary = {
        "event": name,
        "n": lr["n"],
        "seeds": len(walls),
        "defaults_wall_median_s": float(np.median(w)),
        "defaults_wall_max_s": float(np.max(w)),
        "defaults_cpu_median_s": float(np.median(c)),
        "defaults_converged": sum(
            r["max_r_hat"] < 1.01 and r["min_ess_bulk"] >= 400 for r in walls
        ),  # fmt: skip
        "defaults_ess_per_s_median": float(np.median([r["ess_per_s"] for r in walls])),
        "same_posterior_ess_per_s": lr["ess_per_s"],
        "same_posterior_ess_per_cpu_s": lr["min_ess_bulk"] / lr["cpu_s"],
        "same_posterior_r_hat": lr["max_r_hat"],
        "emcee_ess_per_s": em.get("ess_per_s_from_long_tau", nan),
        "emcee_tau": ek.get("autocorr_time_max", nan),
        "nuts_ess_per_s": nu.get("ess_per_s", nan),
        "nuts_r_hat": nu.get("max_r_hat", nan),
    }
    tau = summary["emcee_tau"]
    summary["emcee_ess_per_cpu_s"] = (
        32.0 / (tau * em["cpu_s"] / em["steps_done"]) if "cpu_s" in em else nan
    )
    summary["nuts_ess_per_cpu_s"] = nu["min_ess_bulk"] / nu["cpu_s"] if "cpu_s" in nu else nan
    for peer, key in (("emcee", "ratio_emcee"), ("nuts", "ratio_nuts")):
        summary[key] = summary["same_posterior_ess_per_s"] / summary[f"{peer}_ess_per_s"]
        summary[key + "_cpu"] = (
            summary["same_posterior_ess_per_cpu_s"] / summary[f"{peer}_ess_per_cpu_s"]
        )
    targets = []
    for peer, key, goal, row in (("NUTS + diffrax", "ratio_nuts", 100, nu),
                                 ("emcee + solve_ivp", "ratio_emcee", 300, em)):  # fmt: skip
        ratio = summary[key]
        if "skipped" in row:
            measured = f"not measured: {row['skipped']}"
        elif row is nu:
            measured = (
                f"{_ratio(ratio)} by wall, {_ratio(summary[key + '_cpu'])} by CPU seconds "
                f"({lr['ess_per_s']:.3g} vs {nu['ess_per_s']:.3g} ESS/s, warm-up charged as "
                f"loadbayes' burn-in is; NUTS R-hat {nu['max_r_hat']:.3f}, ESS "
                f"{nu['min_ess_bulk']:.0f} ({nu['worst']}), {nu['grads_per_iteration']:.0f} "
                f"gradients per iteration, {nu['divergences']} divergences, acceptance "
                f"{nu['accept_prob']:.2f})"
            )
        else:
            measured = (
                f"{_ratio(ratio)} by wall, {_ratio(summary[key + '_cpu'])} by CPU seconds "
                f"({lr['ess_per_s']:.3g} vs {em['ess_per_s_from_long_tau']:.3g} ESS/s: tau "
                f"{ek['autocorr_time_max']:.0f} steps x "
                f"{em['wall_s'] / max(em['steps_done'], 1):.2f} s per step)"
            )
        # Met only where both measures meet it: on a shared machine whose load moves
        # between the runs, wall time can favour either side (CPU seconds, the fairer
        # there, count every thread).
        worst = min(ratio, summary[key + "_cpu"])
        why = "" if "skipped" in row else _why(lr, row, worst, goal, walls, tau)
        targets.append({
            "target": f"{name}: ESS/s >= {goal}x {peer} on the same posterior (by wall "
                      "and by CPU seconds)",
            "measured": measured + (f"; missed: {why}" if why else ""),
            "met": bool(worst >= goal),
        })  # fmt: skip
    summary["met"] = all(t["met"] for t in targets)
    return summary, targets


def _ratio(x: float) -> str:
    if not math.isfinite(x):
        return "n/a"
    return f"{x:.2g}x" if x < 10 else f"{x:,.0f}x"


def run_events_part(args, save) -> tuple[list[dict], list[dict], list[dict]]:
    """Issue 35's benchmark: every event, every sampler, the same posterior.

    ``save(rows, summaries, targets)`` is called after each event (a long run that is
    stopped keeps the events it finished).
    """
    seeds = 1 if args.quick else args.seeds
    nuts = (10, 10) if args.quick else (args.nuts_warmup, args.nuts_draws)
    # Compile the numba kernels (both model readings) outside the timed runs.
    warm = _independent_event(60.0, 2.0)
    run_loadbayes(60.0, 2.0, 100, 50, event=warm)
    run_loadbayes(60.0, 2.0, 100, 50, event=warm, steps=False)
    rows, summaries, targets = [], [], []
    for name, spec, why in _events(args.quick):
        if args.only and not any(k.lower() in name.lower() for k in args.only):
            continue
        if spec is None:
            print(f"{name}: skipped, {why}", flush=True)
            summaries.append({"event": name, "skipped": why})
            continue

        def keep(done, name=name, rows=rows, summaries=summaries, targets=targets):
            # A stopped run keeps the samplers this event finished, said to be unfinished.
            stop = {"event": name, "skipped": "unfinished: stopped before every sampler ran"}
            save(rows + done, summaries + [stop], targets)

        r, s, t = run_event(name, spec, args.quick, seeds, nuts, keep, args.skip_nuts)
        rows, targets = rows + r, targets + t
        summaries.append(s)
        save(rows, summaries, targets)
    return rows, summaries, targets


def _line(r) -> str:
    if "skipped" in r:
        return f"{r['sampler']:16s} skipped: {r['skipped']}"
    return (
        f"{r['sampler']:16s} fs {r['fs']:5g} n {r['n']:6d} wall {r['wall_s']:7.2f} s "
        f"ESS {r['min_ess_bulk']:8.1f} ({r['worst']}) R-hat {r['max_r_hat']:.3f} "
        f"ESS/s {r['ess_per_s']:9.3g}"
    )


def run_library_part(args) -> tuple[list[dict], list[dict]]:
    """The package's own event (small industrial motor): moves, rates, emcee."""
    t_end = 3.0 if args.quick else 10.0
    # The default move at the package's defaults (None: COMPOSITE_DEFAULTS read at run
    # time, its first round and on until converged, as the user gets them; a pinned
    # 16,000 here outlived the defaults' 6,000); factor slice costs ~20 density
    # evaluations per iteration, so fewer of its iterations take about as long.
    from loadbayes.fit.composite.sampler import DEFAULT_MOVE

    sizes = {DEFAULT_MOVE: (None, None), "slice": (2500, 700)}
    if args.quick:
        sizes = {DEFAULT_MOVE: (600, 300), "slice": (150, 60)}
    if not args.slice:
        del sizes["slice"]
    steps = 20 if args.quick else 2000
    # Warm-up: compile the numba kernels (both rates, both moves) outside the timed runs.
    for move in sizes:
        run_loadbayes(60.0, 2.0, 100, 50, move=move)
    rows = []
    for fs in (60.0, 960.0):
        for move, (draws, burn) in sizes.items():
            rows.append(run_loadbayes(fs, t_end, draws, burn, move=move))
            print(_line(rows[-1]), flush=True)
    # emcee's log-posterior reads the sag's step as a ramp (five motor coordinates, no
    # step instants): the ratio is taken against loadbayes on that same posterior.
    rows.append(run_loadbayes(60.0, t_end, *sizes[DEFAULT_MOVE], move=DEFAULT_MOVE, steps=False))
    print(_line(rows[-1]), flush=True)
    rows.append(run_emcee(60.0, t_end, steps, seconds=30.0 if args.quick else 150.0))
    print(_line(rows[-1]), flush=True)
    long_steps = 100 if args.quick else 6000
    rows.append(run_emcee(60.0, t_end, long_steps, seconds=600.0, motor="kernel"))
    print(_line(rows[-1]), flush=True)
    default = [r for r in rows if r.get("move") == DEFAULT_MOVE and r.get("steps")]
    same = [r for r in rows if r.get("steps") is False][0]
    lb, em, ek = same, rows[-2], rows[-1]
    _stationary_rate(em, ek)
    ratio = lb["ess_per_s"] / em["ess_per_s_from_long_tau"]
    targets = []
    for r in default:
        ok = r["max_r_hat"] < 1.01 and r["min_ess_bulk"] >= 400 and r["wall_s"] < 30
        targets.append(
            {
                "target": f"{r['fs']:g}/s, 4 chains: R-hat < 1.01, bulk ESS >= 400 for every "
                f"parameter, < 30 s wall (default move, {r['move']})",
                "measured": f"R-hat max {r['max_r_hat']:.3f}, min ESS {r['min_ess_bulk']:.0f} "
                f"({r['worst']}), {r['wall_s']:.1f} s",
                "met": bool(ok),
            }
        )
    targets.append(
        {
            "target": "ESS/s >= 100x emcee (32 walkers, solve_ivp inside), same run, on the "
            "same log-posterior (the step read as a ramp: loadbayes with steps=False)",
            "measured": f"{ratio:,.0f}x ({lb['ess_per_s']:.3g} vs "
            f"{em['ess_per_s_from_long_tau']:.3g} ESS/s = 32 walkers / (tau "
            f"{ek['autocorr_time_max']:.0f} steps, from {ek['steps_done']} steps with the "
            f"kernel, x {em['wall_s'] / em['steps_done']:.2f} s per step with solve_ivp); "
            f"by the short run's ArviZ ESS {lb['ess_per_s'] / em['ess_per_s']:,.0f}x (emcee "
            f"{em['steps_done']} steps per walker in {em['wall_s']:.0f} s, R-hat "
            f"{em['max_r_hat']:.3g}))",
            "met": bool(ratio >= 100),
        }
    )
    for r in rows:
        r["part"] = "library"
    return rows, targets


def _missing(*modules: str) -> str | None:
    """Why a peer cannot run here (its modules not installed), or None."""
    gone = [m for m in modules if importlib.util.find_spec(m) is None]
    if gone:
        return f"{', '.join(gone)} not installed (the bench extra: make .venv-bench/.installed)"
    return None


def _peer_versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in ("emcee", "jax", "numpyro", "diffrax"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


NOTES = [
    "The comparison posterior (rows *-ramp, emcee-*, numpyro-*): the event's t, V, P, Q "
    "alone (no angle), point samples, the voltage read as the line between samples (the "
    "sag's edges as ramps), T0 = 1 (the likelihood does not depend on it; log T0 is drawn "
    "from its prior given u afterwards, as the package does), the package's default prior. "
    "loadbayes samples it with its default sampler (fit_composite, "
    "CompositeModel(steps=False, window_s=0), COMPOSITE_DEFAULTS read at run time, until "
    "converged); the ratios are of that row's ESS/s to the peers'.",
    "loadbayes-defaults rows: the user's default fit of the event as recorded (steps at "
    "unknown instants; phasor rows as one-cycle window means; the recorded angle), seeds "
    "0-4; the events table gives their median and maximum wall time and median CPU "
    "seconds. Wall time from the call of fit_composite (NLS start included) to its return "
    "(naming, diagnostics and the baseline included), after a warm-up fit that compiled "
    "the numba kernels. CPU seconds: this process's, all threads.",
    "emcee's ESS/s: 32 walkers / (tau x seconds per step), tau = emcee's integrated "
    "autocorrelation time (max over the 14 coordinates) from the emcee-kernel row (the "
    "same posterior with the compiled kernel inside, 2,000 steps, the first half "
    "discarded), seconds per step from the emcee-solve_ivp row (60 s of steps). Its burn-in "
    "is not charged and a tau from ~1,000 kept steps is if anything too small: emcee's "
    "rate leans high, the ratio low.",
    "NUTS: benchmarks/composite_peers.py, NumPyro NUTS (target acceptance 0.9, tree depth "
    "<= 10, diagonal mass matrix adapted) on the 14 coordinates whitened by the Laplace "
    "approximation of the package's NLS fit (its estimate and covariance), 2 chains x "
    "(1,000 warm-up + the kept draws), in parallel on two JAX CPU devices; the ODE by "
    "diffrax Tsit5 (PID rtol 1e-6, atol 1e-9, a step on every sample, float64), its "
    "gradient by forward mode (5 tangents; reverse mode cost 4x more). Times exclude "
    "JAX's compilation (compile_s, measured by a one-iteration run). Its ESS/s charges "
    "its warm-up, as loadbayes' charges its NLS and burn-in. (warmup_wall_s and "
    "sampling_wall_s split it; in runs before the warm-up was waited for, JAX's "
    "asynchronous dispatch put nearly all of it in sampling_wall_s.)",
    "Ratios by wall time (the target's) and by CPU seconds (this process's, all threads: "
    "loadbayes' 4 chains, NUTS's 2 devices, emcee's one thread); the load moved between "
    "the runs of one event, so the CPU ratio is the steadier.",
    "ESS: ArviZ bulk ESS, the minimum over every reported parameter (constants left out); "
    "R-hat: ArviZ's rank-normalised split R-hat, the maximum.",
    "The machine is shared (2 cores, other agents' work running): the load average is "
    "given at start and end; ratios within this run are what counts.",
]


def merge(paths: list[str], output: str) -> None:
    """One table from runs of ``--only`` events made side by side: each event's rows and
    targets as its run wrote them, the run's machine and load kept beside the event."""
    runs = [json.loads(Path(q).read_text()) for q in paths]
    out = {k: v for k, v in runs[0].items() if k not in ("events", "results", "targets")}
    out["runs"] = []
    out["events"], out["results"], out["targets"] = [], [], []
    seen: set[str] = set()
    for i, run in enumerate(runs):
        m = run["machine"]
        out["runs"].append({"date": run["date"], "machine": m})
        names = [e["event"] for e in run["events"] if e["event"] not in seen]
        load = [m["load_average_at_start"][0], m["load_average_at_end"][0]]
        for e in run["events"]:
            if e["event"] not in names:
                continue
            rows = [r for r in run["results"] if r.get("event") == e["event"]]
            out["results"] += rows
            if "skipped" in e:
                out["events"].append(e)
                continue
            # The line and targets recomputed from the rows (the CPU rates included).
            summary, targets = summarise(e["event"], rows)
            out["events"].append({**summary, "run": i, "load_1min_start_end": load})
            out["targets"] += targets
        seen |= set(names)
    out["notes"] = list(runs[0]["notes"]) + [
        f"Merged from {len(runs)} runs made at the same time on the same machine (each "
        "event's samplers in one of them, back to back): every event's ratios are within "
        "its run; its run's 1-minute load average at start and end is beside it."
    ]
    Path(output).write_text(json.dumps(out, indent=2) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="Smoke sizes (seconds).")
    ap.add_argument("--output", default=str(Path(__file__).parent / "results" / "composite.json"))
    ap.add_argument("--part", choices=("events", "library"), default="events",
                    help="events: issue 35's table (default); library: the moves on the "
                    "package's own event.")  # fmt: skip
    ap.add_argument("--slice", action="store_true", help="library: also the factor slice move.")
    ap.add_argument("--seeds", type=int, default=5, help="loadbayes defaults: seeds 0..N-1.")
    ap.add_argument("--nuts-warmup", type=int, default=1000)
    ap.add_argument("--nuts-draws", type=int, default=1000)
    ap.add_argument("--only", nargs="*", default=None,
                    help="Events whose name contains one of these words (independent, 120, "
                    "real, griddyn).")  # fmt: skip
    ap.add_argument(
        "--skip-nuts",
        default=None,
        metavar="REASON",
        help="Do not run NUTS; its row says REASON (e.g. what a timebox left undone).",
    )
    ap.add_argument(
        "--merge",
        nargs="+",
        default=None,
        metavar="JSON",
        help="Run nothing: merge these results (of --only runs) into --output.",
    )
    args = ap.parse_args(argv)
    if args.merge:
        merge(args.merge, args.output)
        return 0
    # NUTS's two chains in parallel, one JAX CPU device each (set before JAX is imported).
    flag = "--xla_force_host_platform_device_count=2"
    if flag not in os.environ.get("XLA_FLAGS", ""):
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + flag).strip()
    sys.path.insert(0, str(Path(__file__).resolve().parent))  # composite_peers
    load = os.getloadavg()
    t_run = time.perf_counter()

    def save(rows, summaries, targets):
        import numba
        import scipy

        out = {
            "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "quick": bool(args.quick),
            "part": args.part,
            "machine": {
                "cpu": platform.processor() or platform.machine(),
                "cpu_count": os.cpu_count(),
                "cpus_usable": len(os.sched_getaffinity(0)),
                "platform": platform.platform(),
                "python": platform.python_version(),
                "load_average_at_start": list(load),
                "load_average_at_end": list(os.getloadavg()),
                "run_s": time.perf_counter() - t_run,
            },
            "versions": {
                "numpy": np.__version__,
                "scipy": scipy.__version__,
                "numba": numba.__version__,
                **_peer_versions(),
            },
            "events": summaries,
            "results": [
                {k: (json.dumps(v) if isinstance(v, dict) else v) for k, v in r.items()}
                for r in rows
            ],
            "targets": targets,
            "notes": NOTES if args.part == "events" else [],
        }
        Path(args.output).parent.mkdir(parents=True, exist_ok=True)
        Path(args.output).write_text(json.dumps(out, indent=2) + "\n")

    summaries = []
    if args.part == "library":
        rows, targets = run_library_part(args)
    else:
        rows, summaries, targets = run_events_part(args, save)
    save(rows, summaries, targets)
    for t in targets:
        print(("met     " if t["met"] else "NOT MET ") + t["target"] + ": " + t["measured"])
    for s_ in summaries:
        print(s_)
    return 0


if __name__ == "__main__":
    sys.exit(main())
