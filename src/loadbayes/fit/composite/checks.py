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
from loadbayes.models.composite import EventRecord
from loadbayes.models.composite_steps import step_intervals

__all__ = ["T_PRIME_INTERVALS", "convergence_warnings", "jumps", "sampling_warnings"]

#: T' shorter than this many sample intervals is where a misplaced step biases it.
T_PRIME_INTERVALS = 10.0


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
    import warnings

    from loadbayes.posterior import import_arviz

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rhat = {n: float(import_arviz().rhat(draws[n])) for n in names}
    slow = [n for n, r in rhat.items() if not r < RHAT_MAX]
    if not slow:
        return []
    return [
        "the chains have not converged for "
        + ", ".join(f"{n} (R-hat {rhat[n]:.3f})" for n in slow)
        + ": run longer (--draws, --burn)"
    ]
