"""The channels of a COMTRADE record: chosen by name, number, bay or phase; scaled; checked.

Part of :func:`~loadbayes.recordings.comtrade.read_comtrade` (its module docstring says
how channels are chosen).
"""

from __future__ import annotations

import re

import numpy as np

from loadbayes.io.errors import DataError
from loadbayes.recordings.comtrade_cfg import AnalogChannel, CfgInfo

__all__ = [
    "current_sets",
    "dead_channels",
    "missing_note",
    "pick_channels",
    "scale_channel",
    "unit_factor",
]


_UNIT_SCALE = {"V": 1.0, "kV": 1e3, "KV": 1e3, "MV": 1e6, "mV": 1e-3,
               "A": 1.0, "kA": 1e3, "KA": 1e3, "mA": 1e-3}  # fmt: skip


_PHASES = (("A", "B", "C"), ("R", "S", "T"), ("L1", "L2", "L3"), ("1", "2", "3"))


def _phase_key(ch: AnalogChannel) -> str | None:
    ph = ch.phase.strip().upper()
    if len(ph) == 2 and ph.endswith("N"):
        ph = ph[0]  # "AN": phase a to neutral
    for trio in _PHASES:
        if ph in trio:
            return "abc"[trio.index(ph)]
    tail = ch.name.strip().upper()
    for suffix in ("-N", "_N", "N"):
        if tail.endswith(suffix) and len(tail) > len(suffix) + 1:
            tail = tail[: -len(suffix)]  # "VA-N", "VAN": phase to neutral
            break
    for trio in _PHASES[:3]:
        for k, tag in enumerate(trio):
            if tail.endswith(tag) and len(tail) > len(tag):
                return "abc"[k]
    return None


#: Channel-name endings (after the last separator) and phase fields of a zero-sequence
#: (residual) channel: 3I0 = Ia + Ib + Ic, the neutral's current, 3U0.
_ZERO_NAMES = {"3I0", "I0", "IN", "3IO", "IO", "3U0", "U0", "UN", "3V0", "V0", "VN", "IG", "IRES"}
_ZERO_PHASES = {"N", "0", "Z", "G", "3I0", "I0", "3U0", "U0", "3V0", "V0"}


def _zero_sequence(ch: AnalogChannel) -> bool:
    """Whether a channel is a residual (zero-sequence or neutral) quantity, not a phase."""
    if ch.phase.strip().upper() in _ZERO_PHASES:
        return True
    tail = ch.name.strip().upper().replace("-", "_").replace(" ", "_").split("_")[-1]
    return tail in _ZERO_NAMES or "零序" in ch.name


def _check_role(ch: AnalogChannel, kind: str, path: str) -> None:
    """Refuse a named channel whose unit is the other kind's, or a residual channel."""
    unit = ch.unit.strip()
    if unit_factor(unit) is not None:
        is_current = unit.upper().endswith("A")
        if is_current != (kind == "current"):
            own = "current" if is_current else "voltage"
            raise DataError(
                f"line {ch.line}: channel {ch.name!r} is in {unit!r}, a {own}'s unit, but "
                f"--{kind} names it: name the three phase {kind}s (a {own} channel goes "
                f"to --{own})",
                path,
            )
    if _zero_sequence(ch):
        raise DataError(
            f"line {ch.line}: channel {ch.name!r} (phase {ch.phase.strip()!r}) is a "
            f"zero-sequence (residual) channel, not a phase: --{kind} takes the phases a, "
            "b, c",
            path,
        )


def _duplicates(info: CfgInfo) -> dict[str, list[int]]:
    """Channel ids given to more than one analog channel, with their ``.cfg`` lines."""
    lines: dict[str, list[int]] = {}
    for ch in info.analog:
        lines.setdefault(ch.name, []).append(ch.line)
    return {k: v for k, v in lines.items() if len(v) > 1}


