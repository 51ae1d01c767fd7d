"""Switching steps between samples: where, inside a sample interval, a fault's step fell.

A recorder samples the voltage; a fault (or its clearing) steps it at an instant that
falls somewhere inside one sample interval. Driving the motor with the straight line
between the two samples (what the kernel does elsewhere) reads the step as a ramp over
the whole interval: the motor's flux decays meanwhile, and where T' spans only a few
intervals that misreading biases T' and the reactances (measured on ANDES events, see
docs/composite.md, "Steps between samples"). So each such interval gets a step at an
unknown fraction ``phi`` of the interval, a parameter of the fit.

The step is put into the kernel's input as two **virtual knots** inside the interval:
``(t_k + a, V_k)`` and ``(t_k + a + eps, V_k+1)`` with ``a = dt (eps_f + phi (1 - 3 eps_f))``,
``eps = eps_f dt``: the voltage holds ``V_k`` until the step, ramps over ``eps`` (a
hundred-thousandth of the interval), then holds ``V_k+1``. The angle does the same. The model's
outputs at the virtual knots are not data: only the real samples enter the likelihood.

A **step interval** is one where ``|V_k+1 - V_k| > JUMP v0`` and the change is more than
``RATIO`` times that of both neighbouring intervals: a discontinuity, not a fast ramp
(the first interval of a linear recovery has a neighbour changing as much).

A fault's edge is not always inside one interval: a ramp of 10-50 ms, or a recorder's
phasor, which averages over a window (one cycle, often several samples), spreads it over
two or more intervals, and the samples inside it are neither the level before nor the
one after. :func:`edge_runs` finds such **edges**: a run of consecutive intervals in
which the voltage moves the same way, at least one of them by more than ``JUMP v0``, the
others by more than ``GROW`` of that (``GROW_WINDOW`` with a window; and more than
``NOISE_SIGMAS`` times the record's interval-to-interval noise), no longer than the
window allows (``max_intervals``); with a window that spreads a step over several
intervals (``smear_intervals``), a run of that many intervals moving more than ``JUMP v0``
together is a core too (a 10% step read at 4 phasors a cycle moves each by 2.5%). The
samples inside an edge are left out of the fit
(their window straddles the change; how many is reported), and the edge becomes one
step interval from the sample before it to the sample after it, the step at an unknown
instant in it as above. A run longer than that, up to a ramp of ``RAMP_MAX_S`` plus the
window's smear, is a ramp the phasors resolve: the inside samples whose window lies
wholly on it are kept (:func:`window_ramp_samples`), the others left out, and it is a
ramp through the kept ones, as with point samples below. A still longer run is left as
the samples draw it.

That holds for phasor samples (a window mean straddling the change is neither level).
A **point** sample (``window_s == 0``) inside an edge is the exact voltage at its
instant, on the ramp: left out, and the ramp replaced by a step, it biased the motor
share (issue 21's event at 60/s, 20 ms ramps: NLS on the noise-free event f_m 0.393 for
0.400, residual sd 1.3e-3; docs/composite.md, "Ramps between point samples"). So with
point samples every sample is kept, an edge may be as long as a ramp of
:data:`RAMP_MAX_S`, and an edge with samples inside it is a **ramp**: the voltage holds
``V_k0`` until an unknown instant ``t_a`` in the first interval (the same ``phi``), is
linear through the inside samples, and reaches ``V_k1`` at ``t_b`` in the last interval,
where the line from ``(t_a, V_k0)`` through the last inside sample gets there (a
straight ramp: no second unknown; ``t_a`` no earlier than where that line would get
there only at the next sample, :func:`ramp_start_bound`). With two or more samples
inside, the line is theirs (least squares) and both ends are fixed where it reaches
``V_k0`` and ``V_k1`` (:func:`ramp_ends`): no unknown at all (a sampled ``phi`` there cut
the ESS of a 50 ms ramp at 120/s from 133 to 25). The angle follows the same knots. An
edge of one interval (no sample inside) stays a step.

One idea needs these 646 lines: where a voltage step fell between two samples, found
(steps, edges, ramps, for point and phasor samples apart as above) and put into the
motor's input as virtual knots.
Physics only: no sampling here. ``phi`` is sampled directly, uniform on [0, 1]
(fit/composite/problem.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.typing import NDArray

from loadbayes.measurements.record import EventRecord

__all__ = [
    "EPS_FRACTION",
    "GROW",
    "GROW_WINDOW",
    "JUMP",
    "NOISE_SIGMAS",
    "RAMP_MAX_S",
    "RAMP_START_MARGIN",
    "RATIO",
    "FitSamples",
    "StepGrid",
    "edge_runs",
    "fill_times",
    "max_intervals",
    "ramp_ends",
    "ramp_intervals",
    "ramp_start_bound",
    "smear_intervals",
    "step_intervals",
    "window_ramp_intervals",
    "window_ramp_samples",
]

#: A change within one interval above this fraction of ``v0`` can be a step.
JUMP = 0.05
#: ... if it is more than this many times the change over either neighbouring interval.
RATIO = 3.0
#: Width of the virtual ramp, as a fraction of the interval.
EPS_FRACTION = 1e-5
#: An interval next to a step joins its edge when it moves the same way by more than
#: this share of the step's change (point samples) ...
GROW = 0.05
#: ... or this share with phasor samples (a window): one whose window catches the first
#: few ms of a 20 ms ramp moves about 3% of the step, and read as a level it biased f_m
#: low (docs/composite.md, "Phasor samples: window means").
GROW_WINDOW = 0.02
#: ... and by more than this many times the record's interval-to-interval noise sd.
NOISE_SIGMAS = 4.0
#: Point samples: the longest fault edge read as a ramp through its inside samples (s);
#: a longer run is left as the samples draw it (a recovery the samples resolve).
RAMP_MAX_S = 0.06
#: An edge's end interval moving less than this many times its outside
#: neighbour (the same way) is the level moving on, not the edge (:func:`_trim_moving_level`).
LEVEL_RATIO = 2.0
#: A ramp with one sample inside starts no earlier than where its straight line through
#: that sample ends at the next sample, less this share of its first interval (noise on
#: the inside sample moves that bound by well under it: 0.1% noise on a 30% sag, 0.5%)...
RAMP_START_MARGIN = 0.1


def _interval(t: NDArray[np.float64]) -> float:
    """The record's sample interval (its median; 1 for a single sample)."""
    return float(np.median(np.diff(t))) if t.size > 1 else 1.0


