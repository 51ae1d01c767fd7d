"""The model error of a held-out prediction: an AR(1) discrepancy beside white noise.

``fit/composite/model_error.py`` on records written here with SciPy, not by the package:
a load's response to a voltage sag (``scipy.signal.lsim`` of a first-order recovery), an
AR(1) model error (``scipy.signal.lfilter`` from its stationary start) and white noise.
The discrepancy is fitted on one event and the band of a new observation is scored on
another event of the same load, the way the real-record study scores the reclose.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import signal

from loadbayes.fit.composite.model_error import (
    Discrepancy,
    discrepancy_band,
    error_split,
    fit_discrepancy,
    held_out_error,
    noise_floor,
)
from loadbayes.fit.composite.validate import band_scores

DT = 0.005  # four phasors a cycle at 50 Hz
SD_D, RHO, SD_E = 0.01, 0.7, 0.002


def _response(n: int, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """P of a load with a first-order recovery (T 0.05 s) to a sag from row 40 to 50."""
    t = np.arange(n) * DT
    v = np.where((t >= 40 * DT) & (t < 50 * DT), 1.0 - depth, 1.0)
    sys = signal.lti([0.6 * 0.05, 0.0], [0.05, 1.0])  # dP = 0.6 s T / (1 + s T) dV
    _, dp, _ = signal.lsim(sys, v - 1.0, t)
    return t, 1.0 + 2.0 * (v - 1.0) + dp


def _ar1(n: int, rng) -> np.ndarray:
    """A stationary AR(1) series of variance SD_D^2, coefficient RHO per row."""
    w = rng.standard_normal(n) * SD_D * np.sqrt(1 - RHO**2)
    x0 = rng.standard_normal() * SD_D
    return signal.lfilter([1.0], [1.0, -RHO], w, zi=[RHO * x0])[0]


def test_fit_discrepancy_recovers_a_known_ar1_error_across_a_gap():
    rng = np.random.default_rng(11)
    n = 400
    t = np.arange(n) * DT
    r = _ar1(n, rng) + SD_E * rng.standard_normal(n)
    keep = np.ones(n, bool)
    keep[200:215] = False  # rows left out (a fault's edge): rho ** 16 across the gap
    d = fit_discrepancy(r[keep], t[keep], SD_E**2)
    # About 70 effective rows: the ML sd within 25 % (3 of its standard errors) and rho
    # within 0.1 (3 of its 0.03); a rho read per row rather than per interval would be
    # pulled down by the gap's uncorrelated pair.
    assert d.sd_d == pytest.approx(SD_D, rel=0.25)
    assert d.rho == pytest.approx(RHO, abs=0.1)
    assert d.sd_e == pytest.approx(SD_E)
    assert d.share == pytest.approx(d.sd_d**2 / (d.sd_d**2 + SD_E**2))


def test_white_residuals_give_no_model_error_coefficient():
    rng = np.random.default_rng(5)
    r = 0.003 * rng.standard_normal(300)
    d = fit_discrepancy(r, np.arange(300) * DT, noise_floor(r))
    # White residuals: the noise floor is their whole variance; what the fit leaves to d
    # is small beside it or uncorrelated.
    assert d.sd_d < 0.003 or d.rho < 0.2


@pytest.mark.statistical
def test_band_of_a_new_observation_covers_at_the_nominal_rate():
    """Fitted on one sag, scored on another: 95 % of new observations inside the band.

    150 loads; each: the discrepancy fitted on a 12 % sag (120 rows, the noise floor from
    the 40 rows before it) and the band scored on a 25 % sag at 6 rows 20 apart
    (correlation 0.7^20 < 1e-3): 900 nearly independent hits, binomial sd 0.7 %. The
    plug-in of s_d and rho (about 20 effective rows) makes the band narrow by about 1 %
    of coverage; the check takes [0.915, 0.985] (-5, +5 sd of the binomial about 0.95
    with that bias): false alarm well under 1 %. Without the model error (the noise
    floor alone) the same band covers about 30 % (seeds 1, 2: 29 %), which the check rejects.
    """
    rng = np.random.default_rng(2026)
    n, rows = 120, np.arange(10, 120, 20)
    _, m0 = _response(n, 0.12)
    _, m1 = _response(n, 0.25)
    t = np.arange(n) * DT
    hits, white_hits = [], []
    for _ in range(150):
        y0 = m0 + _ar1(n, rng) + SD_E * rng.standard_normal(n)
        y1 = m1 + _ar1(n, rng) + SD_E * rng.standard_normal(n)
        d = fit_discrepancy(y0 - m0, t, noise_floor(y0[:40]))
        lo, hi = discrepancy_band(m1, np.zeros(n), d)
        hits.append((y1[rows] >= lo[rows]) & (y1[rows] <= hi[rows]))
        lo, hi = discrepancy_band(m1, np.zeros(n), Discrepancy(0.0, 0.0, SD_E, n))
        white_hits.append((y1[rows] >= lo[rows]) & (y1[rows] <= hi[rows]))
    cover = float(np.mean(hits))
    assert 0.915 <= cover <= 0.985, cover
    assert float(np.mean(white_hits)) < 0.5


def test_error_split_reads_an_offset_the_fitted_event_never_showed():
    d = Discrepancy(sd_d=0.01, rho=0.5, sd_e=0.002, n=80)
    resid = np.full(50, 0.03)  # a steady 3 % offset: mean square 9e-4
    spread = np.full(50, 0.004)
    s = error_split(resid, spread, d)
    assert s["mse"] == pytest.approx(9e-4)
    assert s["noise"] == pytest.approx(4e-6 / 9e-4)
    assert s["parameters"] == pytest.approx(1.6e-5 / 9e-4)
    assert s["form_seen"] == pytest.approx(1e-4 / 9e-4)
    assert s["beyond"] == pytest.approx(1 - (4e-6 + 1.6e-5 + 1e-4) / 9e-4)
    assert s["form"] == pytest.approx(s["form_seen"] + s["beyond"])


def _validation(t, x, mean, spread, scored):
    band = {"p_mean": mean, "q_mean": mean, "p_spread": spread, "q_spread": spread}
    return SimpleNamespace(event=SimpleNamespace(t=t, p=x, q=x), band=band, scored=scored)


def test_held_out_error_fits_on_the_first_event_and_scores_the_second():
    rng = np.random.default_rng(8)
    n = 120
    t, m0 = _response(n, 0.12)
    _, m1 = _response(n, 0.25)
    y0 = m0 + _ar1(n, rng) + SD_E * rng.standard_normal(n)
    y1 = m1 + 0.05  # the second event sits 5 % above anything the first showed
    scored = np.ones(n, bool)
    scored[40:50] = False
    fitted = _validation(t, y0, m0, np.zeros(n), scored)
    held = _validation(t, y1, m1, np.zeros(n), scored)
    out = held_out_error(fitted, held, t_fault=40 * DT)
    d = out["p"]["disc"]
    assert d.sd_e == pytest.approx(np.sqrt(noise_floor(y0[:40])))
    ref = fit_discrepancy((y0 - m0)[scored], t[scored], noise_floor(y0[:40]))
    assert d == ref
    lo, hi = discrepancy_band(m1[scored], np.zeros(scored.sum()), ref)
    assert out["p"]["coverage"] == float(np.mean((y1[scored] >= lo) & (y1[scored] <= hi)))
    assert out["p"]["coverage"] < 0.2  # 5 sd_d out: a band the fit states misses it
    assert out["p"]["split"]["beyond"] > 0.9


def test_band_scores_give_the_draws_spread_of_the_response():
    rng = np.random.default_rng(1)
    means = [1.0 + 0.01 * rng.standard_normal(30) for _ in range(50)]
    noisy = [m + 0.02 * rng.standard_normal(30) for m in means]
    event = SimpleNamespace(p=np.ones(30), q=np.ones(30))
    band, _ = band_scores(event, np.ones(30, bool), (noisy, noisy), (means, means), 1.0, 0.95)
    assert np.allclose(band["p_spread"], np.std(np.array(means), axis=0))
    assert np.allclose(band["q_mean"], np.mean(np.array(means), axis=0))
