"""The decaying offset in a phasor's window: found over two cycles, and estimated.

After a voltage step a motor's (or a line's) current carries a decaying DC offset. Over
one cycle it cannot be told from a phasor that moves (a motor's current after the step
moves with its flux), nor fitted beside the harmonics without a large cost; over the
window's cycle and the next, and in a three-phase set's space vector, it can:
:func:`offset_test` tests each window for an offset and estimates it there, for
:func:`~loadbayes.recordings.phasor_fit.fit_phasors` to take it out of the window's
samples (that module's docstring derives the method and gives what was measured).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import f as f_dist

__all__ = ["lstsq", "max_harmonic", "offset_test"]

#: Highest harmonic modelled in a window (fewer when the window holds few samples).
HARMONICS = 7
#: False-alarm rate of the test that adds the decay columns to a channel's window.
DECAY_ALPHA = 1e-3
#: Smallest RMS share of a window's signal that the decay columns must explain before
#: the offset is taken out right after a step (a smaller one moves the phasor by less).
DECAY_MIN_SHARE = 0.005
#: Relative misfit of a voltage channel's plain fit above which a window straddles a step.
STEP_LIMIT = 0.02
#: Time constants (in cycles) of the fast changes of a phasor the three-phase decay test
#: allows for (a motor's flux after a step: ``T' X' / X``, a few milliseconds).
FAST_FLUX_CYCLES = (0.125, 0.25, 0.5)
#: Time constants (in cycles) of the decaying offset whose best fit is taken out.
OFFSET_CYCLES = (0.5, 1.0, 2.0, 4.0, 8.0)
#: Fewest residual degrees of freedom for the decay test to be made at all.
MIN_DOF = 8
_A = np.exp(2j * np.pi / 3)


def max_harmonic(samples: int) -> int:
    """Highest harmonic a window of ``samples`` points can carry beside 5 other columns."""
    return max(1, min(HARMONICS, (samples - 8) // 2 + 1))


def f_critical(dof: int, num: int = 2) -> float:
    """The F(num, dof) value exceeded with probability DECAY_ALPHA."""
    return float(f_dist.isf(DECAY_ALPHA, num, dof))


def lstsq(
    a: np.ndarray, xx: np.ndarray, pinv: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients and residual sum of squares of each window of ``xx`` (..., m) on ``a``.

    ``pinv`` is ``a``'s pseudo-inverse when the caller has it already.
    """
    coef = np.einsum("pm,...m->...p", np.linalg.pinv(a) if pinv is None else pinv, xx)
    return coef, np.sum(np.abs(xx - np.einsum("...p,mp->...m", coef, a)) ** 2, axis=-1)