def ramp_intervals(t: NDArray[np.float64]) -> int:
    """The longest edge, in intervals, of point samples: a ramp of :data:`RAMP_MAX_S`.

    The ramp's own intervals plus the two it starts and ends inside.
    """
    dt = _interval(t)
    return max(2, int(np.ceil(RAMP_MAX_S / dt - 1e-9)) + 1)


def max_intervals(t: NDArray[np.float64], window_s: float) -> int:
    """The longest edge, in intervals, that a ``window_s`` phasor window can make.

    A step spreads over the samples whose window holds it (``window / dt`` of them)
    plus the interval it fell in; at least two intervals (a short ramp across a sample).
    With a window (phasor samples), one interval more: a short ramp's own, which the
    window smears further (a 20 ms ramp and a one-cycle window touch four 60/s samples).
    """
    dt = _interval(t)
    ramp = 1 if window_s > 0 else 0
    return max(2, int(np.ceil(window_s / dt - 1e-9)) + 1 + ramp)


def smear_intervals(t: NDArray[np.float64], window_s: float) -> int:
    """Intervals over which a ``window_s`` phasor window spreads one voltage step.

    The samples whose window holds the step (``window / dt`` of them, at most
    ``ceil(window / dt)``) each read part of it: the window means move across one
    interval more than that. With several samples a window (a one-cycle phasor at 4 a
    cycle: ``W / dt`` = 4) each interval moves a fraction of the step, under
    :data:`JUMP` for any step under ``JUMP (ceil(W / dt) + 1)``; the edge is found from
    the change over this many intervals instead (:func:`edge_runs`). 1 for point samples.
    """
    if window_s <= 0:
        return 1
    return int(np.ceil(window_s / _interval(t) - 1e-9)) + 1


