"""A disturbance record as a table: sequence phasors, positive-sequence power, magnitudes.

One row per phasor estimate of a waveform segment, and one row per sample of an
amplitude segment (a recorder's slow run that holds one magnitude per phase and cycle).

Waveform rows (``kind = "phasor"``), from :func:`~loadbayes.recordings.phasor_fit.fit_phasors`:

- ``v``, ``angle_rad``: the positive-sequence voltage ``V1 = (Va + a Vb + a^2 Vc) / 3``,
  per unit of the phase base, and its angle in the frame rotating at the nominal
  frequency;
- ``p``, ``q``: the positive-sequence power ``3 V1 conj(I1)``, per unit of the 3-phase
  base. This is what the composite fit takes: its model is a positive-sequence model;
- ``p_total``, ``q_total``: the three-phase power ``sum_k Vk conj(Ik)`` (what the load
  draws in all sequences); it differs from ``p, q`` by ``3 (V2 conj(I2) + V0 conj(I0))``;
- ``v2``: the negative-sequence share ``|V2| / |V1|`` of the voltage; ``unbalanced`` is
  true where it exceeds :data:`UNBALANCE_LIMIT`: there the negative-sequence power, which
  the positive-sequence model does not describe, is part of what the load draws;
  ``i2``: ``|I2| / |I1|``;
- ``v2_re, v2_im``, ``i2_re, i2_im``: the negative-sequence phasors
  ``V2 = (Va + a^2 Vb + a Vc) / 3`` (per unit of the phase base, as ``v``) and ``I2``
  (per unit of ``S_base / (3 V_base)``, so that ``p + jq = 3 V1 conj(I1)`` per unit of
  the 3-phase base reads ``V1 conj(I1)`` in these units), in the frame of ``angle_rad``
  (``V1 = v exp(j angle_rad)``): the load's negative-sequence admittance is ``I2 / V2``.
  They are taken without the mirror a moving positive sequence leaves in a one-cycle
  phasor (:mod:`~loadbayes.recordings.sequences`), which the ratios keep;
- ``f``: frequency (Hz) from the turn of ``V1`` between neighbouring estimates;
- ``residual``: the worst voltage channel's relative misfit in the window; ``straddle``
  is true where it exceeds :data:`STRADDLE_LIMIT` (a window across a step, which no
  phasor describes), or where a voltage's phasor differs between the window's two half
  cycles (a fault's inception near a zero crossing, which the misfit misses:
  :data:`~loadbayes.recordings.phasor_fit.HALF_STEP_LIMIT`);
- ``va, vb, vc, ia, ib, ic``: per-phase RMS magnitudes (per unit).

One idea needs these 467 lines: a record's table, its phasor rows (above) and its
amplitude rows (below) built from the waveforms (and a timed probe of the same fit, for
the cost said before a long read).
Amplitude rows (``kind = "amplitude"``) hold only ``va .. ic`` (RMS, per unit; whether
the recorder wrote peak or RMS values is decided by comparing the first amplitude sample
with the neighbouring waveform window, and said in the metadata). No phasor, P or Q is
invented for them: those columns are NaN.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from loadbayes.io.errors import DataError
from loadbayes.measurements.record import SEQUENCE_COLUMNS, UNBALANCE_LIMIT
from loadbayes.recordings.comtrade import Waveforms
from loadbayes.recordings.phasor_fit import fit_phasors
from loadbayes.recordings.sequences import demirror, sequences

__all__ = [
    "STRADDLE_LIMIT",
    "UNBALANCE_LIMIT",
    "RecordTable",
    "phasor_windows",
    "probe_windows",
    "record_table",
]

#: Relative misfit of a window above which it is flagged as straddling a step.
STRADDLE_LIMIT = 0.02
#: Median share of the fundamental in a waveform segment's voltage windows below which
#: the segment holds no waveform (magnitudes mislabelled as waveform samples).
MIN_SHARE = 0.5

COLUMNS = (
    "t_s", "v", "angle_rad", "p", "q", "f", "p_total", "q_total", "v2", "i2",
    "unbalanced", "residual", "straddle", "dc_filtered", "va", "vb", "vc", "ia", "ib",
    "ic", "segment", "kind", *SEQUENCE_COLUMNS,
)  # fmt: skip


@dataclass
class RecordTable:
    """The table (a dict of equal-length arrays) and what was decided reading it."""

    columns: dict[str, np.ndarray]
    v_base_kv: float
    s_base_mva: float
    notes: list[str] = field(default_factory=list)
    amplitude: str = ""

    @property
    def rows(self) -> int:
        """Rows of the table."""
        return int(self.columns["t_s"].size)


def _empty(m: int) -> dict[str, np.ndarray]:
    out = {c: np.full(m, np.nan) for c in COLUMNS}
    out["unbalanced"] = np.zeros(m, dtype=bool)
    out["straddle"] = np.zeros(m, dtype=bool)
    out["dc_filtered"] = np.zeros(m, dtype=bool)
    out["segment"] = np.zeros(m, dtype=np.int64)
    out["kind"] = np.full(m, "phasor", dtype=object)
    return out


def _waveform_rows(
    w: Waveforms, seg, per_cycle: int, dc: str, k: int = 0, source: str = "", progress=None
) -> dict[str, np.ndarray]:
    sl = slice(seg.start, seg.stop)
    skew = None if w.skew_s is None else np.concatenate([w.skew_s[0], w.skew_s[1]])
    try:
        fit = fit_phasors(
            w.t_s[sl], np.vstack([w.v[:, sl], w.i[:, sl]]), f0=w.f_nominal,
            per_cycle=per_cycle, dc=dc, skew_s=skew, step_channels=3, progress=progress,
            phase_sets=((0, 1, 2), (3, 4, 5)),
        )  # fmt: skip
    except ValueError as exc:
        if len(w.segments) < 2:
            raise
        rate = f"{seg.rate_hz:g} samples/s by the rate table" if seg.rate_hz else "stamps"
        raise DataError(
            f"samples {seg.start + 1}-{seg.stop} (segment {k + 1}, {rate}): {exc}; too "
            "short for a waveform segment (an amplitude segment labelled as waveform?)",
            source,
        ) from None
    vph, iph = fit.x[:3], fit.x[3:]
    _, v1, v2 = sequences(vph)
    _, i1, i2 = sequences(iph)
    # The phasors V2, I2 without the mirror of a moving V1, I1 (recordings/sequences.py);
    # the ratios v2, i2 stay the plain one-cycle ones (the `unbalanced` flag's, as before).
    # Not through a step, nor where the mimic filter (--dc on) read a phase (it turns the
    # mirror); a window with its offset taken out (--dc auto) is a plain fit, mirror and all.
    step = (fit.residual[:3].max(axis=0) > STRADDLE_LIMIT) | np.asarray(fit.half_step, bool)
    decay = np.asarray(fit.decay, dtype=bool) & (dc == "on")
    dt = float(np.median(np.diff(w.t_s[sl])))
    v2_ph = demirror(v2, v1, fit.t_s, w.f_nominal, step | decay[:3].any(axis=0), dt)
    i2_ph = demirror(i2, i1, fit.t_s, w.f_nominal, step | decay[3:].any(axis=0), dt)
    m = fit.t_s.size
    out = _empty(m)
    s1 = 3.0 * v1 * np.conj(i1)
    st = np.sum(vph * np.conj(iph), axis=0)
    f = _frequency(fit.t_s, v1, w.f_nominal, fit.f_hz)
    with np.errstate(invalid="ignore", divide="ignore"):
        out.update(
            t_s=fit.t_s, v=np.abs(v1), angle_rad=np.angle(v1), p=s1.real, q=s1.imag, f=f,
            p_total=st.real, q_total=st.imag, v2=np.abs(v2) / np.abs(v1),
            i2=np.abs(i2) / np.abs(i1), residual=fit.residual[:3].max(axis=0),
            v2_re=v2_ph.real, v2_im=v2_ph.imag, i2_re=i2_ph.real, i2_im=i2_ph.imag,
            _share=fit.share[:3].min(axis=0),
            va=np.abs(vph[0]), vb=np.abs(vph[1]), vc=np.abs(vph[2]),
            ia=np.abs(iph[0]), ib=np.abs(iph[1]), ic=np.abs(iph[2]),
        )  # fmt: skip
    out["angle_rad"] = np.unwrap(out["angle_rad"])
    out["dc_filtered"] = np.asarray(fit.decay, dtype=bool).any(axis=0)
    out["_half_step"] = np.asarray(fit.half_step, dtype=bool)
    return out


def _dc_note(table: dict[str, np.ndarray]) -> str:
    """Plain words on where a decaying offset was taken out, and how to compare.

    A fault's current can carry a decaying offset, and --dc auto takes it out of the
    windows where a test finds one (fitted over two cycles beside the moving phasor:
    recordings/phasor_fit.py) and of those that follow while it lasts. The test reads
    each three-phase set's space vector over two cycles, which tells an offset from a
    load's own current transient (a motor's flux after a step, a few ms; before, a
    one-cycle test took it for an offset and put P 2-6% of the load off:
    docs/composite.md, "A recorder's waveforms"). What it still cannot tell apart: a
    negative sequence that moves within the two cycles (an unbalanced fault's first
    cycles). Right after a step is where taking the offset out moves P and Q most, so
    those rows are counted, with the way to compare. Inside an unbalanced fault it is not
    ruled out, but measured (tests/unit/test_record_fault_rows.py): on a static load and
    a phase-to-ground fault the test does not fire without an offset, and with one the
    reading brings P from 1.5-2% of P0 off to under 0.6%; what can still fool it is a
    load whose negative sequence moves.
    """
    dc = np.asarray(table["dc_filtered"], dtype=bool)
    if not dc.any():
        return ""
    step = np.asarray(table["straddle"], dtype=bool)
    near = np.zeros_like(dc)
    for k in np.flatnonzero(step):  # the windows up to two after a straddling one
        near[k : k + 3] = True
    after = int(np.sum(dc & near))
    unbalanced = int(np.sum(dc & np.asarray(table["unbalanced"], dtype=bool)))
    words = (
        f"{int(dc.sum())} phasor rows had a decaying offset taken out (column "
        "'dc_filtered'; --dc auto), where its test found one in the currents"
    )
    if after or unbalanced:
        where = [f"{after} right after a voltage step"] if after else []
        where += [f"{unbalanced} in an unbalanced window"] if unbalanced else []
        words += (
            f" ({', '.join(where)}: there it moves P and Q by up to several per cent; an "
            "unbalanced fault's moving negative sequence can pass for an offset)"
            ": to see what it changed, compare a reading with --dc off"
        )
    return words


def _frequency(t: np.ndarray, v1: np.ndarray, f0: float, f_seg: float) -> np.ndarray:
    """Frequency (Hz) at each window from the turn of V1, a running median of three turns.

    A window across a step of the voltage's magnitude has its phase pulled one way and
    its neighbour's back (a spike and its mirror in the turns); the median of three
    neighbouring turns removes such a pair and follows a real frequency change.
    """
    m = t.size
    if m < 2:
        return np.full(m, f_seg)
    turn = np.angle(v1[1:] * np.conj(v1[:-1])) / (2 * np.pi * np.diff(t))
    # turns[k] is between windows k-1 and k; each window takes the turns either side
    # and the next one out.
    pad = np.concatenate([turn[:1], turn[:1], turn, turn[-1:], turn[-1:]])
    med = np.median(np.stack([pad[0:-2], pad[1:-1], pad[2:]]), axis=0)
    # med[j] is the median around turn j-1; window k lies between turns k-1 and k.
    return f0 + 0.5 * (med[:m] + med[1 : m + 1])


def _amplitude_rows(w: Waveforms, seg, scale: float) -> dict[str, np.ndarray]:
    sl = slice(seg.start, seg.stop)
    m = seg.stop - seg.start
    out = _empty(m)
    out["t_s"] = w.t_s[sl]
    out["kind"] = np.full(m, "amplitude", dtype=object)
    for k, ph in enumerate("abc"):
        out[f"v{ph}"] = np.abs(w.v[k, sl]) / scale
        out[f"i{ph}"] = np.abs(w.i[k, sl]) / scale
    return out


def _amplitude_scale(w: Waveforms, parts: list[tuple]) -> tuple[float, str]:
    """Whether amplitude samples are peak (divide by sqrt 2) or RMS values.

    Decided by the amplitude sample next to a waveform segment against that segment's
    nearest phasor.
    """
    for k, (seg, _) in enumerate(parts):
        if seg.kind != "amplitude":
            continue
        if k > 0 and parts[k - 1][0].kind == "waveform":
            rows, j, sample = parts[k - 1][1], -1, seg.start
        elif k + 1 < len(parts) and parts[k + 1][0].kind == "waveform":
            rows, j, sample = parts[k + 1][1], 0, seg.stop - 1
        else:
            continue
        rms = float(np.mean([rows[c][j] for c in ("va", "vb", "vc")]))
        ratio = float(np.mean(np.abs(w.v[:, sample]))) / rms
        said = f"(amplitude sample / RMS of the neighbouring waveform cycle = {ratio:.3f})"
        if abs(ratio - math.sqrt(2)) < 0.1:
            return math.sqrt(2), f"amplitude segments hold peak values {said}: divided by sqrt 2"
        if abs(ratio - 1.0) < 0.1:
            return 1.0, f"amplitude segments hold RMS values {said}"
        return math.sqrt(2), f"amplitude segments: peak or RMS cannot be told {said}; read as peak"
    return math.sqrt(2), "amplitude segments read as peak values (no waveform beside them)"


def record_table(
    w: Waveforms,
    *,
    per_cycle: int = 1,
    dc: str = "auto",
    v_base_kv: float | None = None,
    s_base_mva: float | None = None,
    source: str = "",
    progress: Callable[[int], None] | None = None,
) -> RecordTable:
    """The record's table: phasor rows of its waveform segments, magnitude rows of the rest.

    Parameters
    ----------
    w : Waveforms
        From :func:`~loadbayes.recordings.comtrade.read_comtrade`.
    per_cycle : int, default 1
        Phasor estimates per nominal cycle in waveform segments.
    dc : {"auto", "on", "off"}
        The decaying DC offset's columns in each window (see
        :mod:`~loadbayes.recordings.phasor_fit`).
    v_base_kv, s_base_mva : float, optional
        Line-to-line voltage base (kV) and three-phase power base (MVA); by default the
        first phasor row's ``sqrt(3) |V1|`` and ``|S1|``.
    source : str
        The file, for error messages.
    progress : callable, optional
        Called with the number of phasor windows fitted, as they are (about
        :func:`phasor_windows` in all).

    Returns
    -------
    RecordTable

    Raises
    ------
    DataError
        If a segment labelled as waveform holds no waveform at the nominal frequency, or
        the first row has no voltage or power and no base is given.
    ValueError
        If the record has no waveform segment.
    """
    segs = w.segments or ()
    if not segs:
        from loadbayes.recordings.comtrade import Segment

        segs = (Segment(0, w.t_s.size, w.rate_hz, "waveform"),)
    if not any(s.kind == "waveform" for s in segs):
        raise ValueError("the record has no waveform segment (only magnitudes): no phasors")
    parts = [
        (
            seg,
            _waveform_rows(w, seg, per_cycle, dc, k, source, progress)
            if seg.kind == "waveform"
            else None,
        )
        for k, seg in enumerate(segs)
    ]
    for k, (seg, rows) in enumerate(parts):
        if rows is not None and (share := float(np.median(rows.pop("_share")))) < MIN_SHARE:
            if seg.rate_hz > 0:
                said = f"the rate table says {seg.rate_hz:g} samples/s (segment {k + 1})"
                guess = "an amplitude segment labelled as waveform?"
            else:
                gaps = np.diff(w.t_s[seg.start : seg.stop])
                said = (
                    f"timed by the .dat's stamps alone (segment {k + 1}; spacing from "
                    f"{gaps.min():.3g} to {gaps.max():.3g} s)"
                )
                guess = "implausible time stamps, or magnitudes rather than waveforms?"
            raise DataError(
                f"samples {seg.start + 1}-{seg.stop}: {said}, but the {w.f_nominal:g} Hz "
                f"fundamental holds only {share:.0%} of their power: not waveform samples "
                f"({guess})",
                source,
            )
    notes = [w.clock_note] if w.clock_note else []
    scale, amp_note = 1.0, ""
    if any(s.kind == "amplitude" for s in segs):
        scale, amp_note = _amplitude_scale(w, parts)
        notes.append(amp_note)
    parts = [(s, r if r is not None else _amplitude_rows(w, s, scale)) for s, r in parts]
    first = next(r for s, r in parts if s.kind == "waveform")
    vb = v_base_kv * 1e3 / math.sqrt(3) if v_base_kv else float(first["v"][0])
    sb = s_base_mva * 1e6 if s_base_mva else float(np.hypot(first["p"][0], first["q"][0]))
    if not (vb > 0 and math.isfinite(vb)):
        raise DataError(
            "the first cycle has no voltage (a dead or unscaled VT): give --v-base "
            "(v_base_kv=) in kV line to line, or name other channels with --voltage",
            source or None,
        )
    if not (sb > 0 and math.isfinite(sb)):
        # Every current 0 at the start: multipliers of 0, a bay not recorded, or an open
        # breaker. The voltages can still be read against a power base that is given.
        raise DataError(
            "the first cycle has no power (the currents are 0: a multiplier of 0, a bay "
            "not recorded, or an open breaker?): name other currents with --current or "
            "--bay, or give --s-base (s_base_mva=) to read the voltages anyway",
            source or None,
        )
    ib = sb / (3.0 * vb)
    cols: dict[str, list] = {c: [] for c in COLUMNS}
    for k, (_, rows) in enumerate(parts):
        rows = dict(rows)
        rows["segment"] = np.full(rows["t_s"].size, k, dtype=np.int64)
        for c in ("v", "va", "vb", "vc", "v2_re", "v2_im"):
            rows[c] = rows[c] / vb
        for c in ("ia", "ib", "ic", "i2_re", "i2_im"):
            rows[c] = rows[c] / ib
        for c in ("p", "q", "p_total", "q_total"):
            rows[c] = rows[c] / sb
        rows["unbalanced"] = np.nan_to_num(rows["v2"], nan=0.0) > UNBALANCE_LIMIT
        rows["straddle"] = np.nan_to_num(rows["residual"], nan=0.0) > STRADDLE_LIMIT
        if "_half_step" in rows:  # a step the misfit misses (a fault's inception)
            rows["straddle"] |= rows.pop("_half_step")
        for c in COLUMNS:
            cols[c].append(rows[c])
    table = {c: np.concatenate(v) for c, v in cols.items()}
    amp = [k + 1 for k, s in enumerate(segs) if s.kind == "amplitude"]
    if amp:
        n_amp = int(np.sum(table["kind"] == "amplitude"))
        notes.append(
            f"{n_amp} rows of amplitude segment(s) {', '.join(map(str, amp))} are per-phase "
            "magnitudes only (va .. ic): no phasor, P or Q is invented for them (NaN)"
        )
    dc_note = _dc_note(table)
    if dc_note:
        notes.append(dc_note)
    n_unb = int(table["unbalanced"].sum())
    if n_unb:
        notes.append(
            f"{n_unb} phasor rows have a negative-sequence voltage above "
            f"{UNBALANCE_LIMIT:.0%} of the positive (column 'unbalanced'): an unbalanced "
            "fault; p and q are positive-sequence power, p_total and q_total all sequences"
        )
    return RecordTable(table, vb * math.sqrt(3) / 1e3, sb / 1e6, notes, amp_note)


def phasor_rows(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The rows that hold phasors (a record's waveform segments), every column kept."""
    if "kind" not in columns:
        return dict(columns)
    keep = np.asarray(columns["kind"]) == "phasor"
    return {k: np.asarray(v)[keep] for k, v in columns.items()}


