"""What an export checks in the fit it exports, before writing: each problem one sentence.

``loadbayes export`` says every problem found here on stderr (``loadbayes: warning:``) and
as a comment in every file it writes (:func:`comment_lines`); a clean, converged,
physical fit adds nothing. Four kinds:

(a) **unconverged**: R-hat above :data:`RHAT_MAX` or bulk ESS below :data:`ESS_MIN` on
    a quantity the writers use (:data:`EXPORTED`), read from the fit's JSON summary or
    computed from the NetCDF's chains;
(b) **non-physical static part** (:attr:`Problem.unphysical`): a share ``a1 .. a6`` of the
    static part outside [0, 1] (so at least one negative), a static part drawing negative
    P (or, for the composite load, negative Q: its shunt holds the compensation). The
    export refuses these unless ``--force-unphysical`` (``f_m`` outside (0, 1] it
    refuses always: :func:`~loadbayes.export.loadparts.load_parts`);
(c) **motor data outside published ranges** (:data:`MOTOR_RANGES`), and a shunt that
    supplies more Q than the motor it compensates draws at v0;
(d) **a share at its prior's bound**: with ``--shares bounded``, a share whose interval
    reaches 0 or 1 (within :data:`BOUND_TOL`): the data push it past the bound, and the
    value exported is the prior's edge, not a measurement.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = [
    "BOUND_TOL",
    "ESS_MIN",
    "EXPORTED",
    "MOTOR_RANGES",
    "RHAT_MAX",
    "Problem",
    "comment_lines",
    "fit_problems",
    "parts_problems",
    "value_problems",
]

#: Convergence wanted of every exported quantity (Vehtari et al. 2021, "Rank-normalization,
#: folding, and localization: an improved R-hat", Bayesian Analysis 16(2): R-hat < 1.01
#: and a bulk ESS of at least 100 per chain, 400 for four chains).
RHAT_MAX = 1.01
ESS_MIN = 400.0
#: The parameters the writers read (the others are in the summary only).
EXPORTED = ("p0", "q0", "v0", "a1", "a2", "a3", "a4", "a5", "a6", "np", "nq", "f_m", "rs",
            "xs", "xm", "rr", "xr", "h_s", "t0", "a", "b", "c", "q_c",
            # a model of parts' (slm, cmld-lite): names no other fit has
            "x_fd", "r_fd", "f_d", "f_el", "f_s",
            *(k + t for t in ("_a", "_b") for k in ("f_m", "rs", "x_open", "x_prime",
                                                    "t_prime_s", "h_s", "t0")))  # fmt: skip
_SHARES = ("a1", "a2", "a3", "a4", "a5", "a6", "f_m")
#: How close an interval's end may come to 0 or 1 before the share is "at its bound"
#: (it prints as 0.000 or 1.000).
BOUND_TOL = 1e-3

#: Published ranges of an aggregate induction motor's data, on its own base (p.u.; H in
#: s). Sources: the typical motor A, B and C data of the WECC composite load model
#: specification (WECC Modeling and Validation Work Group, "WECC Composite Load Model
#: (CMPLDW) Specifications", 2015; the same defaults as PSS/E's CMLDBLU2 in the Load
#: Model Data Tool: Rs 0.03-0.04, Ls = Xs + Xm 1.8, Lp = Xs + Xm Xr/(Xm + Xr) 0.12-0.19,
#: H 0.05-1 s) and the aggregate motor classes of the IEEE Task Force on Load
#: Representation, "Standard load models for power flow and dynamic performance
#: simulation", IEEE Trans. Power Systems 10(3), 1995 (Xs 0.07-0.15, Xm 1.8-4, Rr
#: 0.007-0.06, Xr 0.06-0.18, H 0.1-1.5 s). Each range is widened about twofold either way,
#: so that a value outside is not a different motor class but not a motor. The
#: documentation corpus searched for "WECC composite load model CMLD motor parameters
#: default" gave only IEC 61970's LoadMotor (CIM), whose description is the source of the
#: shunt check: the shunt brings the motor's reactive demand down to the load's, never
#: past it.
MOTOR_RANGES: dict[str, tuple[float, float, str]] = {
    "rs": (0.001, 0.1, "stator resistance Rs (p.u.)"),
    "xs": (0.02, 0.3, "stator leakage reactance Xs (p.u.)"),
    "xm": (1.0, 8.0, "magnetising reactance Xm (p.u.)"),
    "rr": (0.002, 0.12, "rotor resistance Rr (p.u.)"),
    "xr": (0.02, 0.36, "rotor leakage reactance Xr (p.u.)"),
    "h_s": (0.05, 2.0, "inertia H (s)"),
}


@dataclass(frozen=True)
class Problem:
    """One problem of an exported parameter set: a sentence, and whether it is unphysical."""

    text: str
    unphysical: bool = False


def _number(x: Any) -> float | None:
    if isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x):
        return float(x)
    return None


def fit_problems(summary: Mapping[str, Mapping[str, Any]], settings: Mapping[str, Any],
                 interval: str) -> list[Problem]:  # fmt: skip
    """Problems of the fit as a whole: (a) convergence, (d) shares at their bound.

    Parameters
    ----------
    summary : mapping
        Per-parameter rows (``r_hat``, ``ess_bulk``, ``hdi_low``, ``hdi_high``; a row
        without them is not checked).
    settings : mapping
        The fit's settings (``coefficient_prior.shares`` says a bounded fit).
    interval : str
        What the interval is, for the message.

    Returns
    -------
    list of Problem
    """
    out = []
    rhat = {n: v for n in EXPORTED if n in summary
            if (v := _number(summary[n].get("r_hat"))) is not None and v > RHAT_MAX}  # fmt: skip
    ess = {n: v for n in EXPORTED if n in summary
           if (v := _number(summary[n].get("ess_bulk"))) is not None and v < ESS_MIN}  # fmt: skip
    if rhat or ess:
        worst = [f"R-hat {v:.3f} ({n})" for n, v in sorted(rhat.items(), key=lambda kv: -kv[1])]
        worst += [f"bulk ESS {v:.0f} ({n})" for n, v in sorted(ess.items(), key=lambda kv: kv[1])]
        more = f" and {len(worst) - 4} more" if len(worst) > 4 else ""
        out.append(Problem(
            f"the fit has not converged on the exported quantities: {', '.join(worst[:4])}"
            f"{more} (wanted R-hat <= {RHAT_MAX} and bulk ESS >= {ESS_MIN:.0f}): its numbers "
            "may change with a longer run (more --draws)"
        ))  # fmt: skip
    prior = settings.get("coefficient_prior")
    if isinstance(prior, Mapping) and prior.get("shares") == "bounded":
        for n in _SHARES:
            row = summary.get(n) or {}
            lo, hi = _number(row.get("hdi_low")), _number(row.get("hdi_high"))
            if lo is None or hi is None:
                continue
            for bound, end in ((0.0, lo), (1.0, hi)):
                if abs(end - bound) <= BOUND_TOL:
                    mean = _number(row.get("mean"))
                    shown = "" if mean is None else f"{mean:.3f} "
                    out.append(Problem(
                        f"{n} {shown}[{lo:.3f}, {hi:.3f}] ({interval}) is at its bound "
                        f"{bound:g} (--shares bounded): the data push it past [0, 1], so "
                        "its value is the prior's edge, not a measurement"
                    ))  # fmt: skip
    return out


def value_problems(values: Mapping[str, float], parts: Any, model: str) -> list[Problem]:
    """Problems of one exported parameter set: (b) non-physical, (c) outside ranges.

    Parameters
    ----------
    values : mapping
        The parameter set.
    parts : loadbayes.export.loadparts.LoadParts or None
        Its parts (None when they cannot be built: the writer says why).
    model : str
        The model (an exponential load has no shares to check).

    Returns
    -------
    list of Problem
    """
    out: list[Problem] = []
    if model != "exponential":
        # f_m outside (0, 1] is refused by load_parts itself: no simulator holds it.
        bad = [f"{n} = {values[n]:.4g}" for n in _SHARES[:6]
               if n in values and not 0.0 <= values[n] <= 1.0]  # fmt: skip
        if parts is not None and "a3" not in values:
            bad += [f"a3 = {parts.shares_p[2]:.4g}"] if not 0 <= parts.shares_p[2] <= 1 else []
        if parts is not None and "a6" not in values and "a4" in values:
            bad += [f"a6 = {parts.shares_q[2]:.4g}"] if not 0 <= parts.shares_q[2] <= 1 else []
        if bad:
            out.append(Problem(
                f"shares outside [0, 1]: {', '.join(bad)}: the static part is not a physical "
                "load (refit with --shares bounded, or export another --stat)", unphysical=True,
            ))  # fmt: skip
    if parts is not None and parts.motor is not None:
        if parts.p_static < 0 or parts.q_static < 0:
            out.append(Problem(
                f"the static part draws {parts.p_static:.4g} MW, {parts.q_static:.4g} Mvar at "
                "v0: a negative static load is not physical", unphysical=True,
            ))  # fmt: skip
        for n, (lo, hi, what) in MOTOR_RANGES.items():
            v = _number(values.get(n))
            if v is not None and not lo <= v <= hi:
                out.append(Problem(
                    f"motor {what} = {v:.4g} is outside the published range [{lo:g}, {hi:g}] "
                    "(WECC composite load model; IEEE load task force 1995)"
                ))  # fmt: skip
        q_m = parts.motor.q_mvar
        # 1% above: the composite model's own shunt is the motor's Q exactly.
        if parts.q_c > 0 and parts.q_c > 1.01 * q_m:
            out.append(Problem(
                f"the shunt supplies {parts.q_c:.4g} Mvar at v0, more than the {q_m:.4g} "
                "Mvar of the motor it compensates: it compensates more than the load's Q "
                "(IEC 61970 LoadMotor: the shunt brings the motor's demand down, never past it)"
            ))  # fmt: skip
    return out


def parts_problems(values: Mapping[str, float], model_options: Mapping[str, Any]) -> list[Problem]:
    """A model of parts' motors outside the published ranges (:data:`MOTOR_RANGES`), each.

    Its shares are on their simplex by construction (the writer refuses any that are
    not); its motors are named ``rs_a .. h_s_b`` (``cmld-lite``) or ``rs .. h_s`` (``slm``).
    """
    motors = list(model_options.get("motors") or [])
    tags = [""] if len(motors) == 1 else [f"_{m}" for m in motors]
    out = []
    for m, t in zip(motors, tags, strict=True):
        who = f"motor {m.upper()}" if t else "motor"
        for n, (lo, hi, what) in MOTOR_RANGES.items():
            v = _number(values.get(n + t))
            if v is not None and not lo <= v <= hi:
                out.append(Problem(
                    f"{who} {what} = {v:.4g} is outside the published range [{lo:g}, {hi:g}] "
                    "(WECC composite load model; IEEE load task force 1995)"
                ))  # fmt: skip
    return out


def comment_lines(problems: list[str], prefix: str) -> list[str]:
    """One comment line per problem: ``<prefix> loadbayes warning: <problem>``."""
    return [f"{prefix} loadbayes warning: {p}" for p in problems]