def offset_test(
    u: np.ndarray, xx: np.ndarray, period: float, w: float, steps: int, sets=(), proj=None
) -> tuple[np.ndarray, ...]:
    """Where a channel's window holds a decaying offset: read over it and the next cycle.

    Within one cycle a decaying offset cannot be told from a fundamental whose amplitude
    or phase moves (a motor's current after a voltage step changes with its flux within
    a cycle): with the harmonics' columns present, an offset's ramp and a moving phasor
    each lie almost in the span of the others, and a test of the one fires on the other.
    Two things part them:

    - **two cycles** (``u``: the window's cycle and the next, times from its centre):
      the harmonics repeat each cycle, an offset's ramp does not;
    - **a three-phase set** (``sets``: channel triples a, b, c): in the space vector
      ``(2/3)(x_a + a x_b + a^2 x_c)`` the positive-sequence fundamental turns at
      ``+w``, an offset stands still. A positive-sequence phasor that moves, however
      fast (the columns hold a quadratic and three decaying exponentials, of an eighth,
      a quarter and half a cycle, at ``+w``), stays at its frequency. The negative
      sequence is held constant over the two cycles: a moving one at ``-w`` and an
      offset are again nearly confounded (measured on a 20 ms offset: F 794 with the
      negative sequence constant, 165 with it linear, 31 quadratic), so an unbalanced
      fault's first cycles can still fire the test. Without the set, a single
      channel's fast-moving phasor is as well explained by an offset as the offset
      itself (measured: a 5 ms flux decay of a motor after a step), so outside a set
      the null holds only the quadratic phasor.

    The null (the moving fundamental, the harmonics 2..H of both sequences, a constant)
    against it plus an offset ramp and curvature: an F-test at :data:`DECAY_ALPHA`. The
    offset must also matter (on a near-noiseless record any model slip is
    "significant"): a single channel's must explain at least :data:`DECAY_MIN_SHARE` of
    its signal; a set, cleaned as one (all three channels or none), must have one of its
    phasors moved by the offset by at least :data:`DECAY_MIN_SHARE` (judged by
    :func:`_one_pass`: the set's null takes up much of an offset's ramp, so the share of
    the residual does not measure its size).

    The offset itself is estimated without the fast exponentials (they lie almost in the
    span of the quadratic phasor and the offset: with them its estimate's variance is
    600 times larger): for a set, the exponential of :data:`OFFSET_CYCLES` that fits the
    space vector best; for a single channel, the ramp and curvature of its test. The
    follow-up test (``follow``) is that fit's F-test against the same columns without
    the offset, at :data:`DECAY_ALPHA` (for a single channel: its own test).

    Returns the test and the follow-up test per channel and window, shape (k, g); where a
    voltage channel (the first ``steps``) straddles a step in the two cycles (no test
    there; shape (g,)); and the offset's share of each window's phasor (``proj``: the
    one-cycle fit's row for the phasor, over the window's samples), shape (k, g), before
    the window's turn. Windows with less than two cycles of samples (a segment's end)
    are not tested.
    """
    k, g, m2 = xx.shape
    use = np.zeros((k, g), dtype=bool)
    across = np.zeros(g, dtype=bool)
    off = np.zeros((k, g, len(OFFSET_CYCLES)), dtype=complex)
    follow = np.zeros(off.shape, dtype=bool)
    best = np.zeros((k, g), dtype=int)
    score = np.zeros(off.shape)
    if m2 < 4 or u[-1] - u[0] < 1.5 * period:
        return use, follow, best, score, across, off
    r = u / period
    harmonics = range(2, max_harmonic(m2 // 2) + 1)
    offset = [r, r * r]
    # One channel at a time: a quadratic phasor, the harmonics, a constant; fitted to
    # the voltages (the step check) and to the channels outside the sets (their test).
    single = np.array([c for c in range(k) if not any(c in s for s in sets)], dtype=int)
    fitted = np.union1d(np.arange(min(steps, k)), single)
    cols = [np.ones(m2)]
    for p in range(3):
        cols += [r**p * np.cos(w * u), r**p * np.sin(w * u)]
    for h in harmonics:
        cols += [np.cos(h * w * u), np.sin(h * w * u)]
    a = np.column_stack(cols)
    ssq = np.sum(xx[fitted] ** 2, axis=2)
    _, rss = lstsq(a, xx[fitted])
    if steps > 0:
        v = fitted < steps
        across = np.any(rss[v] > STEP_LIMIT**2 * ssq[v], axis=0)
    dof = m2 - a.shape[1] - 2
    on = np.isin(fitted, single)
    if dof >= MIN_DOF and on.any():
        coef_b, rss_b = lstsq(np.column_stack([a, *offset]), xx[fitted[on]])
        poly = coef_b[..., -2:] @ (np.column_stack(offset)[: proj.size].T @ proj)
        off[fitted[on]] = poly[..., None]
        with np.errstate(invalid="ignore", divide="ignore"):
            f_stat = 0.5 * (rss[on] - rss_b) / (rss_b / dof)
        big = rss[on] - rss_b > DECAY_MIN_SHARE**2 * ssq[on]
        use[fitted[on]] = (f_stat > f_critical(dof)) & big
        follow[fitted[on]] = use[fitted[on], :, None]
    # A three-phase set: its space vector.
    turn = np.exp(1j * w * u)
    cols = [np.ones(m2, dtype=complex), np.conj(turn)]
    cols += [turn * r**p for p in range(3)]
    cols += [turn * np.exp(-(r - r[0]) / f) for f in FAST_FLUX_CYCLES]
    for h in harmonics:
        cols += [turn**h, np.conj(turn) ** h]
    a = np.column_stack(cols)
    b = np.column_stack([a, *offset])
    dof = 2 * (m2 - a.shape[1] - 2)
    if not sets or dof < MIN_DOF:
        return use, follow, best, score, across, off
    pinv_a, pinv_b = np.linalg.pinv(a), np.linalg.pinv(b)
    # The offset's estimate, and the test that follows it: the same columns without
    # the fast exponentials, which lie almost in the span of the phasor's quadratic and
    # the offset (with them, the offset's estimate has 600 times the variance).
    slow = np.r_[0:5, 5 + len(FAST_FLUX_CYCLES) : a.shape[1]]
    e0 = a[:, slow]
    pinv_e0 = np.linalg.pinv(e0)
    dof_d = 2 * (m2 - e0.shape[1] - 1)
    # Each exponential beside e0 (Frisch-Waugh): its part orthogonal to e0's span, whose
    # inner product with e0's residual gives its coefficient and the drop in misfit.
    decays = np.column_stack([np.exp(-(r - r[0]) / c) for c in OFFSET_CYCLES])
    perp = decays - e0 @ (pinv_e0 @ decays)
    norm = np.sum(np.abs(perp) ** 2, axis=0)
    for chans in sets:
        ia, ib, ic = chans
        z = (2.0 / 3.0) * (xx[ia] + _A * xx[ib] + _A * _A * xx[ic])
        _, rss_z = lstsq(a, z, pinv_a)
        _, rss_zb = lstsq(b, z, pinv_b)
        coef_e0, rss_e0 = lstsq(e0, z, pinv_e0)
        inner = (z - coef_e0 @ e0.T) @ np.conj(perp)  # (g, len(OFFSET_CYCLES))
        # The offset, an exponential of each time constant: its space vector D e(t) is
        # phase n's Re(D conj(a)^n) e(t), whose phasor is taken out.
        drop = np.abs(inner) ** 2 / norm
        size = inner / norm
        share = decays[: proj.size].T @ proj
        for n, c in enumerate(chans):
            off[c] = (size * np.conj(_A) ** n).real * share
        best[list(chans)] = np.argmax(drop, axis=1)[None, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            f_stat = 0.25 * (rss_z - rss_zb) / (rss_zb / dof)
        # How much an offset matters is judged on the phasors (by the caller): here the
        # null takes up much of an offset's ramp, so its share of the residual is no
        # measure of its size.
        use[list(chans)] = (f_stat > f_critical(dof, 4))[None, :]
        rss_d = rss_e0[:, None] - drop
        with np.errstate(invalid="ignore", divide="ignore"):
            f_stat = 0.5 * drop / (rss_d / dof_d)
        follow[list(chans)] = (f_stat > f_critical(dof_d, 2))[None, ...]
        with np.errstate(invalid="ignore", divide="ignore"):
            score[list(chans)] = np.nan_to_num(drop / rss_e0[:, None])[None, ...]
    return use, follow, best, score, across, off