def window_ramp_intervals(t: NDArray[np.float64], window_s: float) -> int:
    """The longest edge, in intervals, of phasor samples: a smeared ramp.

    A ramp of :data:`RAMP_MAX_S` and the window's smear (``ceil(window / dt)`` more).
    """
    dt = _interval(t)
    return ramp_intervals(t) + int(np.ceil(window_s / dt - 1e-9))


def window_ramp_samples(
    t: NDArray[np.float64], k0: int, k1: int, window_s: float
) -> NDArray[np.int64]:
    """The samples inside the edge ``(k0, k1)`` whose window lies wholly on its ramp.

    Sample ``k0 + 1``'s window is the first to reach the ramp (the first interval moves),
    so the ramp starts before ``t[k0+1] + W/2``, and a sample's window is past that start
    from ``t[k0+1] + W`` on; likewise up to ``t[k1-1] - W`` before its end. A window mean
    of a straight line is its value at the centre: these samples are exact points on the
    ramp (the others mix a level and the ramp, and are left out).
    """
    inside = np.arange(k0 + 1, k1)
    lo, hi = t[k0 + 1] + window_s, t[k1 - 1] - window_s
    tol = 1e-9 * max(window_s, 1e-12)
    return inside[(t[inside] >= lo - tol) & (t[inside] <= hi + tol)].astype(np.int64)


def edge_runs(
    v: NDArray[np.float64],
    *,
    longest: int,
    jump: float = JUMP,
    grow: float = GROW,
    span: int = 1,
) -> list[tuple[int, int]]:
    """The edges of one voltage record: ``(k0, k1)``, from sample ``k0`` to ``k1``.

    The voltage moves across ``k1 - k0`` intervals (at most ``longest``).

    A single-interval edge is a step interval of :func:`step_intervals`; a longer one
    holds ``k1 - k0 - 1`` samples inside it, which the fit leaves out.

    ``span`` (phasor samples: :func:`smear_intervals`) is how many intervals a window
    spreads one step over. An edge's core is then also any ``span`` consecutive
    intervals over which the voltage moves by more than ``jump`` (those of them moving
    that way by more than the noise floor), not only a single interval that does: at 4
    phasors a cycle a step of 20% moves each of its intervals by about 5%, and read as a
    ramp through the window means (not a step) it biased f_m up by a fifth and T'
    five-fold (docs/composite.md, "Several phasors a window").
    """
    v = np.asarray(v, dtype=float)
    dv = np.diff(v)
    if dv.size == 0:
        return []
    single, core, noise = _cores(v, jump, span)
    out: list[tuple[int, int]] = []
    k = 0
    while k < dv.size:
        if not core[k]:
            k += 1
            continue
        # The run of core intervals moving the same way.
        k0, k1 = k, k + 1
        sign = np.sign(dv[k])
        while k1 < dv.size and core[k1] and np.sign(dv[k1]) == sign:
            k1 += 1
        big = float(np.max(np.abs(dv[k0:k1])))
        if not single[k0:k1].any():  # a smeared step: judged against its whole change
            big = max(big, abs(float(np.sum(dv[k0:k1]))))
        floor = max(grow * big, NOISE_SIGMAS * noise)

        def joins(i: int, sign=sign, floor=floor) -> bool:
            return 0 <= i < dv.size and np.sign(dv[i]) == sign and abs(dv[i]) > floor

        while k1 - k0 < longest and (joins(k0 - 1) or joins(k1)):
            # Grow toward the larger neighbour first.
            left = abs(dv[k0 - 1]) if joins(k0 - 1) else -1.0
            right = abs(dv[k1]) if joins(k1) else -1.0
            if left >= right:
                k0 -= 1
            else:
                k1 += 1
        grown_out = joins(k0 - 1) or joins(k1)
        if k1 - k0 == 1 and not grown_out:
            # One interval: a step if it stands out as before (RATIO), else a fast ramp.
            before = abs(dv[k0 - 1]) if k0 > 0 else 0.0
            after = abs(dv[k1]) if k1 < dv.size else 0.0
            if abs(dv[k0]) > RATIO * before and abs(dv[k0]) > RATIO * after:
                out.append((k0, k1))
        elif not grown_out and k1 - k0 <= longest and (not out or k0 >= out[-1][1]):
            out.append((k0, k1))
        k = k1
    return out


