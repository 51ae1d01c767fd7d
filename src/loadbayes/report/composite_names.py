"""The composite's vocabulary: every named draw's unit and meaning, and the table's rows.

The names themselves are the fit's contract (:mod:`loadbayes.fit.composite.naming`
builds the draws); what they mean is the model's (``CompositeModel.quantities``, read
here) and is looked up here, once, for the CLI table
(:mod:`loadbayes.report.composite_table`), the report (:mod:`loadbayes.report.composite`)
and the figures (:mod:`loadbayes.plots.fit`, :mod:`loadbayes.plots.composite`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from loadbayes.models.zip_motor import CompositeModel

__all__ = ["QUANTITIES", "TABLE_NAMES", "VOCABULARY", "describe"]

#: Every named draw's unit and meaning in words, as the model says them
#: (:attr:`loadbayes.models.zip_motor.CompositeModel.quantities`): the one place the CLI
#: table, the report and the figures take them from (an event's suffix ``_e{k}`` and each
#: step's number are added by :func:`describe`).
QUANTITIES: Mapping[str, tuple[str, str]] = CompositeModel.quantities
#: The rows of the CLI table, per event (an event's own suffix added), then the motor's.
TABLE_NAMES = (
    ("p0", "q0", "f_m", "a1", "a2", "a3", "a4", "a5", "a6"),
    ("rs", "x_prime", "x_open", "t_prime_s", "h_s", "t0", "mva_m", "q_c"),
)
#: Each dynamic model's vocabulary, by the model's name (``Posterior.model``):
#: :func:`describe` reads it. The composite's alone for now.
VOCABULARY: dict[str, Mapping[str, tuple[str, str]]] = {"composite": QUANTITIES}
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
