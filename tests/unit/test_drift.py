"""The drifting-level ZIP's pieces: FFBS and the Kalman likelihood against dense Gaussian
algebra, the residual-drift test's false-alarm rate, and the time column's parsing."""

import numpy as np
import pytest
from scipy import stats

from loadbayes.fit.drift import residual_drift
from loadbayes.inference.ffbs import ffbs, kf_loglik
from loadbayes.io.errors import DataError
from loadbayes.measurements.times import check_increasing, parse_times


def _dense(y, h, dt, w, r, q, m0, v0):
    """Exact joint Gaussian of the path x given y, and the prior covariance of y."""
    # x_t = x_0' + sum of steps: prior mean m0, covariance v0 + q * cumulative dt w
    tcum = np.cumsum(np.r_[0.0, dt[1:] * w[1:]])
    cx = v0 + q * np.minimum.outer(tcum, tcum)
    hm = np.diag(h)
    cy = hm @ cx @ hm + r * np.diag(w)
    gain = cx @ hm @ np.linalg.inv(cy)
    mean = m0 + gain @ (y - h * m0)
    cov = cx - gain @ hm @ cx
    return mean, cov, m0 * h, cy


def test_ffbs_draws_match_the_exact_posterior():
    rng = np.random.default_rng(0)
    n = 5
    y = rng.normal(1.0, 0.3, n)
    h = 1.0 + rng.normal(0, 0.1, n)
    dt = np.array([1.0, 1.0, 3.0, 0.5, 2.0])  # a gap and a short step
    w = np.array([1.0, 0.5, 2.0, 1.5, 0.8])  # the load's local scale, squared
    r, q, m0, v0 = 0.04, 0.02, 0.9, 0.5
    mean, cov, _, _ = _dense(y, h, dt, w, r, q, m0, v0)
    m_draws = 40_000
    out = np.empty((m_draws, n))
    m, p, z = np.empty(n), np.empty(n), np.empty(n)
    for i in range(m_draws):
        z[:] = rng.standard_normal(n)
        ffbs(y, h, dt, w, r, q, m0, v0, z, out[i], m, p)
    # Monte Carlo tolerance: 5 standard errors (false alarm < 1e-5 per entry)
    se_mean = np.sqrt(np.diag(cov) / m_draws)
    assert np.all(np.abs(out.mean(0) - mean) < 5 * se_mean)
    emp = np.cov(out.T)
    se_cov = np.sqrt((cov**2 + np.outer(np.diag(cov), np.diag(cov))) / m_draws)
    assert np.all(np.abs(emp - cov) < 5 * se_cov)


def test_kalman_likelihood_is_the_dense_gaussian_density():
    rng = np.random.default_rng(1)
    n = 7
    y = rng.normal(2.0, 0.2, n)
    x1, x2 = rng.normal(0, 0.05, n), rng.normal(0, 0.03, n)
    b1, b2 = 0.4, -0.3
    h = 1.0 + b1 * x1 + b2 * x2
    dt = np.r_[1.0, rng.uniform(0.5, 3.0, n - 1)]
    w = rng.uniform(0.3, 3.0, n)
    r, q, m0, v0 = 0.01, 0.003, 2.0, 1.0
    _, _, my, cy = _dense(y, h, dt, w, r, q, m0, v0)
    exact = stats.multivariate_normal(my, cy).logpdf(y)
    got = kf_loglik(y, x1, x2, dt, w, b1, b2, r, q, m0, v0)
    assert got == pytest.approx(exact, rel=1e-10)


def test_residual_drift_false_alarm_rate_on_white_noise():
    # 400 white-noise records: the alarm (p < 1e-3) fires on about 0.4 of them; more than
    # 4 alarms has probability < 1e-3 (binomial(400, 1e-3)).
    rng = np.random.default_rng(2)
    t = np.arange(1440) * 60.0
    alarms = sum(residual_drift(t, rng.standard_normal(t.size))[1] < 1e-3 for _ in range(400))
    assert alarms <= 4


def test_residual_drift_sees_a_daily_swing():
    rng = np.random.default_rng(3)
    t = np.arange(1440) * 60.0
    resid = 0.3 * np.sin(2 * np.pi * t / 86_400) + rng.standard_normal(t.size) * 0.1
    share, p = residual_drift(t, resid)
    assert p < 1e-6 and share > 0.5


def test_times_numbers_and_iso_timestamps():
    np.testing.assert_array_equal(parse_times(["0", "1.5", "3"], path="f", column="t"),
                                  [0.0, 1.5, 3.0])  # fmt: skip
    iso = ["2026-03-01T00:00:00", "2026-03-01T00:01:00", "2026-03-01T01:00:00"]
    np.testing.assert_array_equal(parse_times(iso, path="f", column="t"), [0.0, 60.0, 3600.0])


def test_bad_time_cell_named_by_file_column_and_row():
    iso = ["2026-03-01T00:00:00", "2026-03-01T00:01:00", "noon", "2026-03-01T00:03:00"]
    with pytest.raises(DataError) as err:
        parse_times(iso, path="day.csv", column="time")
    assert str(err.value).startswith("day.csv: column 'time', row 3: 'noon'")
    with pytest.raises(DataError, match="row 3: time does not increase"):
        check_increasing(np.array([0.0, 60.0, 60.0]), np.array([1, 2, 3]), path="d", column="t")
