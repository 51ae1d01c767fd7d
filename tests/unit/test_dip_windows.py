"""The grid-code windows of a dip (IEC 61400-27-2 6.4.3-6.4.4): masks and errors by hand."""

import numpy as np
import pytest

from loadbayes.fit.composite.windows import dip_windows, window_errors


def _dip():
    t = np.arange(60) / 50.0
    v = np.where((t >= 0.2) & (t < 0.4), 0.6, 1.0)
    return t, v


def test_the_windows_split_a_dip_at_its_start_and_clearing():
    t, v = _dip()
    w = dip_windows(t, v)
    assert np.flatnonzero(w["fault"]).tolist() == list(range(10, 20))
    assert w["pre_fault"][:10].all() and not w["pre_fault"][10:].any()
    assert w["post_fault"][20:].all() and not w["post_fault"][:20].any()


def test_me_mae_mxe_per_window_against_hand_numbers():
    t, v = _dip()
    meas = np.ones(t.size)
    sim = meas.copy()
    sim[10:20] += np.where(np.arange(10) % 2 == 0, 0.2, -0.1)  # fault: +0.2, -0.1 alternate
    sim[20:] += 0.05  # post-fault: a constant offset
    out = window_errors(t, v, {"p": meas}, {"p": sim}, scale=0.5)
    assert out["pre_fault"]["p"] == {"me": 0.0, "mae": 0.0, "mxe": 0.0}
    fault = out["fault"]["p"]
    assert fault["me"] == pytest.approx(0.05 / 0.5)
    assert fault["mae"] == pytest.approx(0.15 / 0.5)
    assert fault["mxe"] == pytest.approx(0.2 / 0.5)
    assert out["post_fault"]["p"]["me"] == pytest.approx(0.1)
    # Samples not scored do not enter.
    scored = np.ones(t.size, bool)
    scored[10] = False
    fault = window_errors(t, v, {"p": meas}, {"p": sim}, scale=0.5, scored=scored)["fault"]
    assert fault["n"] == 9 and fault["p"]["mxe"] == pytest.approx(0.4)
    assert "IEC 61400-27-2" in out["source"]


def test_no_dip_is_all_pre_fault():
    t = np.arange(20) / 50.0
    w = window_errors(t, np.ones(20), {"q": np.ones(20)}, {"q": np.ones(20)}, scale=1.0)
    assert w["pre_fault"]["n"] == 20 and w["fault"]["q"] is None