def _by_spec(info: CfgInfo, spec: str, kind: str) -> AnalogChannel:
    """A channel by name (``ch_id``) or by its 1-based number."""
    dup = _duplicates(info).get(spec)
    if dup:
        raise DataError(
            f"channel id {spec!r} is on lines {', '.join(map(str, dup))}: name the channel "
            f"by its 1-based number in --{kind}",
            info.path,
        )
    for ch in info.analog:
        if ch.name == spec:
            return ch
    if re.fullmatch(r"[0-9]+", spec.strip()):  # not isdigit(): '²' is a digit to it
        for ch in info.analog:
            if ch.n == int(spec):
                return ch
        raise DataError(
            f"no analog channel number {spec} (channels 1 to {len(info.analog)}; --{kind})",
            info.path,
        )
    names = [ch.name for ch in info.analog]
    more = f", ... and {len(names) - 20} more" if len(names) > 20 else ""  # one line, short
    raise DataError(
        f"no analog channel {spec!r} (channels: {', '.join(names[:20])}{more})", info.path
    )


def _trios(chans: list[AnalogChannel]) -> list[list[AnalogChannel]]:
    """Three-phase sets, in file order: per bay (``ccbm``) a, b, c channels."""
    groups: dict[str, dict[str, AnalogChannel]] = {}
    for ch in chans:
        key = _phase_key(ch)
        if key is not None:
            groups.setdefault(ch.ccbm.strip(), {}).setdefault(key, ch)
    out = [[g["a"], g["b"], g["c"]] for g in groups.values() if len(g) == 3]
    if not out:  # no bay fields: the first a, b, c of the file
        found: dict[str, AnalogChannel] = {}
        for ch in chans:
            key = _phase_key(ch)
            if key is not None and key not in found:
                found[key] = ch
        if len(found) == 3:
            out = [[found["a"], found["b"], found["c"]]]
    return out


def _bays(info: CfgInfo) -> list[str]:
    return list(dict.fromkeys(ch.ccbm.strip() for ch in info.analog if ch.ccbm.strip()))


def current_sets(info: CfgInfo) -> list[tuple[str, list[AnalogChannel]]]:
    """Every three-phase current set of the file, in file order, with its bay's name.

    The name is the set's bay field (``ccbm``), or else the phase a channel's name
    (a file without bay fields). An archive's scan lists a record's bays with it.
    """
    cands = [ch for ch in info.analog if ch.unit.strip().upper().endswith("A")]
    cands = [ch for ch in cands if unit_factor(ch.unit) is not None and not _zero_sequence(ch)]
    return [(t[0].ccbm.strip() or t[0].name.strip(), t) for t in _trios(cands)]


