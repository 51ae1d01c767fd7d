"""The composite's vocabulary: every named draw's unit and meaning, and the table's rows.

The names themselves are the fit's contract (:mod:`loadbayes.fit.composite.naming`
builds the draws); what they mean is said here, once, for the CLI table
(:mod:`loadbayes.report.composite_table`), the report (:mod:`loadbayes.report.composite`)
and the figures (:mod:`loadbayes.plots.fit`, :mod:`loadbayes.plots.composite`). It
imports nothing of the package, so any of them may take it at no cost.
"""

from __future__ import annotations

import re

__all__ = ["QUANTITIES", "TABLE_NAMES", "VOCABULARY", "describe"]

_PU_SYS, _PU_MOTOR = "p.u. system base", "p.u. motor base"
#: Every named draw's unit and meaning in words: the one place the CLI table, the report
#: and the figures take them from (an event's suffix ``_e{k}`` and each step's number are
#: added by :func:`describe`). "Motor base" is the motor's own rating (``mva_m``), whose
#: size comes from the prior of T0 (terminal data fix only their product).
QUANTITIES: dict[str, tuple[str, str]] = {
    "p0": (_PU_SYS, "load P at v0"),
    "q0": (_PU_SYS, "load Q at v0"),
    "v0": ("p.u.", "voltage at the first sample"),
    "f_m": ("-", "motor's share of p0"),
    "a1": ("-", "static P: constant-impedance share"),
    "a2": ("-", "static P: constant-current share"),
    "a3": ("-", "static P: constant-power share"),
    "a4": ("-", "static Q: constant-impedance share"),
    "a5": ("-", "static Q: constant-current share"),
    "a6": ("-", "static Q: constant-power share"),
    "mva_m": (_PU_SYS, "motor rating (MVA)"),
    "q_c": (_PU_SYS, "shunt Q (motor Q0)"),
    "rs": (_PU_MOTOR, "stator resistance Rs"),
    "xs": (_PU_MOTOR, "stator leakage reactance Xs (= Xr)"),
    "xm": (_PU_MOTOR, "magnetising reactance Xm"),
    "rr": (_PU_MOTOR, "rotor resistance Rr"),
    "xr": (_PU_MOTOR, "rotor leakage reactance Xr"),
    "h_s": ("s, motor base", "inertia constant H"),
    "a": ("-", "load torque share A (of A w^2 + B w + C)"),
    "b": ("-", "load torque share B (of A w^2 + B w + C)"),
    "c": ("-", "load torque share C (of A w^2 + B w + C)"),
    "t0": (_PU_MOTOR, "initial load torque T0"),
    "x_prime": (_PU_MOTOR, "transient reactance X'"),
    "x_open": (_PU_MOTOR, "open-circuit X"),
    "t_prime_s": ("s", "transient time constant T'"),
    "f_hz": ("Hz", "nominal frequency (the motor's time base)"),
    "tau_p": ("1/(p.u.)^2", "noise precision of P"),
    "tau_q": ("1/(p.u.)^2", "noise precision of Q"),
    "nu_p": ("-", "Student-t degrees of freedom of P's noise"),
    "nu_q": ("-", "Student-t degrees of freedom of Q's noise"),
    "log_rs": ("log p.u.", "log Rs (sampled)"),
    "log_x_prime": ("log p.u.", "log X' (sampled)"),
    "log_dx": ("log p.u.", "log (X - X') (sampled)"),
    "log_t_prime": ("log s", "log T' (sampled)"),
    "log_h": ("log s", "log H (sampled)"),
    "log_t0": ("log p.u.", "log T0 (sampled)"),
    "log_a_over_c": ("-", "log(A/C), torque (sampled)"),
    "log_b_over_c": ("-", "log(B/C), torque (sampled)"),
    "t_step": ("s", "instant of voltage step {j} (event clock)"),
}
#: The rows of the CLI table, per event (an event's own suffix added), then the motor's.
TABLE_NAMES = (
    ("p0", "q0", "f_m", "a1", "a2", "a3", "a4", "a5", "a6"),
    ("rs", "x_prime", "x_open", "t_prime_s", "h_s", "t0", "mva_m", "q_c"),
)
#: Each dynamic model's vocabulary, by the model's name (``Posterior.model``):
#: :func:`describe` reads it. The composite's alone for now.
VOCABULARY: dict[str, dict[str, tuple[str, str]]] = {"composite": QUANTITIES}
_SUFFIXED = re.compile(r"^(?P<base>.+?)(?P<j>\d*)_e(?P<k>\d+)$")


def describe(name: str, model: str = "composite") -> tuple[str, str]:
    """The unit and the meaning in words of a named draw (``("", "")`` when unknown).

    Event ``k``'s names (suffix ``_e{k}``) say "event k+1"; the steps' instants
    ``t_step{j}`` their number. ``model`` picks the vocabulary (:data:`VOCABULARY`).

    Examples
    --------
    >>> describe("t_prime_s")
    ('s', "transient time constant T'")
    >>> describe("f_m_e1")
    ('-', "motor's share of p0, event 2")
    """
    quantities = VOCABULARY[model]
    event = ""
    m = _SUFFIXED.match(name)
    if m and (m["base"] + m["j"]) in quantities or (m and m["base"] == "t_step"):
        name, event = m["base"] + m["j"], f", event {int(m['k']) + 1}"
    if name.startswith("t_step") and name[6:].isdigit():
        unit, words = quantities["t_step"]
        return unit, words.format(j=int(name[6:]) + 1) + event
    if name not in quantities:
        return "", ""
    unit, words = quantities[name]
    return unit, words + event
