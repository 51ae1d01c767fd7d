"""How a unit problem is said: the fix in the caller's words, and one error for the first.

The unit checks of :mod:`loadbayes.measurements.units` find what looks wrong; this module
says it. A fix names an option as the user types it, ``--v-base 13.8`` on the command
line or ``v_base=13.8`` from Python (:data:`Wording`, :func:`option`, :func:`accept`,
:func:`suggest_v_base`); a :class:`UnitProblem` holds what was seen and that fix, and
:func:`refuse` turns the first problem into one :class:`~loadbayes.io.errors.DataError`
naming the user's column.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from loadbayes.io.errors import DataError

__all__ = [
    "ACCEPT",
    "ACCEPT_PY",
    "UnitProblem",
    "Wording",
    "accept",
    "option",
    "refuse",
    "suggest_v_base",
]

#: The option that accepts unusual data.
ACCEPT = "--accept-units"
#: Whose names the fixes give: the command line's options or Python's keywords.
Wording = Literal["cli", "python"]
#: The keyword that accepts unusual data, from Python.
ACCEPT_PY = "accept_units=True"


def option(name: str, value: object = None, *, wording: Wording = "cli") -> str:
    """An option as the user types it: ``--v-base 13.8`` (CLI) or ``v_base=13.8`` (Python).

    ``name`` is the CLI spelling without the dashes (``"v-base"``); a ``value`` of
    None gives the bare option (``--s-base``, ``s_base=...``).
    """
    if wording == "cli":
        return f"--{name}" + ("" if value is None else f" {value}")
    key = name.replace("-", "_")
    if value is None:
        return f"{key}=..."
    try:
        float(str(value))
    except ValueError:
        return f"{key}={str(value)!r}"
    return f"{key}={value}"


def accept(wording: Wording = "cli") -> str:
    """The option that fits unusual data anyway, in the caller's wording."""
    return ACCEPT if wording == "cli" else ACCEPT_PY


# Common nominal voltages (kV and V) offered as the --v-base a median is close to.
_STANDARD_V = (
    0.12, 0.208, 0.22, 0.23, 0.24, 0.4, 0.415, 0.48, 0.6, 2.4, 3.3, 4.16, 6.6, 10, 11,
    12.47, 12.66, 13.2, 13.8, 20, 22, 24.9, 33, 34.5, 66, 69, 110, 115, 132, 138, 220,
    230, 345, 380, 400, 500, 765, 120, 208, 240, 415, 480, 690,
)  # fmt: skip


@dataclass(frozen=True)
class UnitProblem:
    """What looks wrong with one column, and which option fixes it.

    Attributes
    ----------
    column : str
        ``"v"``, ``"p"`` or ``"q"`` (or a motor column).
    seen : str
        What the data show, in numbers.
    fix : str
        The option(s) that fix it.
    """

    column: str
    seen: str
    fix: str
    wording: Wording = "cli"

    def __str__(self) -> str:
        return f"{self.seen}; {self.fix} (or {accept(self.wording)} if the data are right)"


def suggest_v_base(raw_median: float, wording: Wording = "cli") -> str:
    """``--v-base X`` for the data's median V: a standard voltage when one is close."""
    near = min(_STANDARD_V, key=lambda s: abs(np.log(raw_median / s)))
    if abs(raw_median / near - 1) < 0.08:
        return option("v-base", f"{near:g}", wording=wording)
    line = min(_STANDARD_V, key=lambda s: abs(np.log(raw_median * np.sqrt(3) / s)))
    if abs(raw_median * np.sqrt(3) / line - 1) < 0.05:
        return (
            f"{option('v-base', f'{raw_median:.4g}', wording=wording)} (line-to-neutral "
            f"data of a {line:g} system: {line:g}/sqrt(3))"
        )
    return option("v-base", f"{raw_median:.4g}", wording=wording)


def refuse(
    problems: list[UnitProblem],
    *,
    path: str | None = None,
    names: Mapping[str, str | None] | None = None,
) -> None:
    """Raise one :class:`DataError` for the first problem, naming the user's column.

    Parameters
    ----------
    problems : list of UnitProblem
        From :mod:`loadbayes.measurements.units`' checks; nothing happens
        when it is empty.
    path : str, optional
        The file, for the message.
    names : mapping, optional
        The user's column names (``{"v": "V_kV", ...}``).

    Raises
    ------
    DataError
        When ``problems`` is not empty.
    """
    if not problems:
        return
    first = problems[0]
    column = (names or {}).get(first.column) or first.column
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    raise DataError(str(first) + more, path=path, column=column)
