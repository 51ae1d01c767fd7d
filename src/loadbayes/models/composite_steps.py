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
window allows (``max_intervals``). The samples inside an edge are left out of the fit
(their window straddles the change; how many is reported), and the edge becomes one
step interval from the sample before it to the sample after it, the step at an unknown
instant in it as above. A run longer than the window (a ramp that the samples resolve)
is left as the samples draw it.

Physics only: no sampling here. ``phi`` is sampled directly, uniform on [0, 1]
(fit/composite/problem.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "EPS_FRACTION",
    "GROW",
    "GROW_WINDOW",
    "JUMP",
    "NOISE_SIGMAS",
    "RATIO",
    "FitSamples",
    "StepGrid",
    "edge_runs",
    "fill_times",
    "max_intervals",
    "step_intervals",
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


def max_intervals(t: NDArray[np.float64], window_s: float) -> int:
    """The longest edge, in intervals, that a ``window_s`` phasor window can make.

    A step spreads over the samples whose window holds it (``window / dt`` of them)
    plus the interval it fell in; at least two intervals (a short ramp across a sample).
    With a window (phasor samples), one interval more: a short ramp's own, which the
    window smears further (a 20 ms ramp and a one-cycle window touch four 60/s samples).
    """
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    ramp = 1 if window_s > 0 else 0
    return max(2, int(np.ceil(window_s / dt - 1e-9)) + 1 + ramp)


def edge_runs(
    v: NDArray[np.float64], *, longest: int, jump: float = JUMP, grow: float = GROW
) -> list[tuple[int, int]]:
    """The edges of one voltage record: ``(k0, k1)``, from sample ``k0`` to ``k1``.

    The voltage moves across ``k1 - k0`` intervals (at most ``longest``).

    A single-interval edge is a step interval of :func:`step_intervals`; a longer one
    holds ``k1 - k0 - 1`` samples inside it, which the fit leaves out.
    """
    v = np.asarray(v, dtype=float)
    dv = np.diff(v)
    if dv.size == 0:
        return []
    noise = 1.4826 * float(np.median(np.abs(dv - np.median(dv))))
    core = np.abs(dv) > jump * abs(v[0])
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
    """Events' samples with two virtual knots in every step interval, concatenated.

    Attributes
    ----------
    t, v, delta : ndarray
        The augmented input (times of the virtual knots at ``phi = 1/2``).
    starts : ndarray of int
        Start of each event in the augmented arrays (and the end, last).
    real : ndarray of int
        Positions of the real samples in the augmented arrays, event after event.
    pos : ndarray of int
        Position of each step's first virtual knot (the second follows it).
    left, width : ndarray
        ``t_k`` and ``t_k+1 - t_k`` of each step interval.
    event_of, k_of : ndarray of int
        Each step's event and interval index ``k`` in that event.
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

    @property
    def n_steps(self) -> int:
        """Number of step intervals over all events."""
        return int(self.pos.size)

    @classmethod
    def build(
        cls,
        ts: Sequence[NDArray[np.float64]],
        vs: Sequence[NDArray[np.float64]],
        deltas: Sequence[NDArray[np.float64]],
        *,
        detect: bool = True,
        intervals: Sequence[NDArray[np.int64]] | None = None,
    ) -> StepGrid:
        """Augment each event's ``t, v, delta`` (``detect=False``: no steps, real only).

        ``intervals`` gives each event's step intervals (from :func:`edge_runs`, on the
        samples the fit keeps) instead of :func:`step_intervals`.
        """
        t_out, v_out, d_out, real, pos, left, width, ev_of, k_of = ([] for _ in range(9))
        starts, offset = [0], 0
        for e, (t, v, d) in enumerate(zip(ts, vs, deltas, strict=True)):
            if not detect:
                ks = np.zeros(0, dtype=np.int64)
            elif intervals is not None:
                ks = np.asarray(intervals[e], dtype=np.int64)
            else:
                ks = step_intervals(v)
            n = t.size
            # Each real sample k moves right by 2 for every step interval before it.
            shift = np.searchsorted(ks, np.arange(n), side="left") * 2
            idx = np.arange(n) + shift
            m = n + 2 * ks.size
            ta, va, da = np.empty(m), np.empty(m), np.empty(m)
            ta[idx], va[idx], da[idx] = t, v, d
            for k in ks:
                p = idx[k] + 1
                va[p], va[p + 1] = v[k], v[k + 1]
                da[p], da[p + 1] = d[k], d[k + 1]
                pos.append(offset + p)
                left.append(t[k])
                width.append(t[k + 1] - t[k])
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
        )
        fill_times(grid.t, grid.pos, grid.left, grid.width, np.full(grid.n_steps, 0.5))
        return grid

    def times(self, phi: NDArray[np.float64]) -> NDArray[np.float64]:
        """A copy of the augmented times with the steps at fractions ``phi``."""
        t = self.t.copy()
        fill_times(t, self.pos, self.left, self.width, np.asarray(phi, dtype=float))
        return t

    def real_local(self, k: int) -> NDArray[np.int64]:
        """Positions of event ``k``'s real samples within its own augmented arrays."""
        per_event = np.diff(self.starts) - 2 * np.bincount(
            self.event_of, minlength=self.starts.size - 1
        )
        r0 = int(np.sum(per_event[:k]))
        return self.real[r0 : r0 + per_event[k]] - self.starts[k]

    def motor_input(self, k: int, t: NDArray[np.float64]):
        """Event ``k``'s augmented input (times ``t`` from :meth:`times`) and its real samples.

        Returns an :class:`~loadbayes.models.composite.EventRecord` to drive the motor with and
        the positions of the real samples in it (the likelihood's only).
        """
        from loadbayes.models.composite import EventRecord

        s0, s1 = self.starts[k], self.starts[k + 1]
        v = self.v[s0:s1]
        return EventRecord(t[s0:s1], v, v, v, self.delta[s0:s1]), self.real_local(k)

    def step_time(self, phi: NDArray[np.float64]) -> NDArray[np.float64]:
        """The instant of each step (s, the event's own clock), vectorised over draws."""
        return self.left + self.width * (EPS_FRACTION * 1.5 + phi * (1 - 3 * EPS_FRACTION))

    def phi_of(self, times: NDArray[np.float64]) -> NDArray[np.float64]:
        """Inverse of :meth:`step_time`: each step's fraction from its instant."""
        frac = (np.asarray(times, dtype=float) - self.left) / self.width
        return np.clip((frac - 1.5 * EPS_FRACTION) / (1 - 3 * EPS_FRACTION), 0.0, 1.0)