def pick_channels(
    info: CfgInfo, names: list[str] | None, kind: str, bay: str | None = None
) -> tuple[list[AnalogChannel], str]:
    """Three phase channels and how they were chosen."""
    if names is not None:
        if len(names) != 3:
            raise DataError(f"--{kind} takes three channel names, got {len(names)}", info.path)
        chans = [_by_spec(info, nm, kind) for nm in names]
        for ch in chans:
            _check_role(ch, kind, info.path)
        for k, ch in enumerate(chans):
            if ch in chans[:k]:
                raise DataError(
                    f"--{kind} names channel {ch.name!r} (line {ch.line}) twice: one channel "
                    "cannot be two phases",
                    info.path,
                )
        return chans, "named"
    base = "V" if kind == "voltage" else "A"
    cands = [ch for ch in info.analog if ch.unit.strip().upper().endswith(base)]
    cands = [ch for ch in cands if unit_factor(ch.unit) is not None]
    how = "found by unit and phase"
    by_bay = False
    if bay is not None:
        in_bay = [ch for ch in cands if bay.lower() in (ch.ccbm + " " + ch.name).lower()]
        if in_bay:
            cands, how, by_bay = in_bay, f"bay {bay!r}", True
        elif kind == "current":
            raise DataError(
                f"bay {bay!r} has no current channels (bays: {', '.join(_bays(info))})",
                info.path,
            )
        else:
            how = f"bay {bay!r} has no voltage channels: the first three-phase voltage"
    trios = _trios(cands)
    dup = _duplicates(info)
    if dup and any(ch.name in dup for t in trios[:1] for ch in t) or (not trios and dup):
        name, lines = next(iter(dup.items()))
        raise DataError(
            f"channel id {name!r} is given to the channels on lines "
            f"{', '.join(map(str, lines))}: name the {kind} channels by their 1-based "
            f"numbers with --{kind} N,N,N",
            info.path,
        )
    if not trios:
        odd = [ch for ch in info.analog if unit_factor(ch.unit) is None]
        if len(cands) < 3 and not odd:
            # A single-phase (or a currents- or voltages-only) record: nothing to name.
            have = ", ".join(repr(ch.name) for ch in cands) or "none"
            raise DataError(
                f"{len(cands)} {kind} channel{'s' * (len(cands) != 1)} ({have}"
                f"{' in bay ' + repr(bay) if bay is not None and cands else ''}): the positive "
                f"sequence, P and Q need the three phases' {kind}s; a single-phase or "
                f"{'current' if kind == 'voltage' else 'voltage'}-only record cannot be read",
                info.path,
            )
        hint = (
            f"; line {odd[0].line}: channel {odd[0].name!r} has unit {odd[0].unit.strip()[:20]!r}"
            f", not one of {', '.join(sorted(set(_UNIT_SCALE)))}"
            if odd
            else ""
        )
        raise DataError(
            f"cannot tell which three channels are the phase {kind}s; name them with "
            f"--{kind} A,B,C (names or 1-based numbers; analog channels: "
            f"{', '.join(ch.name for ch in info.analog)}){hint}",
            info.path,
        )
    if by_bay and len(trios) > 1:
        # The text names several bays: the one whose bay field it is, or none silently.
        exact = [t for t in trios if t[0].ccbm.strip().lower() == bay.strip().lower()]
        if len(exact) != 1:
            raise DataError(
                f"bay {bay!r} matches {len(trios)} {kind} sets: "
                + ", ".join(t[0].ccbm.strip() or t[0].name for t in trios)
                + f"; give more of the bay's name, or --{kind} A,B,C",
                info.path,
            )
        trios = exact
    if kind == "current" and bay is None and len(trios) > 1:
        raise DataError(
            f"{len(trios)} three-phase current sets ("
            + "; ".join(t[0].ccbm.strip() or t[0].name for t in trios)
            + "): choose one with --bay TEXT or --current A,B,C",
            info.path,
        )
    return trios[0], how


def unit_factor(unit: str) -> float | None:
    """The factor from a channel's unit to volts or amperes, or None if unknown."""
    unit = unit.strip()
    if unit in _UNIT_SCALE:
        return _UNIT_SCALE[unit]
    # Case is only meaningful for m/M (milli, mega); "kv", "KV", "a" are plain.
    return {"V": 1.0, "KV": 1e3, "A": 1.0, "KA": 1e3}.get(unit.upper())


def scale_channel(ch: AnalogChannel, values: np.ndarray, side: str, path: str) -> np.ndarray:
    """A channel's values in volts or amperes on the primary or secondary side."""
    unit = ch.unit.strip()
    factor = unit_factor(unit)
    if factor is None:
        raise DataError(
            f"line {ch.line}: channel {ch.name!r} unit {unit[:20]!r} is not one of "
            f"{', '.join(sorted(set(_UNIT_SCALE)))}",
            path,
        )
    ratio = ch.primary / ch.secondary
    if side == "primary" and ch.pors == "S":
        factor *= ratio
    elif side == "secondary" and ch.pors == "P":
        factor /= ratio
    return values * factor


def missing_note(info: CfgInfo, ch: AnalogChannel) -> str:
    """Why a sample is missing, in the words of the standard's markers."""
    if info.format == "BINARY" and info.revision == "1991":
        return (
            "missing value (raw 0xFFFF: COMTRADE 1991 BINARY marks a missing sample so, "
            "though later revisions read it as -1)"
        )
    if info.format == "BINARY":
        return "missing value (raw 0x8000, the BINARY missing-sample marker)"
    if info.format == "BINARY32":
        return "missing value (raw 0x80000000, the BINARY32 missing-sample marker)"
    if info.format == "FLOAT32":
        return "missing value (NaN or infinite, FLOAT32's missing-sample marker)"
    return "missing value (an empty, 99999, NaN or infinite cell)"


