"""What a composite fit cannot see in its recordings: warnings about the sampling itself.

The motor is driven by the measured voltage, linear between samples
(docs/composite.md). Two things a recording leaves out bias the fit without any sign in
the residuals, and both are measured on ANDES events (docs/composite.md, "Limits of a
sampled recording"):

- **A step between two samples.** A fault's voltage step falls somewhere inside one
  sample interval; the model reads it as a ramp across the interval. The motor's flux
  decays with T' meanwhile, so when T' spans only a few intervals the misplaced step
  is misread as a faster T'. (ANDES, Krause 3 hp motor, T' = 0.087 s, a 30% sag: at
  120 samples/s the 95% interval of T' was 0.012-0.023 s; at 960/s it covered 0.087.)
- **A phase jump read from a frequency column.** A fault or its clearing turns the bus
  voltage's angle by a step (0.16 rad in the ANDES Kundur case); a frequency signal is
  a filtered derivative and holds none of it, so the angle integrated from it is wrong
  from the first instant of the event. (ANDES Kundur case, bus 7, a 40% sag: the static
  P shares missed their intervals by far with ``f`` and were covered with the angle.)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from loadbayes.diagnostics import RHAT_MAX
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite_steps import step_intervals

__all__ = [
    "F_HZ_RANGE",
    "MIN_KEPT",
    "T_PRIME_INTERVALS",
    "check_run",
    "convergence_warnings",
    "jumps",
    "own_bases_warnings",
    "sampling_warnings",
    "start_warnings",
]

#: T' shorter than this many sample intervals is where a misplaced step biases it.
T_PRIME_INTERVALS = 10.0
#: Nominal frequencies a power system runs at, with room (Hz): 16.7 Hz rail to 400 Hz
#: aircraft. Outside it the motor's time base makes no sense (the NLS start failed).
F_HZ_RANGE = (10.0, 1000.0)
#: Fewest kept draws per chain: fewer and R-hat, ESS and the intervals mean nothing
#: (two identical kept draws were once reported as "well determined").
MIN_KEPT = 50
#: The voltage at the event's first sample more than this share below the level it
#: settles at (its last tenth): the event starts inside the sag, not in a steady state.
START_BELOW = 0.05
#: The first samples (this many seconds) vary by more than this share of V0: not steady.
START_SPAN_S, START_FLAT = 0.05, 0.02


def check_run(
    *, f_hz: float, draws: int, burn: int, thin: int, seed: object, max_seconds: float = 1.0
) -> None:
    """Refuse settings the composite fit cannot run, before any work (one line each).

    Raises
    ------
    loadbayes.io.errors.OptionError
        ``f_hz`` outside :data:`F_HZ_RANGE`, fewer than :data:`MIN_KEPT` kept draws per
        chain, a negative integer seed, or a time budget that is not a positive number.
    """
    from loadbayes.io.errors import OptionError

    lo, hi = F_HZ_RANGE
    if not (lo <= f_hz <= hi):
        raise OptionError(
            f"--f-hz {f_hz:g}: the nominal frequency must be between {lo:g} and {hi:g} Hz"
        )
    kept = len(range(burn, draws, thin))
    if kept < MIN_KEPT:
        raise OptionError(
            f"--draws {draws} --burn {burn} --thin {thin} keep {kept} draw(s) per chain; "
            f"the composite fit needs at least {MIN_KEPT} (R-hat, ESS and the intervals "
            "mean nothing with fewer)"
        )
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed < 0:
        raise OptionError(f"--seed {seed}: the seed must be a non-negative integer")
    if not (isinstance(max_seconds, (int, float)) and max_seconds > 0 and max_seconds < 1e9):
        raise OptionError(
            f"--max-seconds {max_seconds}: the time budget must be a positive number of seconds"
        )


def _head(e: EventRecord) -> np.ndarray | slice:
    """The samples before the event moves: within ``START_SPAN_S`` of its first, at least 3."""
    head = e.t <= e.t[0] + START_SPAN_S
    return head if head.sum() >= 3 else slice(0, 3)


def start_warnings(events: Sequence[EventRecord]) -> list[str]:
    """Plain-words warnings for an event that does not start in a steady state.

    The fit takes each event's first sample as the operating point before the
    disturbance (the motor's initial state, ``p0``, ``q0`` and ``v0``). An event cut
    inside a sag or during its recovery starts lower than it settles, or moving.
    """
    out = []
    for e in events:
        v0 = float(e.v[0])
        tail = float(np.median(e.v[-max(e.n // 10, 1) :]))
        head = e.v[_head(e)]
        span = float(np.ptp(head)) / abs(v0) if v0 else np.inf
        why = None
        if tail > v0 * (1 + START_BELOW):
            why = (f"its first voltage ({v0:.3g}) is {100 * (1 - v0 / tail):.0f}% below the "
                   f"level it ends at ({tail:.3g}): it starts inside the sag")  # fmt: skip
        elif span > START_FLAT:
            why = (f"its voltage moves by {100 * span:.1f}% in the first {head.size} samples: "
                   "it starts during a change")  # fmt: skip
        if why:
            out.append(
                f"{e.name or 'the event'} does not start in a steady state: {why}. The fit "
                "takes the first sample as the pre-disturbance operating point, so v0, p0, "
                "q0 and the motor refer to the wrong state: cut the event earlier (events "
                "--pre)"
            )
    return out


#: P and Q both this close to 1 before every event: each read per unit of its own
#: initial value (P/P0, Q/Q0), not of one base.
OWN_BASE_TOL = 0.01


def own_bases_warnings(events: Sequence[EventRecord]) -> list[str]:
    """A warning when P and Q look per unit of their own initial values (P/P0, Q/Q0).

    The model reads P and Q on one base: the motor's Q is tied to its P by its physics
    (one rating for both). Data given as P/P0 and Q/Q0 put Q on a base P0/Q0 times
    another, and the fit reads a different motor. The fan motor of issue 35 (Q0 = 0.72
    P0, written as P/P0 and Q/Q0): f_m 0.337 [0.308, 0.370] for 0.400 at the defaults;
    with q times Q0/P0 the truth's residuals are those of the best fit (NLS sum of squares
    within 1.1 of it; 1,425 worse before) and NLS gives f_m 0.389-0.391 (docs/composite.md,
    "Input"). Said when both P and Q are within :data:`OWN_BASE_TOL` of 1 before every
    event (two or more samples before the voltage moves): on one base that needs Q0 = P0.
    """
    for e in events:
        head = _head(e)
        p, q = float(np.median(e.p[head])), float(np.median(e.q[head]))
        if not (abs(p - 1) < OWN_BASE_TOL and abs(q - 1) < OWN_BASE_TOL):
            return []
    return [
        "P and Q are both 1.00 before every event: if each is per unit of its own initial "
        "value (P/P0, Q/Q0), Q is on another base than P, and the motor, whose Q the fit "
        "ties to its P, is misread (f_m and T' biased, intervals that miss): give both on "
        "one base (--s-base, or q times Q0/P0)"
    ]


def jumps(event: EventRecord) -> np.ndarray:
    """Indices ``k`` of the step intervals ``(t_k, t_k+1)`` (models/composite_steps.py)."""
    return step_intervals(event.v)


def sampling_warnings(
    events: Sequence[EventRecord], t_prime_s: np.ndarray, *, steps_modelled: bool = False
) -> list[str]:
    """Plain-words warnings about steps between samples and angles read from frequency.

    Parameters
    ----------
    events : sequence of EventRecord
        The recordings fitted.
    t_prime_s : ndarray
        Posterior draws of the motor's T' (s).
    steps_modelled : bool
        Whether the fit placed each step inside its interval (then T' is not biased by
        the ramp and only the angle is warned about).

    Returns
    -------
    list of str
        At most one warning of each kind.
    """
    out = []
    t_prime = float(np.median(t_prime_s))
    stepped = [(e, jumps(e)) for e in events]
    stepped = [(e, k) for e, k in stepped if k.size]
    if not stepped:
        return out
    dt = max(float(np.median(np.diff(e.t))) for e, _ in stepped)
    if not steps_modelled and t_prime < T_PRIME_INTERVALS * dt:
        e, k = stepped[0]
        out.append(
            f"the voltage steps by {100 * abs(e.v[k[0] + 1] - e.v[k[0]]) / e.v0:.0f}% within "
            f"one sample interval at t = {e.t[k[0]]:.4g} s ({e.name or 'event 0'}) and the "
            f"motor's T' (median {t_prime:.3g} s) spans fewer than "
            f"{T_PRIME_INTERVALS:g} sample intervals ({dt:.3g} s): the model reads the step "
            "as a ramp across the interval, which biases T' (low) and the motor's "
            "reactances; model the step's instant (the default) or record at a higher "
            "sampling rate"
        )
    from_f = [e for e, _ in stepped if e.angle_from == "frequency"]
    if from_f:
        out.append(
            f"the voltage angle of {from_f[0].name or 'event 0'} was integrated from its "
            "frequency column, which cannot hold the phase jump of a fault or its clearing "
            "(the voltage steps there): give the recorded voltage angle (angle_rad) if "
            "the recorder has it, or expect the motor share and the static shares to absorb "
            "the missing jump"
        )
    return out


def convergence_warnings(
    draws: dict[str, np.ndarray], names: Sequence[str], chains: int
) -> list[str]:
    """One warning naming the sampled coordinates whose R-hat is not below ``RHAT_MAX``.

    Only the sampled coordinates are judged (the motor's five and any torque
    log-ratios), and in the composite's own words: which ones, their R-hat, and that a
    longer run (``--draws``, ``--burn``) is the remedy. Nothing for a single chain.
    (:func:`loadbayes.diagnostics.sampler_warnings` judges every parameter of a summary
    table, with ESS and kept-draw warnings besides, in other words.)
    """
    if chains < 2:
        return []
    from loadbayes.core.convergence import summarize

    values = summarize(np.stack([draws[n] for n in names]), tail=False)["r_hat"]
    rhat = {n: float(r) for n, r in zip(names, values, strict=True)}
    slow = [n for n, r in rhat.items() if not r < RHAT_MAX]
    if not slow:
        return []
    return [
        "the chains have not converged for "
        + ", ".join(f"{n} (R-hat {rhat[n]:.3f})" for n in slow)
        + ": run longer (--draws, --burn)"
    ]
