"""``loadbayes validate``'s band: the fitted events' playback error widens it, or not.

The events come from ``tests/sag_generator.py``: a ZIP part and a third-order induction
motor integrated by SciPy's ``solve_ivp`` (the equations of docs/composite.md, its own
steady state by ``brentq``), driven by a sag with 5 ms ramps between samples; nothing of
the package's motor code makes them. One event is fitted (``fit_composite``, 2 chains x
1,500 iterations), six others at other depths, lengths and operating points are held out
(434-474 scored rows). Each case takes about 3 s.

Binomial margins: a band of exactly 95 % on n independent rows has sd sqrt(0.95 0.05 / n),
0.010 at n = 474 and 0.0105 at 434. The cases are fixed (seeds), so each assertion passes
or fails the same way every run; the false-alarm rates below are those of a fresh seed.

- Model true, point samples: the fitted event's playback misses it by the noise, and the
  band stays the fit's noise band (switching needs a chi-square excess at 1 %:
  ``validate_band.ALPHA``). Coverage asked 0.92-0.98 (3 sd below, 2.6 above: 0.6 % a
  channel) and the width within 5 % of the fit-noise band's.
- A slow extra reactive part the model lacks (a first-order lag of the voltage's fall,
  0.25 s, 0.10 P0 per unit of the fall), point samples: the fit's noise absorbs it (the
  fit reads it as the playback does), so the playback shows no more error than the fit's
  noise and the band stays (measured: fit noise 0.54 % of P0, playback 0.61 %).
- The same slow part read through one-cycle phasor windows (as the real record is): the
  fit reads the steps at fitted instants, the playback reads the voltage linearly between
  samples and misses Q by about twice the fit's noise (as ``zip+motor`` on the real
  record). The fit-noise band under-covers Q (asked at most 0.92: 2.8 sd under 95 %, a
  0.3 % chance were it nominal); the band with the playback's model error covers it
  (asked 0.93-0.995; measured 0.977, a band 1.2 times wider: the AR(1) spreads an error
  that lives after the steps over every row, so it is if anything wide).
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.fit.composite.validate import validate_events
from loadbayes.fit.composite.validate_band import BAND_FIT_NOISE, fitted_masks, honest_bands
from loadbayes.measurements.events import events_from_arrays
from loadbayes.models.zip_motor import CompositeModel
from sag_generator import F_HZ, sag

pytestmark = pytest.mark.statistical

NAMES = {k: k for k in ("t", "v", "p", "q", "f", "angle", "event")}


def _event(*, seed=0, **sag_kw):
    """One sag's EventRecord (tests/sag_generator.py), noise sd NOISE on P and Q."""
    cols = sag(seed=seed, **sag_kw)
    (ev,) = events_from_arrays(cols, np.arange(1, cols["t"].size + 1), path=f"sag {seed}",
                               names=NAMES, f_hz=F_HZ)  # fmt: skip
    return ev


FITTED = dict(depth=0.35, jump=0.08, t_fault=0.1012, hold=0.06, p0=0.9, q0=0.25, seed=2)
HELD = [dict(depth=0.3, jump=0.12, t_fault=0.1527, hold=0.071, p0=0.8, q0=0.2, v0=0.98, seed=1),
        dict(depth=0.25, jump=0.05, t_fault=0.1203, hold=0.09, p0=1.0, q0=0.3, seed=3),
        dict(depth=0.4, jump=0.1, t_fault=0.1308, hold=0.05, p0=0.85, q0=0.22, v0=1.01,
             seed=4),
        dict(depth=0.2, jump=0.06, t_fault=0.0911, hold=0.12, p0=0.95, q0=0.28, v0=0.99, seed=5),
        dict(depth=0.33, jump=0.09, t_fault=0.1406, hold=0.065, p0=0.75, q0=0.18, seed=6),
        dict(depth=0.28, jump=0.07, t_fault=0.1105, hold=0.08, p0=0.88, q0=0.24, v0=1.02,
             seed=7)]  # fmt: skip


def _bands(slow: bool, window: float = 0.0):
    """The fit-noise scores and the honest ones of the held-out events."""
    fitted = _event(**FITTED, slow=slow, window=window)
    held = [_event(**h, slow=slow, window=window) for h in HELD]
    run = SamplerSettings(draws=1500, burn=700, chains=2, seed=0)
    model = CompositeModel(f_hz=F_HZ, window_s=window)
    post = fit_composite(model, [fitted], sampler=run).posterior
    # The rows inside an edge (on a step's ramp, or straddling it): a recorder's flags.
    plain = validate_events(post, held, exclude=fitted_masks(held, window))
    own = validate_events(post, [fitted], exclude=fitted_masks([fitted], window))
    honest = honest_bands(post, plain, own)
    return plain, honest


def _cover(scores, ch):
    n = sum(int(s.scored.sum()) for s in scores)
    return sum(getattr(s, f"coverage_{ch}") * int(s.scored.sum()) for s in scores) / n


def _width(scores, ch):
    return float(np.mean(np.concatenate([(s.band[f"{ch}_hi"] - s.band[f"{ch}_lo"])[s.scored]
                                         for s in scores])))  # fmt: skip


def test_model_true_keeps_the_fit_noise_band():
    plain, honest = _bands(slow=False)
    for ch in ("p", "q"):
        assert getattr(honest[0], f"band_{ch}") == BAND_FIT_NOISE
        assert _width(honest, ch) == pytest.approx(_width(plain, ch), rel=0.05)
        assert 0.92 <= _cover(honest, ch) <= 0.98  # measured 0.954 P, 0.939 Q
        pb = honest[0].playback[ch]
        assert pb["rms"] < 1.25 * pb["fit_noise_sd"]  # measured 1.05, 1.11
    assert [s.coverage_fit_noise_p for s in honest] == [s.coverage_p for s in plain]


def test_a_slow_part_the_fit_reads_too_leaves_the_band():
    plain, honest = _bands(slow=True)
    for ch in ("p", "q"):
        assert getattr(honest[0], f"band_{ch}") == BAND_FIT_NOISE
        assert _cover(honest, ch) == _cover(plain, ch)  # measured 0.962 P, 0.920 Q


def test_what_the_playback_misses_widens_the_band():
    plain, honest = _bands(slow=True, window=1 / F_HZ)
    pb = honest[0].playback["q"]
    assert pb["rms"] > 1.5 * pb["fit_noise_sd"]  # measured 1.05 % of P0 against 0.50 %
    assert honest[0].band_q != BAND_FIT_NOISE
    assert _cover(plain, "q") <= 0.92  # measured 0.889
    assert 0.93 <= _cover(honest, "q") <= 0.995  # measured 0.977
    assert _width(honest, "q") > _width(plain, "q")
    # P's playback shows no more than the noise: its band is kept (measured 0.947).
    assert honest[0].band_p == BAND_FIT_NOISE and _cover(honest, "p") == _cover(plain, "p")