def _cores(v: NDArray[np.float64], jump: float, span: int):
    """``(single, core, noise)`` of :func:`edge_runs`: its core intervals and noise sd.

    ``single``: intervals moving by more than ``jump v0`` alone; ``core``: those, or a
    smeared step's body (``span > 1``, :func:`_smeared_core`); ``noise``: the robust sd
    of the interval-to-interval changes.
    """
    dv = np.diff(v)
    noise = 1.4826 * float(np.median(np.abs(dv - np.median(dv))))
    single = np.abs(dv) > jump * abs(v[0])
    core = single.copy()
    if span > 1 and dv.size >= span:
        core |= _smeared_core(dv, span, jump * abs(v[0]), NOISE_SIGMAS * noise)
    return single, core, noise


def _smeared_core(dv: NDArray[np.float64], span: int, limit: float, floor: float):
    """Intervals of a smeared step: in ``span`` intervals the voltage moves by ``limit``.

    Within each run of ``span`` intervals whose sum (the change from its first sample to
    its last) exceeds ``limit`` and none of which does alone, the intervals moving that
    way by more than half an even share of ``limit`` (and than ``floor``, the noise's):
    the step's body, not the drift beside it (a real fault's level moves by 0.1-0.2% a
    row; those and the step's partly covered end intervals join the edge by the growth
    rule of :func:`edge_runs`, judged against the whole step).
    """
    sums = np.convolve(dv, np.ones(span), mode="valid")  # sums[j] = dv[j : j + span].sum()
    # Runs holding an interval over ``limit`` are the single-interval rule's, as before.
    single = np.convolve(np.abs(dv) > limit, np.ones(span), mode="valid") > 0
    out = np.zeros(dv.size, dtype=bool)
    body = max(floor, 0.5 * limit / span)
    for j in np.flatnonzero((np.abs(sums) > limit) & ~single):
        part = dv[j : j + span]
        out[j : j + span] |= (np.sign(part) == np.sign(sums[j])) & (np.abs(part) > body)
    return out


def step_intervals(v: NDArray[np.float64], *, jump: float = JUMP, ratio: float = RATIO):
    """Indices ``k`` of the step intervals ``(t_k, t_k+1)`` of one voltage record."""
    v = np.asarray(v, dtype=float)
    dv = np.abs(np.diff(v))
    if dv.size == 0:
        return np.zeros(0, dtype=np.int64)
    before = np.concatenate([[0.0], dv[:-1]])
    after = np.concatenate([dv[1:], [0.0]])
    hit = (dv > jump * abs(v[0])) & (dv > ratio * before) & (dv > ratio * after)
    return np.flatnonzero(hit).astype(np.int64)


