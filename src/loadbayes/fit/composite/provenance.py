"""What a composite fit records about how it was run: the settings of its JSON outputs.

:func:`problem_settings` describes the events, the model's choices and the prior (shared
by the posterior and the NLS baseline), :func:`sampler_record` how the chains ran and
:func:`baseline_record` what the NLS start found. The keys and their order are the JSON's.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.nls import NLSResult
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.sampler import ChainResult
from loadbayes.models.composite_steps import RAMP_MAX_S

__all__ = [
    "METHOD",
    "MOVE_NAME",
    "baseline_record",
    "problem_settings",
    "sampler_record",
    "samples_record",
]

#: The posterior's ``method`` for each u-move (``-student-t`` appended with that noise).
METHOD = {
    "am": "mwg-adaptive-metropolis",
    "shear": "mwg-sheared-adaptive-metropolis",
    "slice": "mwg-factor-slice",
}
#: The u-move in words, for the ``scheme`` setting.
MOVE_NAME = {
    "am": "adaptive Metropolis with t jumps after burn-in",
    "shear": "adaptive Metropolis in coordinates straightening the main bend (from burn-in), "
    "with t jumps after burn-in",
    "slice": "factor slice sampling",
}


def problem_settings(
    problem: CompositeProblem,
    torque: tuple[float, float, float] | str,
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The events, the frequency, the torque, the prior, the steps and the model's choices.

    ``torque`` is as the caller gave it (``(A, B, C)`` or ``"estimate"``); ``extra`` is
    appended (the caller's own provenance, such as the files read).
    """
    events = problem.recorded
    estimate = isinstance(torque, str)
    grid = problem.grid
    fs = problem.fit_samples

    # The edges with samples inside: those left out (a phasor window straddling the
    # change) and those read as a ramp through kept inside samples (point samples; a
    # phasor ramp's samples whose window lies on it).
    def edges_where(test) -> list[dict[str, int]]:
        out = []
        for e, (runs, keep) in enumerate(zip(fs.edges, fs.keep, strict=True)):
            for k0, k1 in runs:
                kept = np.isin(np.arange(k0 + 1, k1), keep)
                if kept.size and test(kept):
                    out.append({"event": e, "from_k": int(k0), "to_k": int(k1)})
        return out

    left_edges = edges_where(lambda kept: not kept.all())
    ramp_edges = edges_where(lambda kept: kept.any())
    return {
        "n": int(sum(e.n for e in problem.events)),
        "events": [
            {
                "name": e.name,
                "n": e.n,
                "n_fitted": int(fs.keep[i].size),
                "t_span_s": float(e.t[-1] - e.t[0]),
                "v0": e.v0,
                "angle_from": e.angle_from or None,
            }
            for i, e in enumerate(events)
        ],
        "f_hz": problem.f_hz,
        # The bases of the data (None: per unit); the command gives them in ``extra``.
        "v_base_kv": None,
        "s_base_mva": None,
        "torque": "estimate" if estimate else list(torque),
        "torque_prior": "Dirichlet(1, 1, 1) on (a, b, c), sampled in log(a/c), log(b/c)"
        if estimate
        else None,
        "prior": problem.prior.to_dict(),
        "h_max_s": problem.h_max,
        "steps": {
            "modelled": bool(problem.steps),
            "intervals": [
                {"event": int(e), "k": int(fs.keep[e][k]), "t_s": float(t), "dt_s": float(w)}
                for e, k, t, w in zip(grid.event_of, grid.k_of, grid.left, grid.width, strict=True)
            ],
            "window_s": problem.window_s if problem.window_s is not None else 1.0 / problem.f_hz,
            "left_out": {
                "rule": "the samples inside a fault's edge (a run of intervals moving the "
                "same way, no longer than the phasor window allows) are left out of the "
                "likelihood; the edge is a step at an unknown instant between its ends. "
                "A longer edge (a ramp the phasors resolve, up to "
                f"{RAMP_MAX_S:g} s plus the window) keeps the inside samples whose window "
                "lies wholly on the ramp and leaves out the others",
                "count": fs.left_out,
                "samples": left_edges,
            },
            "ramps": {
                "rule": "point samples (window 0), or a phasor ramp's samples whose window "
                "lies on it: an edge of up to "
                f"{RAMP_MAX_S:g} s with samples inside it is a straight ramp through them "
                "(kept in the likelihood); with one inside, from an unknown instant in its "
                "first interval (its t_step; no earlier than where the line would reach "
                "the level after only at the next sample, 'intervals' t_s) to where that "
                "line reaches the level after; "
                "with more, between where their least-squares line reaches the levels "
                "before and after (fixed)",
                "count": fs.ramps,
                "samples": ramp_edges,
            },
        },
        "samples": samples_record(problem.window),
        "shunt": "q_c = mva_m * q_m(0): the motor's initial Q compensated at v0",
        "closure": "xs = xr",
        **(extra or {}),
    }


def samples_record(window_s: float) -> dict[str, Any]:
    """How the fit read each sample: a window mean centred on its stamp, or a point value."""
    if window_s > 0:
        text = (
            f"samples read as {window_s:.6g}-s window means centred on the stamp (the "
            "motor's P and Q averaged over [t - W/2, t + W/2], as a phasor estimator "
            "gives them)"
        )
    else:
        text = "point samples (the motor's P and Q at the sample instants)"
    return {"window_s": float(window_s), "read_as": text}


def sampler_record(
    sampler: SamplerSettings,
    move: str,
    res: list[ChainResult],
    seconds: dict[str, float],
    likelihood: str,
) -> dict[str, Any]:
    """How the chains ran: iterations, seed, scheme, acceptance, evaluations, timings.

    The wall times are the only entries that differ between two runs of the same seed:
    they are kept under the one key ``timing_s`` so that two runs' JSON compare equal
    once it is left out.
    """
    return {
        "draws": sampler.draws,
        "burn": sampler.burn,
        "thin": sampler.thin,
        "seed": sampler.seed,
        "scheme": f"metropolis-within-gibbs ({MOVE_NAME[move]} on theta, beta "
        "integrated out; beta and tau exact)",
        "move": move,
        "acceptance": [r.acceptance for r in res],
        "evaluations_per_iteration": [r.evaluations_per_iteration for r in res],
        "jump_acceptance": [r.jump_acceptance for r in res],
        "timing_s": seconds,
        "likelihood": likelihood,
    }


def baseline_record(problem: CompositeProblem, start: NLSResult) -> dict[str, Any]:
    """What the NLS start found: its cost, residual sds and estimates (wall time: timing_s)."""
    return {
        "timing_s": {"nls": start.seconds},
        "nls_nfev": start.nfev,
        "residual_sd": start.sigma.tolist(),
        "estimate_u": dict(zip(problem.free_coordinates, start.u.tolist(), strict=False)),
        "estimate_step_fraction": problem.phi(start.u).tolist(),
    }