def sags_by_segment(columns: dict[str, np.ndarray], **settings) -> list:
    """The sags of each segment found separately, their windows kept inside it.

    A recorder keeps waveforms only around each fault; a window that ran past a segment's
    end would join two recordings across a gap, and two faults a second apart would be
    merged into one event. So :func:`~loadbayes.recordings.events.find_sags` runs on each
    segment's rows alone (``settings`` are its keywords), and the windows' rows are
    shifted back to the whole table and renumbered in time order.
    """
    from dataclasses import replace

    from loadbayes.recordings.events import find_sags

    t = np.asarray(columns["t_s"], dtype=float)
    v = np.asarray(columns["v"], dtype=float)
    segment = np.asarray(columns.get("segment", np.zeros(t.size, dtype=np.int64)))
    v_ref = settings.pop("v_ref", None)
    out: list = []
    for k in dict.fromkeys(segment.tolist()):
        rows = np.flatnonzero(segment == k)
        if rows.size < 2:
            continue
        ref = float(np.median(v[rows])) if v_ref is None else v_ref
        for ev in find_sags(t[rows], v[rows], v_ref=ref, **settings):
            out.append(
                replace(
                    ev,
                    index=len(out) + 1,
                    start=int(rows[ev.start]),
                    stop=int(rows[ev.stop - 1]) + 1,
                )  # fmt: skip
            )
    return out


