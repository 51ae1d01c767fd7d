"""How a plain table's samples are read: point values, or a recorder's window means.

A record read by ``loadbayes read comtrade`` (and cut by ``loadbayes events``) knows its
phasor window: one cycle, stamped at its centre. A plain CSV says nothing of how it was
sampled, and the two readings differ where it matters: a simulator's point samples read
as one-cycle window means biased f_m low (an ANDES Motor5 event: 0.377 [0.359, 0.395]
for 0.400; with the samples inside a fault's edge left out and its ramp read as a step,
the fan motor's two sags: NLS f_m 0.376-0.381 against 0.389-0.391 as points), and a
recorder's window means read as points under-read the P jump after an edge
(docs/composite.md, "Phasor samples: window means").

:func:`choose_reading` fits both readings by the NLS of the fit's start
(:func:`~loadbayes.fit.composite.nls.nls`) and compares their maximised Gaussian
log-likelihoods (each channel's noise profiled out) on the samples both keep (the
window reading leaves out those whose window straddles an edge). A difference of at
least :data:`EVIDENCE` decides. Below it the data do not tell the two apart (a slow
motor, whose flux barely moves within a cycle), and the samples are read as points: the
readings then differ only at the fault's edges, where reading point samples as window
means threw the edge's own samples away and replaced its ramp by a step, the bias
measured above, while window means read as points moved f_m by less than its sd on the
same events (tests/independent_composite.py's fan and fast motors, 0.5% noise).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from loadbayes.core.parallel import one_blas_thread, run_threads
from loadbayes.fit.composite.nls import nls
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.measurements.record import EventRecord

__all__ = ["EVIDENCE", "SampleReading", "choose_reading", "reading_model"]

#: The log-likelihood difference that decides between the readings (a ratio of e^3, 20).
EVIDENCE = 3.0


@dataclass(frozen=True)
class SampleReading:
    """The reading chosen: ``window_s`` (0: points), the evidence and the words."""

    window_s: float
    delta_loglik: float  # points minus window means, on the samples both keep
    samples: int  # the samples both keep, over all events
    words: str
    #: The chosen reading's NLS estimate: the fit's start, which it need not run again.
    start: Any = field(default=None, repr=False, compare=False)

    def as_dict(self) -> dict[str, Any]:
        """The JSON record (``settings.sample_reading``)."""
        return {
            "read_as": "points" if self.window_s == 0 else "window means",
            "window_s": self.window_s,
            "chosen_by": "the data (no record of how the samples were taken)",
            "loglik_points_minus_window": round(self.delta_loglik, 3),
            "samples_compared": self.samples,
            "evidence_needed": EVIDENCE,
            "why": self.words,
        }


def _residuals(model: Any, events: list[EventRecord], prior: Any, window_s: float):
    """The NLS estimate, each event's kept sample indices and its P, Q residuals there."""
    problem = CompositeProblem(events, prior, f_hz=model.f_hz, torque=model.fixed_torque,
                               h_max=model.h_max, steps=model.steps,
                               window_s=window_s)  # fmt: skip
    est = nls(problem)
    chans = problem.channels(est.u)
    if chans is None:
        return None
    res = [(p - zp @ b, q - zq @ b) for ((zp, p), (zq, q)), b in zip(chans, est.betas, strict=True)]
    return est, problem.fit_samples.keep, res