@dataclass(frozen=True)
class StepGrid:
    """Events' samples with two virtual knots in every edge, concatenated.

    A step interval's two knots sit side by side inside it; a ramp's (point samples
    inside the edge, kept) sit in its first and its last interval, the ramp's start and
    end (:func:`fill_times`).

    Attributes
    ----------
    t, v, delta : ndarray
        The augmented input (times of the virtual knots at ``phi = 1/2``).
    starts : ndarray of int
        Start of each event in the augmented arrays (and the end, last).
    real : ndarray of int
        Positions of the real samples in the augmented arrays, event after event.
    pos : ndarray of int
        Position of each edge's first virtual knot (a step's second follows it).
    left, width : ndarray
        ``t_k`` and ``t_k+1 - t_k`` of each edge's first interval.
    event_of, k_of : ndarray of int
        Each edge's event and first sample ``k`` in that event.
    pos_b : ndarray of int
        Position of each edge's second virtual knot (``pos + 1`` for a step).
    last, right : ndarray
        A ramp's last inside sample's time and its end sample's time (a step: the
        interval's end, twice).
    v_a, v_l, v_b : ndarray
        The voltage at the edge's first sample, its last inside sample and its end.
    """

    t: NDArray[np.float64]
    v: NDArray[np.float64]
    delta: NDArray[np.float64]
    starts: NDArray[np.int64]
    real: NDArray[np.int64]
    pos: NDArray[np.int64]
    left: NDArray[np.float64]
    width: NDArray[np.float64]
    event_of: NDArray[np.int64]
    k_of: NDArray[np.int64]
    pos_b: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    last: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    right: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    v_a: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    v_l: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    v_b: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def n_steps(self) -> int:
        """Number of edges (steps and ramps) over all events."""
        return int(self.pos.size)

    @property
    def n_ramps(self) -> int:
        """Ramps with a sampled start (one kept sample inside; longer ones are fixed knots)."""
        return int(np.sum(self.pos_b != self.pos + 1))

    @classmethod
    def build(
        cls,
        ts: Sequence[NDArray[np.float64]],
        vs: Sequence[NDArray[np.float64]],
        deltas: Sequence[NDArray[np.float64]],
        *,
        detect: bool = True,
        intervals: Sequence[NDArray[np.int64]] | None = None,
        ends: Sequence[NDArray[np.int64]] | None = None,
    ) -> StepGrid:
        """Augment each event's ``t, v, delta`` (``detect=False``: no steps, real only).

        ``intervals`` gives each event's edges' first samples (from :func:`edge_runs`,
        on the samples the fit keeps) instead of :func:`step_intervals`; ``ends`` their
        last samples (default: the next sample, a step interval). An edge with samples
        inside it is a ramp: knot ``A`` (``V_k0``) after its first sample, knot ``B``
        (``V_k1``) before its last.
        """
        t_out, v_out, d_out, real, pos, left, width, ev_of, k_of = ([] for _ in range(9))
        pos_b, last, right, v_a, v_l, v_b = ([] for _ in range(6))
        starts, offset = [0], 0
        for e, (t, v, d) in enumerate(zip(ts, vs, deltas, strict=True)):
            if not detect:
                ks = np.zeros(0, dtype=np.int64)
            elif intervals is not None:
                ks = np.asarray(intervals[e], dtype=np.int64)
            else:
                ks = step_intervals(v)
            k1s = ks + 1 if ends is None or not detect else np.asarray(ends[e], dtype=np.int64)
            n = t.size
            # Each real sample k moves right by one for every edge that starts before it
            # (knot A) and one for every edge that ends at or before it (knot B).
            ar = np.arange(n)
            shift = np.searchsorted(ks, ar, side="left") + np.searchsorted(k1s, ar, side="right")
            idx = ar + shift
            m = n + 2 * ks.size
            ta, va, da = np.empty(m), np.empty(m), np.empty(m)
            ta[idx], va[idx], da[idx] = t, v, d
            for k, k1 in zip(ks, k1s, strict=True):
                pa, pb = idx[k] + 1, idx[k1] - 1
                va[pa], va[pb] = v[k], v[k1]
                da[pa], da[pb] = d[k], d[k1]
                if k1 - k > 2:
                    # Two or more samples on the ramp: its line is theirs, and its ends
                    # are fixed knots, not sampled (a fraction there mixed slowly).
                    ta[pa], ta[pb] = ramp_ends(t[k : k1 + 1], v[k : k1 + 1])
                    continue
                pos.append(offset + pa)
                pos_b.append(offset + pb)
                lo = t[k] if k1 == k + 1 else ramp_start_bound(t[k : k1 + 1], v[k : k1 + 1])
                left.append(lo)
                width.append(t[k + 1] - lo)
                last.append(t[k1 - 1] if k1 > k + 1 else t[k + 1])
                right.append(t[k1])
                v_a.append(v[k])
                v_l.append(v[k1 - 1])
                v_b.append(v[k1])
                ev_of.append(e)
                k_of.append(k)
            t_out.append(ta)
            v_out.append(va)
            d_out.append(da)
            real.append(offset + idx)
            offset += m
            starts.append(offset)
        grid = cls(
            np.concatenate(t_out),
            np.concatenate(v_out),
            np.concatenate(d_out),
            np.array(starts, dtype=np.int64),
            np.concatenate(real).astype(np.int64),
            np.array(pos, dtype=np.int64),
            np.array(left, dtype=float),
            np.array(width, dtype=float),
            np.array(ev_of, dtype=np.int64),
            np.array(k_of, dtype=np.int64),
            np.array(pos_b, dtype=np.int64),
            np.array(last, dtype=float),
            np.array(right, dtype=float),
            np.array(v_a, dtype=float),
            np.array(v_l, dtype=float),
            np.array(v_b, dtype=float),
        )
        grid._fill(grid.t, np.full(grid.n_steps, 0.5))
        return grid

    def _fill(self, t: NDArray[np.float64], phi: NDArray[np.float64]) -> None:
        fill_times(t, self.pos, self.left, self.width, np.asarray(phi, dtype=float),
                   self.pos_b, self.last, self.right, self.v_a, self.v_l, self.v_b)  # fmt: skip

    def times(self, phi: NDArray[np.float64]) -> NDArray[np.float64]:
        """A copy of the augmented times with the steps at fractions ``phi``."""
        t = self.t.copy()
        self._fill(t, phi)
        return t

    def real_local(self, k: int) -> NDArray[np.int64]:
        """Positions of event ``k``'s real samples within its own augmented arrays."""
        r0, r1 = np.searchsorted(self.real, self.starts[k : k + 2])
        return self.real[r0:r1] - self.starts[k]

    def motor_input(self, k: int, t: NDArray[np.float64]):
        """Event ``k``'s augmented input (times ``t`` from :meth:`times`) and its real samples.

        Returns an :class:`~loadbayes.measurements.record.EventRecord` to drive the motor with and
        the positions of the real samples in it (the likelihood's only).
        """
        s0, s1 = self.starts[k], self.starts[k + 1]
        v = self.v[s0:s1]
        return EventRecord(t[s0:s1], v, v, v, self.delta[s0:s1]), self.real_local(k)

    def step_time(self, phi: NDArray[np.float64]) -> NDArray[np.float64]:
        """The instant of each step (s, the event's own clock), vectorised over draws.

        A step's is the middle of its ``eps`` ramp; a ramp's, its start (knot ``A``).
        """
        return self.left + self.width * (self._eps_offset() + phi * (1 - 3 * EPS_FRACTION))

    def _eps_offset(self) -> NDArray[np.float64]:
        # Where phi = 0 puts the instant, in intervals: 1.5 eps (a step), eps (a ramp).
        step = self.pos_b == self.pos + 1 if self.pos_b.size else np.ones(self.pos.size, bool)
        return np.where(step, 1.5, 1.0) * EPS_FRACTION

    def phi_of(self, times: NDArray[np.float64]) -> NDArray[np.float64]:
        """Inverse of :meth:`step_time`: each step's fraction from its instant."""
        frac = (np.asarray(times, dtype=float) - self.left) / self.width
        return np.clip((frac - self._eps_offset()) / (1 - 3 * EPS_FRACTION), 0.0, 1.0)