@numba.njit(cache=True, nogil=True)
def fill_times(t, pos, left, width, phi):  # pragma: no cover - compiled
    """Put each step's two virtual knots at fraction ``phi`` of its interval (in place)."""
    for j in range(pos.size):
        eps = EPS_FRACTION * width[j]
        a = left[j] + eps + phi[j] * (width[j] - 3.0 * eps)
        t[pos[j]] = a
        t[pos[j] + 1] = a + eps


@dataclass(frozen=True)
class FitSamples:
    """Which samples of each event the fit reads, and its step intervals among them.

    ``keep[e]``: indices of event ``e``'s samples in the fit (the samples inside an
    edge left out); ``intervals[e]``: the step intervals, indices into the kept samples;
    ``edges[e]``: the edges ``(k0, k1)`` in the event's own sample indices.
    """

    keep: list[NDArray[np.int64]]
    intervals: list[NDArray[np.int64]]
    edges: list[list[tuple[int, int]]]

    @property
    def left_out(self) -> int:
        """Samples left out over all events."""
        return int(sum(k1 - k0 - 1 for ev in self.edges for k0, k1 in ev))

    @classmethod
    def find(
        cls,
        ts: Sequence[NDArray[np.float64]],
        vs: Sequence[NDArray[np.float64]],
        *,
        window_s: float,
        detect: bool = True,
    ) -> FitSamples:
        """The edges of every event (``detect=False``: none, every sample kept)."""
        keep, intervals, edges = [], [], []
        for t, v in zip(ts, vs, strict=True):
            grow = GROW_WINDOW if window_s > 0 else GROW
            runs = edge_runs(v, longest=max_intervals(t, window_s), grow=grow) if detect else []
            mask = np.ones(t.size, dtype=bool)
            for k0, k1 in runs:
                mask[k0 + 1 : k1] = False
            kept = np.flatnonzero(mask).astype(np.int64)
            # Each edge's first sample k0 is kept: its position among the kept samples.
            intervals.append(np.searchsorted(kept, [k0 for k0, _ in runs]).astype(np.int64))
            keep.append(kept)
            edges.append(runs)
        return cls(keep, intervals, edges)