@one_blas_thread  # two NLS fits of small least squares (core/parallel.py)
def choose_reading(model: Any, events: list[EventRecord]) -> SampleReading:
    """Point samples or one-cycle window means for a ``zip+motor`` fit, by the evidence.

    Parameters
    ----------
    model : CompositeModel
        The model as the command built it (its frequency, torque, steps); its own
        ``window_s`` is not used.
    events : list of EventRecord
        The events, in per unit.

    Returns
    -------
    SampleReading
        ``window_s`` 0 (points) or one cycle of ``model.f_hz``, and why.
    """
    cycle = 1.0 / model.f_hz
    prior = model.default_prior(events)
    fits: list[Any] = [None, None]

    def fit(k: int, window_s: float) -> None:
        fits[k] = _residuals(model, events, prior, window_s)

    # The two fits side by side: each is the same whichever thread runs it, and most of
    # each (the motor's compiled integration, LAPACK's least squares) releases the GIL.
    run_threads([lambda: fit(0, 0.0), lambda: fit(1, cycle)])
    point, window = fits
    if point is None or window is None:  # no feasible motor under one reading: the other
        w = cycle if point is None else 0.0
        return SampleReading(w, 0.0, 0, "only one reading had a feasible motor")
    ss_p, ss_w, n = np.zeros(2), np.zeros(2), 0
    for kp, rp, kw, rw in zip(*point[1:], *window[1:], strict=True):
        common = np.intersect1d(kp, kw)
        ip, iw = np.searchsorted(kp, common), np.searchsorted(kw, common)
        for c in range(2):
            ss_p[c] += float(rp[c][ip] @ rp[c][ip])
            ss_w[c] += float(rw[c][iw] @ rw[c][iw])
        n += int(common.size)
    with np.errstate(divide="ignore", invalid="ignore"):
        dl = float(np.sum(0.5 * n * np.log(ss_w / ss_p)))
    dl = dl if np.isfinite(dl) else 0.0
    size = f"{n} samples both readings keep"
    if dl >= EVIDENCE:
        return SampleReading(0.0, dl, n, (
            f"read as points: they fit better than one-cycle window means (log-"
            f"likelihood {dl:+.1f} on the {size}); --window-s to choose"), point[0])  # fmt: skip
    if dl <= -EVIDENCE:
        return SampleReading(cycle, dl, n, (
            f"read as one-cycle window means ({cycle:.6g} s): they fit better than point "
            f"samples (log-likelihood {-dl:+.1f} on the {size}); --window-s 0 reads them "
            "as points"), window[0])  # fmt: skip
    return SampleReading(0.0, dl, n, (
        f"read as points: the file carries no record of a phasor window, and "
        f"one-cycle window means fit no better (log-likelihood difference {dl:+.1f} on "
        f"the {size}, under {EVIDENCE:g}); --window-s {cycle:.6g} reads them as a "
        "recorder's window means"), point[0])  # fmt: skip


def reading_model(model: Any, events: list[EventRecord], *, chosen: bool) -> tuple[Any, Any]:
    """``(model, reading)``, the model read as the data say when nothing chose it.

    A ``zip+motor`` model whose reading is not ``chosen`` (no ``--window-s``, no record
    of the window beside the files) gets the data's (:func:`choose_reading`); any other
    model, or a chosen reading, stays as it is (reading None).
    """
    if chosen or model.name != "zip+motor":
        return model, None
    reading = choose_reading(model, events)
    return replace(model, window_s=reading.window_s), reading


def reading_note(reading: SampleReading | None, window_s: float | None, f_found: Any,
                 f_hz: float, *, model_window_s: float | None = None) -> str | None:  # fmt: skip
    """How the samples are read, and who said so: the data, ``--window-s`` or the record.

    ``f_found``: the record's index and frequency when the events came from one.
    ``model_window_s``: the window a model fixes itself (a model of parts, built by the
    command: ``--window-s`` is ``zip+motor``'s), None where the reading is the command's.
    """
    if model_window_s is not None:
        if model_window_s == 0:
            said = f" ({f_found[1]} says they are one-cycle phasors)" if f_found else ""
            return (f"point samples{said}: a model of parts reads each sample as the "
                    "load's P and Q at its stamp, not as a window's mean (window means "
                    "are zip+motor's, --window-s)")  # fmt: skip
        return f"samples read as {model_window_s:g}-s window means (the model's own)"
    if reading is not None:
        return f"samples {reading.words}"
    if window_s is not None:
        if window_s == 0:
            return "point samples (--window-s 0): the motor's P and Q at the sample instants"
        return f"samples read as {window_s:g}-s window means (--window-s)"
    if f_found:
        return (
            f"samples read as one-cycle window means ({1.0 / f_hz:.6g} s): {f_found[1]} says "
            "they are the record's phasors, estimated over one cycle"
        )
    return None
