"""Where a held-out prediction misses, and what a record says no model could know.

``studies/real_record_physical``'s measures, on records written here with NumPy: the
currents' 2nd harmonic before and after a sag, the split of a prediction's error over the
rows before the fault, the first cycles after clearing and the level after them, and two
faults' own responses compared with no model.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from loadbayes.studies.real_record_physical import (
    FIRST_CYCLES,
    _miss_words,
    faults_apart,
    reclose_miss,
    second_harmonic,
)

N = 64  # samples a cycle
F = 50.0


def _waves(h2_before: float, h2_after: float, sag: float = 0.8):
    """20 cycles: 6 before, 3 at ``sag``, 11 after; currents with the given 2nd harmonics."""
    c = np.arange(20 * N)
    cyc = c // N
    th = 2 * np.pi * c / N
    shift = np.array([0.0, -2 * np.pi / 3, 2 * np.pi / 3])[:, None]
    level = np.where((cyc >= 6) & (cyc < 9), sag, 1.0)
    v = level * np.cos(th + shift)
    h2 = np.where(cyc < 6, h2_before, np.where(cyc < 9, 0.3, h2_after))
    i = np.cos(th + shift - 0.3) + h2 * np.cos(2 * (th + shift) + 0.7)
    return v, i


def test_second_harmonic_before_and_after_a_sag():
    v, i = _waves(0.01, 0.04)
    before, after = second_harmonic(v, i, N)
    assert before == pytest.approx(0.01, abs=1e-9)
    # the fault's cycles (2nd harmonic 0.3) are not counted on either side
    assert after == pytest.approx(0.04, abs=1e-9)


def test_second_harmonic_needs_a_sag():
    v, i = _waves(0.01, 0.04, sag=0.99)
    assert all(np.isnan(second_harmonic(v, i, N)))


def _validation(t, resid_p, resid_q, scale=0.5):
    p_mean = np.full(t.size, 0.5)
    q_mean = np.full(t.size, 0.1)
    band = {"p_mean": p_mean, "q_mean": q_mean, "q_lo": q_mean - 0.01, "q_hi": q_mean + 0.01}
    event = SimpleNamespace(t=t, p=p_mean + resid_p * scale / 100,
                            q=q_mean + resid_q * scale / 100)  # fmt: skip
    return SimpleNamespace(event=event, scored=np.ones(t.size, bool), band=band, scale=scale)


def test_reclose_miss_splits_the_error_in_time():
    t = np.arange(80) * 0.005
    t_fault, t_clear = 0.195, 0.25
    first = (t > t_clear) & (t <= t_clear + FIRST_CYCLES / F)
    later = t > t_clear + FIRST_CYCLES / F
    rp = np.where(t < t_fault, np.where(np.arange(80) % 2, 1.0, -1.0), 0.0)
    rp = np.where(first, 3.0, np.where(later, -2.0, rp))
    rq = np.where(later, 4.0, 0.0)  # 4 % of a 0.5 scale = 0.02: outside the 0.01 band
    m = reclose_miss(_validation(t, rp, rq), t_fault, t_clear, F)
    assert m["before_p"] == pytest.approx(1.0)
    assert m["first_p"] == pytest.approx(3.0)
    assert m["first_q"] == pytest.approx(0.0)
    assert m["later_p"] == pytest.approx(-2.0)
    assert m["later_q"] == pytest.approx(4.0)
    assert m["later_cover_q"] == 0.0
    assert m["beyond_rows"] == 0 and np.isnan(m["beyond_q"])
    # the fitted event's record ran 0.1 s past its clearing: the rows after that apart
    rq = np.where(t > t_clear + 0.1, 6.0, rq)
    m = reclose_miss(_validation(t, rp, rq), t_fault, t_clear, F, reach=0.1)
    assert m["beyond_rows"] == int(np.sum(t > t_clear + 0.1))
    assert m["beyond_q"] == pytest.approx(6.0)
    assert m["within_q"] == pytest.approx(4.0)
    assert m["later_q"] == pytest.approx(np.mean(rq[later]))
    assert any("a stretch no fit of the first fault saw" in w
               for w in _miss_words({"slm": m}, {}, {}, []))  # fmt: skip


def _event(t, v, p, q):
    return SimpleNamespace(t=t, v=v, p=p, q=q, n=t.size)


def test_faults_apart_reads_the_records_alone():
    t = np.arange(80) * 0.005
    straddle = (t >= 0.195) & (t <= 0.25)
    v = np.where(straddle, 0.87, 1.0)
    rng = np.random.default_rng(3)
    swing = 0.01 * np.sin(2 * np.pi * 6 * t)  # the load moving by itself, before the fault
    p0 = np.where(t > 0.25, 1.0 + 0.2 * np.exp(-(t - 0.25) / 0.03), 1.0) + swing
    q0 = np.full(t.size, 0.2)
    later = t > 0.25 + FIRST_CYCLES / F
    p1 = p0 + np.where(later, 0.03, 0.0)  # the second fault's P 3 % higher later on
    e0 = _event(t, v, p0, q0)
    e1 = _event(t, v + 1e-4 * rng.standard_normal(t.size), p1, q0)
    a = faults_apart([e0, e1], [straddle, straddle], F)
    pre = np.mean(p1[t < 0.195])
    assert a["rows"] == int(later.sum())
    assert a["mean_p"] == pytest.approx(3.0 / pre, rel=1e-6)
    assert a["rms_q"] == pytest.approx(0.0, abs=1e-12)
    assert a["rms_v"] < 0.05
    assert a["steady_p"] == pytest.approx(np.std(p1[t < 0.195]) / pre * 100)
    assert faults_apart([e0, e1], [np.zeros(80, bool), straddle], F) == {}


def test_miss_words_say_an_inrush_only_where_the_harmonic_rose():
    m = {"slm": {"later_p": 0.2, "later_q": 5.0, "beyond_rows": 0}}
    own = {"slm": {"later_p": 0.1, "later_q": 3.0}}
    apart = {"rows": 14, "rms_p": 0.4, "mean_p": 0.1, "rms_q": 0.9, "mean_q": 0.8,
             "rms_v": 0.3, "steady_p": 0.2}  # fmt: skip
    words = _miss_words(m, own, apart, [(0.008, 0.011), (0.008, 0.037)])
    assert any("inrush" in w for w in words)
    assert any("slm misses the reclose's Q" in w and "+3.0" in w for w in words)
    assert not any("moves by" in w for w in words)  # 0.2 % is no floor worth a word
    quiet = _miss_words(m, {"slm": {"later_p": 0.1, "later_q": -3.0}}, apart,
                        [(0.008, 0.011), (0.008, 0.015)])  # fmt: skip
    assert not any("inrush" in w for w in quiet)
    assert not any("misses the reclose" in w for w in quiet)  # its own miss has the other sign


def test_form_words_only_where_most_of_the_miss_was_never_shown():
    from loadbayes.fit.composite.model_error import Discrepancy
    from loadbayes.studies.reclose_form import form_rows, form_words

    d = Discrepancy(sd_d=0.013, rho=0.64, sd_e=0.0006, n=66)
    split = {"mse": 1e-3, "noise": 0.0004, "parameters": 0.02, "form_seen": 0.14,
             "beyond": 0.84, "form": 0.98}  # fmt: skip
    easy = dict(split, form_seen=1.6, beyond=-0.7)
    form = {"slm": {"p": {"disc": d, "coverage": 0.96, "split": easy},
                    "q": {"disc": d, "coverage": 0.63, "split": split}}}  # fmt: skip
    words = form_words(form)
    assert len(words) == 1 and words[0].startswith("slm: 84% of the mean square")
    assert "reclose's Q" in words[0] and "covers 63%" in words[0]
    rows = form_rows("slm", form["slm"], scale=0.97)
    assert rows["slm: reclose in the 95% band with that model error (P, Q)"] == "96%, 63%"
    first = rows["slm: first fault's model error: AR(1) sd (% of P0), rho, share of its error"]
    assert first.startswith("P 1.34, 0.64, 100%")
