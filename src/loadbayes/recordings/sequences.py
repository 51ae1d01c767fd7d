"""Sequence components of phase phasors, and the mirror a moving phasor leaves in them.

The symmetrical components of phases ``a, b, c`` (``a = exp(j 2 pi / 3)``)::

    X0 = (Xa + Xb + Xc) / 3,   X1 = (Xa + a Xb + a^2 Xc) / 3,   X2 = (Xa + a^2 Xb + a Xc) / 3

The mirror. A one-cycle phasor (the DFT, or the least-squares fit of
:mod:`~loadbayes.recordings.phasor_fit` on whole evenly spaced cycles) of a channel
``x(t) = sqrt(2) Re(P(t) exp(j w t))`` whose phasor moves, ``P = P(c) + P' (t - c)``
over the window centred at ``c``, is::

    P(c) + (1/T) int conj(P' tau) exp(-2j w (c + tau)) dtau = P(c) + j conj(P') exp(-2j w c) / (2 w)

and a curvature ``P'' (t - c)^2 / 2`` adds ``conj(P'') exp(-2j w c) / (4 w^2)`` (a flux
decaying with a time constant ``tau`` makes this ``1 / (2 w tau)`` of the first: 6-8% for
the 20-30 ms of a small motor)

(the ``exp(-j w t)`` half of the cosine, turning at ``-2w`` in the window, weighted by the
ramp). Over the three phases of a positive-sequence set ``P_k = X1 a^-k`` the mirrors
``conj(X1') a^k`` form a negative-sequence set: a positive sequence that moves (a motor's
current while its flux decays after a fault's step, ``dI1/dt`` of 10-20 p.u./s) puts
``j conj(dX1/dt) exp(-2j w c) / (2 w)`` into the measured ``X2``: 0.02 p.u. at 50 Hz, 4%
of a fault's I2 on the tests' generated record (``tests/sequence_generator.py``), where
the fault's own I2 is what is measured. The derivatives are known from the neighbouring
windows, so the mirror is taken out (:func:`demirror`; on that record it leaves about
1e-4 p.u. of the 0.02). Not in a window the mimic filter of ``--dc on`` read: the
filter's gain at ``-w`` is the conjugate of the one divided out at ``+w``, which turns
the mirror nearly over, and adds ``tau X1'`` to the window's ``X1``; there the mirror is
left in, and no derivative is taken through it (a window whose decaying offset
``--dc auto`` took out is a plain fit of the cleaned samples: its mirror is taken out). The
positive sequence's own mirror of a moving X2 (a few times smaller, and in ``v, p, q``,
whose values are kept as they were) is left too.
"""

from __future__ import annotations

import numpy as np

__all__ = ["demirror", "sequences"]

_A = np.exp(2j * np.pi / 3)


def sequences(ph: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zero, positive and negative sequence of phase phasors shaped (3, m)."""
    zero = ph.sum(axis=0) / 3.0
    pos = (ph[0] + _A * ph[1] + _A**2 * ph[2]) / 3.0
    neg = (ph[0] + _A**2 * ph[1] + _A * ph[2]) / 3.0
    return zero, pos, neg


def demirror(
    x2: np.ndarray,
    x1: np.ndarray,
    t_s: np.ndarray,
    f_hz: float,
    bad: np.ndarray,
    sample_s: float | None = None,
) -> np.ndarray:
    """``X2`` less the mirror of the moving ``X1`` (module docstring).

    Parameters
    ----------
    x2, x1 : numpy.ndarray
        Negative and positive sequence at the window centres, shape (m,).
    t_s : numpy.ndarray
        Window centres (s) in the time of the phasors' frame (``exp(j w t)``).
    f_hz : float
        The frame's frequency.
    bad : numpy.ndarray of bool
        Windows across a step: no derivative is taken through them. A window with no
        good neighbour keeps its ``X2`` as it is.
    sample_s : float, optional
        The sampling interval. A window of ``N`` samples at ``t_n = c - T/2 + n dt``
        weighs the ramp by ``K1 = mean(tau_n exp(-2j w tau_n)) = dt / (exp(-2j w dt) -
        1)`` rather than the integral's ``j / (2 w)`` (``1 + j pi / N`` times it: 5%
        off at 64 samples per cycle, 16% at 20), and the curvature by ``K2 =
        mean(tau_n^2 exp(-2j w tau_n)) / 2``; both are summed over the window's offsets.
        None: the integrals.

    Returns
    -------
    numpy.ndarray
        ``x2 - (conj(X1') K1 + conj(X1'') K2) exp(-2j w t)``, the derivatives from
        three neighbouring good windows (:func:`_derivatives`).
    """
    m = t_s.size
    if m < 2:
        return x2
    w = 2.0 * np.pi * f_hz
    slope, curve = _derivatives(x1, float(np.median(np.diff(t_s))), ~np.asarray(bad, bool))
    k1, k2 = 1j / (2.0 * w), 1.0 / (4.0 * w * w)
    n = int(round(1.0 / (f_hz * sample_s))) if sample_s else 0
    if n >= 4:
        tau = (np.arange(n) - 0.5 * n) * sample_s
        turn = np.exp(-2j * w * tau)
        k1, k2 = np.mean(tau * turn), 0.5 * np.mean(tau * tau * turn)
    mirror = np.conj(slope) * k1 + np.conj(curve) * k2
    return x2 - mirror * np.exp(-2j * w * t_s)


def _derivatives(x: np.ndarray, h: float, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Slope and curvature of ``x`` sampled every ``h``, through good points only.

    Three points: centred where both neighbours are good, else the two after (a window
    just past a step) or the two before; two points (slope alone) where only one
    neighbour is good; nothing where none is, or the window itself is bad.
    """
    m = x.size
    ok = np.broadcast_to(ok, (m,))
    pad = np.concatenate([np.zeros(2, complex), x, np.zeros(2, complex)])
    good = np.concatenate([np.zeros(2, bool), ok, np.zeros(2, bool)])

    def at(k: int) -> tuple[np.ndarray, np.ndarray]:  # x[i + k] and whether it is good
        return pad[2 + k : 2 + k + m], good[2 + k : 2 + k + m]

    (xm2, gm2), (xm1, gm1), (x0, _), (xp1, gp1), (xp2, gp2) = (at(k) for k in (-2, -1, 0, 1, 2))
    slope = np.zeros(m, complex)
    curve = np.zeros(m, complex)
    rules = [  # (where, slope, curvature), the first that applies wins
        (gm1 & gp1, (xp1 - xm1) / (2 * h), (xp1 - 2 * x0 + xm1) / h**2),
        (gp1 & gp2, (-3 * x0 + 4 * xp1 - xp2) / (2 * h), (x0 - 2 * xp1 + xp2) / h**2),
        (gm1 & gm2, (3 * x0 - 4 * xm1 + xm2) / (2 * h), (x0 - 2 * xm1 + xm2) / h**2),
        (gp1, (xp1 - x0) / h, 0.0),
        (gm1, (x0 - xm1) / h, 0.0),
    ]
    done = ~ok
    for where, s, c in rules:
        use = where & ~done
        slope = np.where(use, s, slope)
        curve = np.where(use, c, curve)
        done = done | use
    return slope, curve
