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

__all__ = ["SEQUENCE_COLUMNS", "UNBALANCE_LIMIT", "EventRecord", "check_units", "sequence_phasors"]

#: A table's columns of the negative-sequence phasors, per unit: ``V2 = v2_re + j v2_im``
#: and ``I2 = i2_re + j i2_im`` (what :attr:`EventRecord.v2` and ``.i2`` are read from).
SEQUENCE_COLUMNS = ("v2_re", "v2_im", "i2_re", "i2_im")

#: Negative-sequence voltage share ``|V2| / |V1|`` above which a sample is unbalanced
#: (the reader's ``unbalanced`` column and :attr:`EventRecord.unbalanced`). Below it, V2
#: is the supply's own standing unbalance (typically 0.5-2%), against which the load's
#: unequal single-phase loads make I2: there I2 / V2 is not an admittance.
UNBALANCE_LIMIT = 0.05


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
    v2, i2 : complex ndarray or None
        Negative-sequence voltage and current phasors per sample (an event file's
        ``v2_re, v2_im, i2_re, i2_im``; docs/formats.md): V2 per unit of the phase
        voltage base, I2 per unit of ``S_base / V_base`` (with a balanced load
        ``p + jq = V1 conj(I1)``), current into the load, in the frame of ``delta``
        (``V1 = v exp(j delta)``). None when the record has no negative sequence (a
        positive-sequence PMU, a simulation).
    """

    t: NDArray[np.float64]
    v: NDArray[np.float64]
    p: NDArray[np.float64]
    q: NDArray[np.float64]
    delta: NDArray[np.float64] | None = None
    name: str = ""
    angle_from: str = ""
    v2: NDArray[np.complex128] | None = None
    i2: NDArray[np.complex128] | None = None
    #: The rows whose phasor window straddles a voltage step (the reader's ``straddle``
    #: column), or None: not known. A model reading window means leaves them out.
    straddle: NDArray[np.bool_] | None = None

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

    def take(self, keep: NDArray[np.intp] | NDArray[np.bool_]) -> EventRecord:
        """The event with only the samples at ``keep``: every per-sample field sliced.

        ``dataclasses.replace`` with ``t, v, p, q`` (and ``delta``) alone would leave
        ``v2`` and ``i2`` at the old length.
        """
        from dataclasses import replace

        def cut(x):
            return None if x is None else x[keep]

        return replace(self, t=self.t[keep], v=self.v[keep], p=self.p[keep], q=self.q[keep],
                       delta=cut(self.delta), v2=cut(self.v2), i2=cut(self.i2),
                       straddle=cut(self.straddle))  # fmt: skip

    @property
    def unbalanced(self) -> bool:
        """Whether ``|V2| / |V1|`` exceeds :data:`UNBALANCE_LIMIT` at any sample."""
        if self.v2 is None:
            return False
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.abs(self.v2) / np.abs(self.v)
        return bool(np.nanmax(share, initial=0.0) > UNBALANCE_LIMIT)

    @property
    def y2(self) -> NDArray[np.complex128] | None:
        """The load's negative-sequence admittance ``I2 / V2`` (system p.u.) per sample.

        NaN where ``|V2| / |V1|`` is at most :data:`UNBALANCE_LIMIT` (no fault: V2 and
        I2 there are standing unbalance, and their ratio is no admittance); None when
        the event has no negative sequence. A static load's is about ``P0 - jQ0`` (its
        constant-impedance equivalent); a running motor's is close to its locked-rotor
        admittance, several times its rating.
        """
        if self.v2 is None or self.i2 is None:
            return None
        with np.errstate(invalid="ignore", divide="ignore"):
            y = self.i2 / self.v2
            keep = np.abs(self.v2) / np.abs(self.v) > UNBALANCE_LIMIT
        return np.where(keep, y, complex(np.nan, np.nan))


def sequence_phasors(
    found: dict[str, np.ndarray],
    *,
    path: str,
    v_base: float | None = None,
    s_base: float | None = None,
) -> dict[str, np.ndarray]:
    """``{"v2": V2, "i2": I2}`` (complex, per unit) from a table's columns, or ``{}``.

    ``found`` holds the columns read of :data:`SEQUENCE_COLUMNS`
    (``v2_re, v2_im, i2_re, i2_im``); all four or none (one missing is refused, naming
    it). Per unit as ``loadbayes events`` writes them; with bases, V2 is in the units
    of ``v`` (divided by ``v_base``) and I2 in those of ``p`` over ``v`` (so that a
    balanced load's ``p + jq = v conj(i)`` holds in the data's units: multiplied by
    ``v_base / s_base``).
    """
    have = [c for c in SEQUENCE_COLUMNS if c in found]
    if not have:
        return {}
    if len(have) < len(SEQUENCE_COLUMNS):
        missing = next(c for c in SEQUENCE_COLUMNS if c not in found)
        raise DataError(
            f"missing column (the negative sequence needs all of {', '.join(SEQUENCE_COLUMNS)}; "
            f"{', '.join(have)} given)",
            path,
            missing,
        )
    v2 = np.asarray(found["v2_re"], dtype=float) + 1j * np.asarray(found["v2_im"], dtype=float)
    i2 = np.asarray(found["i2_re"], dtype=float) + 1j * np.asarray(found["i2_im"], dtype=float)
    vs, ss = v_base or 1.0, s_base or 1.0
    return {"v2": v2 / vs, "i2": i2 * vs / ss}


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