def dead_channels(vch, v, ich, i, path: str, dat: str | None = None) -> list[str]:
    """Refuse a dead or mis-scaled voltage phase; say where a current phase is dead.

    A voltage phase that is constant over the whole record (a multiplier of 0, an open
    VT fuse) puts the positive sequence at 2/3 of the truth; one whose typical magnitude
    differs from the others' by 3x or more has a unit or ratio wrong in the ``.cfg``
    (V among kV). A constant current phase can be real (an open pole): said, not refused.
    Currents are checked as the voltages are, where it cannot be right: a sample more
    than :data:`ABSURD_RATIO` times its channel's median (refused, naming the sample of
    ``dat``), a phase :data:`CURRENT_RATIO_LIMIT` times smaller than another (refused);
    one 3x smaller is said (an unbalanced load can be real).
    """
    notes = []
    spread = np.ptp(v, axis=1)
    for ch, sp in zip(vch, spread, strict=True):
        if sp == 0:
            raise DataError(
                f"line {ch.line}: voltage channel {ch.name!r} is constant over the whole "
                "record (a dead phase, or a multiplier of 0): the positive sequence would be "
                "2/3 of the truth; name another with --voltage",
                path,
            )
    typical = np.median(np.abs(v), axis=1)
    if typical.min() > 0 and typical.max() / typical.min() >= 3.0:
        lo, hi = int(np.argmin(typical)), int(np.argmax(typical))
        ratio = typical[hi] / typical[lo]
        raise DataError(
            f"line {vch[lo].line}: voltage channel {vch[lo].name!r} is {ratio:.3g}"
            f" times smaller than {vch[hi].name!r} over the record: its unit "
            f"({vch[lo].unit.strip()!r}) or ratio is wrong, or the phases are not one set",
            path,
        )
    for ch, sp in zip(ich, np.ptp(i, axis=1), strict=True):
        if sp == 0:
            notes.append(f"current channel {ch.name!r} is constant over the whole record")
    for kind, chans, x in (("voltage", vch, v), ("current", ich, i)):
        _absurd_samples(kind, chans, x, dat or path)
    typical = np.median(np.abs(i), axis=1)
    if typical.min() > 0 and typical.max() / typical.min() >= 3.0:
        lo, hi = int(np.argmin(typical)), int(np.argmax(typical))
        ratio = typical[hi] / typical[lo]
        said = (
            f"line {ich[lo].line}: current channel {ich[lo].name!r} is {ratio:.3g} times "
            f"smaller than {ich[hi].name!r} over the record"
        )
        if ratio >= CURRENT_RATIO_LIMIT:
            raise DataError(
                f"{said}: no load is that unbalanced; its unit ({ich[lo].unit.strip()!r}), "
                "multiplier or ratio is wrong, or the phases are not one set",
                path,
            )
        notes.append(
            f"{said}: a load that unbalanced, an open pole, or a wrong unit or ratio in the "
            ".cfg (check it: P and Q are read from these currents)"
        )
    return notes


#: A sample this many times its channel's median magnitude is corrupt, not measured (a
#: fault current is 10-50 times the load's; a FLOAT32 3e38 is 1e35 times it).
ABSURD_RATIO = 1e6
#: A current phase this many times smaller than another is a unit or multiplier slip;
#: between 3x and this, an unbalanced load or an open pole can be real: said, not refused.
CURRENT_RATIO_LIMIT = 1e3


def _absurd_samples(kind: str, chans, x: np.ndarray, path: str) -> None:
    """Refuse a sample far beyond its channel's typical magnitude (a corrupt value)."""
    for ch, row in zip(chans, x, strict=True):
        med = float(np.median(np.abs(row)))
        if not med > 0:
            continue
        far = np.flatnonzero(np.abs(row) > ABSURD_RATIO * med)
        if far.size:
            k = int(far[0])
            raise DataError(
                f"{kind} channel {ch.name!r}, sample {k + 1}: {row[k]:.3g} is "
                f"{abs(row[k]) / med:.3g} times the channel's median magnitude (more than "
                f"{ABSURD_RATIO:.0e}): a corrupt sample, not a measurement",
                path,
            )
