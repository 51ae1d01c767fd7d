"""One recorded event (:class:`EventRecord`) and the unit check of a recording.

An :class:`EventRecord` is what :func:`~loadbayes.measurements.events.read_events`
reads and what the composite fit, its figures, ``validate`` and ``playback`` are given;
:func:`check_units` is ``fit zip``'s per-unit check applied to each event (in the CLI's
words or Python's). The record lives with the readers, below the models: the composite's
physics (``models/composite.py``) takes it from here, the one import of
``measurements/`` that ``models/`` makes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from loadbayes.io.errors import DataError
from loadbayes.measurements.units import check_power_units, require_power
from loadbayes.measurements.wording import UnitProblem, accept

__all__ = ["EventRecord", "check_units"]


@dataclass(frozen=True, eq=False)
class EventRecord:
    """One recorded disturbance at the load bus (all system p.u.; times in s).

    The record of one event: the samples the composite fit is given (an "event" in the
    CLI, the JSON and :func:`~loadbayes.measurements.events.read_events`), as opposed to
    :class:`~loadbayes.recordings.events.SagWindow`, where a sag lies in a long record.

    Parameters
    ----------
    t, v, p, q : ndarray
        Sample times (strictly increasing), voltage magnitude, total active and reactive
        power of the load.
    delta : ndarray or None
        Voltage angle (rad) relative to a frame rotating at the nominal frequency.
    name : str
        Label (the file, or the file and event id).
    angle_from : str
        Where ``delta`` came from: ``"angle"`` (a recorded angle), ``"frequency"``
        (integrated from a frequency column, which cannot hold a phase jump) or ``""``
        (none, or set by the caller).
    """

    t: NDArray[np.float64]
    v: NDArray[np.float64]
    p: NDArray[np.float64]
    q: NDArray[np.float64]
    delta: NDArray[np.float64] | None = None
    name: str = ""
    angle_from: str = ""

    @property
    def v0(self) -> float:
        """The first sample's voltage: the steady state's and the ZIP's reference."""
        return float(self.v[0])

    @property
    def x(self) -> NDArray[np.float64]:
        """``V / v0``."""
        return self.v / self.v0

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)


def check_units(
    events: Sequence[EventRecord],
    *,
    accept_units: bool = False,
    columns: dict[str, str] | None = None,
    wording: str = "cli",
    overridable: bool = True,
) -> list[str]:
    """The unit check of ``fit zip``, per event: V per unit, P and Q of a sensible size.

    ``overridable=False``: the caller has no ``--accept-units`` (``playback``,
    ``validate``), so the message does not offer it.

    ``columns`` maps ``v``, ``p``, ``q`` to the data's own column names (the ones a
    message names; default the short names).

    The composite's nominal powers are estimated (``p0``, ``q0`` per event), so P and Q
    are checked as ``fit zip --p0 auto`` checks them; a negative median P (a load that
    generates) is refused too. With ``accept_units`` the problems become warnings.
    ``wording`` names the fixes as the CLI's options or Python's keywords.

    Returns
    -------
    list of str
        Warnings (only with ``accept_units``).

    Raises
    ------
    loadbayes.io.errors.DataError
        The first problem, naming the event's file (and event id) and the column.
    """
    names = {"v": "v", "p": "p", "q": "q", **(columns or {})}
    out: list[str] = []
    for e in events:
        require_power(e.p, e.q, path=e.name or None, names=names, wording=wording)  # type: ignore[arg-type]
        problems = check_power_units(e.v, e.p, e.q, p0="auto", q0="auto", wording=wording)
        med_p = float(np.median(e.p))
        if not problems and med_p < 0:
            problems.append(
                UnitProblem(
                    "p",
                    f"P has median {med_p:.4g} < 0: the bus exports power, and a composite "
                    "load (ZIP + motor) consumes it",
                    "give P as the power into the load (check the meter's sign convention)",
                    wording,  # type: ignore[arg-type]
                )
            )
        if not problems:
            continue
        if not accept_units:
            first = problems[0]
            column = names.get(first.column, first.column)
            said = str(first) if overridable else f"{first.seen}; {first.fix}"
            raise DataError(said, path=e.name or None, column=column)
        out += [f"{e.name or 'event'}: column '{names.get(pr.column, pr.column)}': {pr.seen} "
                f"(fitted anyway: {accept(wording)})" for pr in problems]  # type: ignore[arg-type]  # fmt: skip
    return out
