"""Statistical checks of the induction-motor estimator on simulated records.

Every record is the default 25% sag (0.5 s, 150 ms), 3 s at 1 ms (3001 samples), noise sd
5% of each target channel's RMS, with fixed seeds, so each run is deterministic. The
false-alarm rates below say how often a *correct* estimator would fail a check over
random seeds:

- 99.99% central interval covering the truth (z = 3.89): 1e-4 per parameter, or 5e-4
  allowing for the shared flux and current precisions (the two channels of a block have
  different noise; the z-score sd is 0.8-1.12, measured over 100 replications). 4 motors
  x (5 coefficients + 5 identified physical + 4 closure for the two Xs = Xr motors):
  48 checks, correlated, below 2.5% together;
- every coefficient within the paper's 6%: the posterior sd is 0.05-0.5%, so a miss
  would be > 10 sd: nil;
- the paper's form attenuating b3 by more than 15% (measured 22-50%, > 20 sd): nil;
- coupled sampler with (ab, ac) pinned against the linear sampler: means within 4
  combined MCSE (6e-5 each) and sds within 8% (3.6 sd of the estimate, 3e-4 each):
  under 1e-3 for the 6 comparisons;
- calibration over 40 noise replications: coverage of 95% intervals >= 80% of 200
  (P < 1e-6 at a true coverage of 0.91), |mean z| < 0.5 (7 sd of the mean of 200
  correlated z: nil), z sd in [0.75, 1.35] (about 4 sd: 1e-4);
- single-site against blocked: means within 4 combined MCSE: 6e-5 each, 3e-4 for 5.

Overall false-alarm rate below 3%.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.motor_sim import simulate
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import RegressionStats
from loadbayes.fit import accumulate, fit_im
from loadbayes.inference.bilinear import sample_bilinear
from loadbayes.inference.gibbs import sample_block
from loadbayes.models.motor import COEFFICIENT_NAMES, inverse
from loadbayes.models.motor_fit import DATA_COLUMNS, InductionMotorModel
from loadbayes.models.motor_library import MOTORS
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.statistical

MOTOR_NAMES = sorted(MOTORS)
Z = 3.89  # two-sided 99.99%
SAMPLER = {"draws": 6000, "burn": 1000, "chains": 2}


def _cols(df):
    return {k: df[k].to_numpy() for k in DATA_COLUMNS}


@pytest.fixture(scope="module")
def records():
    return {name: simulate(name, noise=0.05, seed=11) for name in MOTOR_NAMES}


def _central(x: np.ndarray, z: float = Z) -> tuple[float, float]:
    from scipy import stats

    p = stats.norm.sf(z)
    lo, hi = np.nanquantile(x.reshape(-1), [p, 1 - p])
    return float(lo), float(hi)


@pytest.mark.parametrize("name", MOTOR_NAMES)
def test_each_motor_is_recovered_with_intervals_that_cover(name, records) -> None:
    df = records[name]
    params = MOTORS[name]
    post = fit_im(_cols(df), f_hz=params.f_hz, sampler=SamplerSettings(seed=1, **SAMPLER))
    truth = dict(df.attrs["coefficients"])
    truth.update({k: getattr(params, k) for k in ("rs", "xp", "x", "tp_s", "h_s")})
    if params.xs == params.xr:  # the closure is exact for this motor
        truth.update({k: getattr(params, k) for k in ("xs", "xm", "xr", "rr")})
    else:  # the closure's value on the true coefficients
        closure = inverse(params.coefficients(), "xs=xr", f_hz=params.f_hz)
        truth.update({k: float(closure[k]) for k in ("xs", "xm", "xr", "rr")})
    for k in COEFFICIENT_NAMES:
        assert abs(post.mean()[k] / truth[k] - 1) < 0.06, k
    for k, true in truth.items():
        lo, hi = _central(post.draws[k])
        assert lo <= true <= hi, (k, lo, true, hi)


def test_paper_form_attenuates_b3_when_currents_are_noisy(records) -> None:
    # Errors in variables: the noisy Id, Iq inside the speed regressor pull b3 to zero.
    for name, df in records.items():
        f = MOTORS[name].f_hz
        b3 = df.attrs["coefficients"]["b3"]
        measured = fit_im(
            _cols(df), f_hz=f, currents="measured", sampler=SamplerSettings(seed=1, **SAMPLER)
        )
        ratio = measured.mean()["b3"] / b3
        assert 0 < ratio < 0.85, (name, ratio)


def test_coupled_sampler_reduces_to_the_linear_one_when_ab_ac_are_known(records) -> None:
    df = records["krause_2250hp"]
    cols = _cols(df)
    c = df.attrs["coefficients"]
    v_true = np.array([c["ab"], c["ac"]])
    model = InductionMotorModel(t0=df.attrs["t0"])
    st = model.bilinear_stats(accumulate(InductionMotorModel(), [cols]))
    priors = model.default_priors()
    pinned = BlockPrior(mean=v_true, precision=1e30 / v_true**2)
    kw = {"draws": 20_000, "burn": 1000, "chains": 4, "seed": 7}
    coupled = sample_bilinear(
        st,
        [priors["flux"], priors["speed"]],
        pinned,
        tau_shape=[1e-3] * 3,
        tau_rate=[1e-9] * 3,
        v_start=(v_true, np.zeros((2, 2))),
        settings=SamplerSettings(**kw),
    )
    # The same flux and speed regressions with the model's currents at the true (ab, ac).
    ud, uq, ed, eq, w = (cols[k] for k in ("ud", "uq", "ed", "eq", "w"))
    dd, dq = ud - ed, uq - eq
    i_d, i_q = c["ab"] * dd + c["ac"] * dq, c["ab"] * dq - c["ac"] * dd
    wb = model.wb
    z = np.vstack([np.column_stack([ed, i_q]), np.column_stack([eq, -i_d])])
    r = np.r_[cols["ded"] + wb * (w - 1) * eq, cols["deq"] - wb * (w - 1) * ed]
    h = model.t0 * w**2 - (ed * i_d + eq * i_q)
    linear = {
        "flux": (RegressionStats(z.T @ z, z.T @ r, float(r @ r), r.size), ("b1", "b2", "tau_e")),
        "speed": (
            RegressionStats(
                np.array([[h @ h]]),
                np.array([h @ cols["dw"]]),
                float(cols["dw"] @ cols["dw"]),
                h.size,
            ),
            ("b3", "tau_w"),
        ),
    }
    for block, (stats_, names) in linear.items():
        res = sample_block(stats_, priors[block], settings=SamplerSettings(**kw))
        ref = {n: res.coef[..., i] for i, n in enumerate(names[:-1])} | {names[-1]: res.tau}
        a = Posterior({n: coupled[n] for n in names}, model="t", method="t").summary()
        b = Posterior(ref, model="t", method="t").summary()
        for n in names:
            tol = 4 * np.hypot(a.loc[n, "mcse_mean"], b.loc[n, "mcse_mean"])
            assert abs(a.loc[n, "mean"] - b.loc[n, "mean"]) < tol, n
            assert a.loc[n, "sd"] / b.loc[n, "sd"] == pytest.approx(1, abs=0.08), n


def test_intervals_are_calibrated_over_noise_replications() -> None:
    base = simulate("krause_3hp", noise=0.0)
    cols0 = _cols(base)
    truth = np.array([base.attrs["coefficients"][k] for k in COEFFICIENT_NAMES])
    model = InductionMotorModel()
    priors = model.default_priors()
    rng = np.random.default_rng(2024)
    zs = []
    for rep in range(40):
        cols = dict(cols0)
        for k in ("ded", "deq", "dw", "id", "iq"):
            x = cols0[k]
            cols[k] = x + 0.05 * np.sqrt(np.mean(x**2)) * rng.standard_normal(x.size)
        gram = accumulate(model, [cols])
        st = model.bilinear_stats(gram, model.first_row(cols))
        v_ls, v_cov, _ = model.current_estimate(gram)
        out = sample_bilinear(
            st,
            [priors["flux"], priors["speed"]],
            priors["current"],
            tau_shape=[1e-3] * 3,
            tau_rate=[1e-9] * 3,
            v_start=(v_ls, v_cov),
            settings=SamplerSettings(draws=2000, burn=300, chains=2, seed=rep),
        )
        draws = np.stack([out[k].reshape(-1) for k in COEFFICIENT_NAMES], axis=1)
        zs.append((draws.mean(axis=0) - truth) / draws.std(axis=0))
    zs = np.array(zs)
    assert np.mean(np.abs(zs) < 1.96) >= 0.80
    assert abs(zs.mean()) < 0.5
    assert 0.75 < zs.std() < 1.35


def test_single_site_agrees_with_blocked(records) -> None:
    cols = _cols(records["large_industrial"])
    kw = {"sampler": SamplerSettings(draws=12_000, burn=1000, chains=4, seed=3)}
    blocked = fit_im(cols, **kw).summary(var_names=list(COEFFICIENT_NAMES))
    single = fit_im(cols, scheme="single-site", **kw).summary(var_names=list(COEFFICIENT_NAMES))
    for k in COEFFICIENT_NAMES:
        tol = 4 * np.hypot(blocked.loc[k, "mcse_mean"], single.loc[k, "mcse_mean"])
        assert abs(blocked.loc[k, "mean"] - single.loc[k, "mean"]) < tol, k