def phasor_windows(w: Waveforms, per_cycle: int = 1) -> int:
    """About how many windows :func:`record_table` fits (both passes): its cost, told first."""
    segs = [s for s in (w.segments or ()) if s.kind == "waveform"]
    spans = [w.t_s[s.stop - 1] - w.t_s[s.start] for s in segs] or [w.t_s[-1] - w.t_s[0]]
    return int(2 * sum(max(span, 0.0) * w.f_nominal * per_cycle for span in spans))


def probe_windows(w: Waveforms, per_cycle: int, dc: str, cycles: float, clock) -> tuple[int, float]:
    """Fit the first ``cycles`` of the first waveform segment as :func:`record_table` would.

    Returns the windows fitted (both passes, as :func:`phasor_windows` counts them) and
    the seconds they took by ``clock``: the cost per window of this record at this
    ``per_cycle`` (which the sample times' regularity and ``dc`` change twenty-fold).
    """
    from dataclasses import replace

    seg = next((s for s in (w.segments or ()) if s.kind == "waveform"), None)
    start, stop = (seg.start, seg.stop) if seg is not None else (0, w.t_s.size)
    end = int(np.searchsorted(w.t_s, w.t_s[start] + cycles / w.f_nominal))
    if seg is None:
        from loadbayes.recordings.comtrade import Segment

        seg = Segment(start, stop, w.rate_hz, "waveform")
    part = replace(seg, stop=max(start + 2, min(stop, end)))
    done = [0]

    def count(n: int) -> None:
        done[0] += n

    began = clock()
    try:
        _waveform_rows(w, part, per_cycle, dc, progress=count)
    except (ValueError, DataError):
        return 0, 0.0  # too short to probe: the read itself will say what is wrong
    return done[0], clock() - began