def ramp_start_bound(t: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """Earliest start of a straight ramp through one inside sample (``t, v``: 3 samples).

    The line from ``(t_a, v[0])`` through ``(t[1], v[1])`` reaches ``v[2]`` inside the last
    interval only when ``t_a`` is late enough; an earlier start had its end clamped at
    ``t[2]``, a kinked line the model does not mean, where the chains spent most of
    their time on a broad shoulder of ``t_a`` (docs/composite.md, "Ramps between point
    samples"). The bound is moved :data:`RAMP_START_MARGIN` of the interval earlier (the
    inside sample's noise moves it); the interval's start when the inside sample is not
    between the levels.
    """
    rise, rest = float(v[1] - v[0]), float(v[2] - v[1])
    if not rise * rest > 0.0:
        return float(t[0])
    a_lo = float(t[1]) - rise * float(t[2] - t[1]) / rest
    return float(max(a_lo - RAMP_START_MARGIN * float(t[1] - t[0]), t[0]))


def ramp_ends(t: NDArray[np.float64], v: NDArray[np.float64]) -> tuple[float, float]:
    """A ramp's start and end from its samples ``t[0] .. t[-1]`` (two or more inside).

    The least-squares line through the inside samples ``1 .. -2`` reaches ``v[0]`` at
    the start, kept inside the first interval, and ``v[-1]`` at the end, inside the last.
    """
    c1, c0 = np.polyfit(t[1:-1], v[1:-1], 1)
    eps_a, eps_b = EPS_FRACTION * (t[1] - t[0]), EPS_FRACTION * (t[-1] - t[-2])
    if c1 == 0.0 or not np.isfinite(c1):
        return 0.5 * (t[0] + t[1]), 0.5 * (t[-2] + t[-1])
    ta = min(max((v[0] - c0) / c1, t[0] + eps_a), t[1] - eps_a)
    tb = min(max((v[-1] - c0) / c1, t[-2] + eps_b), t[-1] - eps_b)
    return float(ta), float(tb)


def _trim_moving_level(
    v: NDArray[np.float64],
    k0: int,
    k1: int,
    *,
    core: NDArray[np.bool_] | None = None,
    floor: float = 0.0,
) -> tuple[int, int]:
    """An edge ``(k0, k1)`` less its end intervals where the level moves on.

    A ramp ends at a level: the interval after it moves by the noise. A step into a
    level that moves on (a grid's bus voltage after a fault: 0.95 to 0.676 at once,
    then 0.648, 0.623, 0.605 at 60/s in ANDES's IEEE 14-bus case) grows an edge over
    the level's first intervals, which move about as much as the ones after them; read
    as a ramp through those samples, the step was spread over a whole interval and the
    level made flat, and f_m came out 0.386-0.392 and T' 0.14 s for 0.400 and 0.50 s
    (NLS, noise-free; 0.388 and 0.23 s at 120/s). So an end interval of the edge that
    moves less than :data:`LEVEL_RATIO` times its outside neighbour, the same way, is
    the level's, not the edge's: it is dropped (from both ends, while the edge is longer
    than one interval), and the samples there draw the level.

    Phasor samples the same: the bus of a motor load answers the motor's current after a
    step (GridDyn's CMLD, a 41% sag: one-cycle window means 0.613, 0.588, 0.573, 0.565
    after it), the 2% growth of a window edge took those intervals in, and the edge was
    read as a ramp the phasors resolve (T' 0.7-1.7 s for 0.2, NLS, noise-free;
    docs/composite.md, "Edges that span samples"). A window also rounds a ramp's ends
    into tapers that shrink the same way, so with a window (:func:`FitSamples.find`)
    the trim stops at the edge's ``core`` (:func:`edge_runs`'s), and the level must move
    visibly: the interval outside by more than ``floor`` (the noise floor). A window's
    part of a step beside its core is kept by the level before the step, which does not
    move its way. On 1,500 random sags with flat levels (30-240/s, windows 1/60 and 1/50
    s, ramps 0-50 ms, noise 0-0.2%) no edge changes; on 1,500 with levels that move on,
    185 do.
    """
    dv = np.diff(v)

    def level(i: int, out: int) -> bool:
        return (
            0 <= out < dv.size
            and (core is None or not core[i])
            and abs(dv[out]) > floor
            and np.sign(dv[out]) == np.sign(dv[i])
            and abs(dv[i]) < LEVEL_RATIO * abs(dv[out])
        )

    while k1 - k0 > 1 and (level(k1 - 1, k1) or level(k0, k0 - 1)):
        if level(k1 - 1, k1):
            k1 -= 1
        else:
            k0 += 1
    return k0, k1


@numba.njit(cache=True, nogil=True)
def fill_times(t, pos, left, width, phi, pos_b, last, right, v_a, v_l, v_b):  # pragma: no cover
    """Put each edge's two virtual knots where ``phi`` puts them (in place).

    A step (``pos_b == pos + 1``): both at fraction ``phi`` of its interval, ``eps``
    apart. A ramp (samples inside it): its start ``A`` at fraction ``phi`` of the first
    interval; its end ``B`` in the last interval where the line from ``A`` through the
    last inside sample ``(last, v_l)`` reaches the level after, ``v_b`` (kept inside
    that interval; at its start when the inside sample is already past ``v_b``).
    """
    for j in range(pos.size):
        eps = EPS_FRACTION * width[j]
        a = left[j] + eps + phi[j] * (width[j] - 3.0 * eps)
        t[pos[j]] = a
        if pos_b[j] == pos[j] + 1:
            t[pos_b[j]] = a + eps
            continue
        eps_b = EPS_FRACTION * (right[j] - last[j])
        slope = (v_l[j] - v_a[j]) / (last[j] - a)
        rest = v_b[j] - v_l[j]
        tb = last[j] + rest / slope if rest * slope > 0.0 else last[j]
        t[pos_b[j]] = min(max(tb, last[j] + eps_b), right[j] - eps_b)


@dataclass(frozen=True)
class FitSamples:
    """Which samples of each event the fit reads, and its edges among them.

    ``keep[e]``: indices of event ``e``'s samples in the fit (with a window, the samples
    inside an edge left out; point samples keep them all); ``intervals[e]``: each
    edge's first sample, ``ends[e]`` its last, indices into the kept samples (a step
    interval: the next one); ``edges[e]``: the edges ``(k0, k1)`` in the event's own
    sample indices.
    """

    keep: list[NDArray[np.int64]]
    intervals: list[NDArray[np.int64]]
    edges: list[list[tuple[int, int]]]
    ends: list[NDArray[np.int64]] | None = None

    @property
    def left_out(self) -> int:
        """Samples left out over all events, inside an edge with a window.

        All of a step's; those of a ramp whose window reaches past its ends.
        """
        return int(
            sum(
                int(np.sum(~np.isin(np.arange(k0 + 1, k1), keep)))
                for ev, keep in zip(self.edges, self.keep, strict=True)
                for k0, k1 in ev
            )
        )

    @property
    def ramps(self) -> int:
        """Edges read as ramps through their kept inside samples, over all events."""
        ends = self.intervals if self.ends is None else self.ends
        return int(sum(np.sum(e - i > 1) for i, e in zip(self.intervals, ends, strict=True)))

    @classmethod
    def find(
        cls,
        ts: Sequence[NDArray[np.float64]],
        vs: Sequence[NDArray[np.float64]],
        *,
        window_s: float,
        detect: bool = True,
    ) -> FitSamples:
        """The edges of every event (``detect=False``: none, every sample kept).

        With a window (``window_s > 0``) the samples inside an edge are left out and the
        edge is one step interval between the kept ones; an edge longer than a step's
        (:func:`max_intervals`), a ramp the samples resolve, keeps the inside samples
        whose window lies wholly on the ramp (:func:`window_ramp_samples`) and is a ramp
        through them. Point samples (``window_s == 0``) are on the voltage's ramp: they
        are all kept, and an edge of up to :data:`RAMP_MAX_S` (:func:`ramp_intervals`)
        is a ramp through them.
        """
        keep, intervals, ends, edges = [], [], [], []
        for t, v in zip(ts, vs, strict=True):
            point = window_s <= 0
            grow = GROW if point else GROW_WINDOW
            longest = ramp_intervals(t) if point else window_ramp_intervals(t, window_s)
            span = smear_intervals(t, window_s)
            runs = edge_runs(v, longest=longest, grow=grow, span=span) if detect else []
            if point:
                runs = [_trim_moving_level(v, k0, k1) for k0, k1 in runs]
            elif runs:
                _, core, noise = _cores(np.asarray(v, dtype=float), JUMP, span)
                runs = [_trim_moving_level(v, k0, k1, core=core,
                                           floor=NOISE_SIGMAS * noise)
                        for k0, k1 in runs]  # fmt: skip
            mask = np.ones(t.size, dtype=bool)
            if not point:
                step = max_intervals(t, window_s)
                for k0, k1 in runs:
                    mask[k0 + 1 : k1] = False
                    if k1 - k0 > step:
                        mask[window_ramp_samples(t, k0, k1, window_s)] = True
            kept = np.flatnonzero(mask).astype(np.int64)
            # Each edge's first sample k0 and last k1 are kept: their places among the kept.
            intervals.append(np.searchsorted(kept, [k0 for k0, _ in runs]).astype(np.int64))
            ends.append(np.searchsorted(kept, [k1 for _, k1 in runs]).astype(np.int64))
            keep.append(kept)
            edges.append(runs)
        return cls(keep, intervals, edges, ends)
