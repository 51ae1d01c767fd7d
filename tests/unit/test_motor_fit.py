"""Unit tests of the induction-motor regression model, its coupled sampler and fit_im."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from loadbayes.baselines.kalman import kalman
from loadbayes.baselines.least_squares import coupled_least_squares, least_squares
from loadbayes.cases.motor_sim import constant, simulate, write_csv
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit import accumulate, fit_im, fit_im_file, im_priors
from loadbayes.inference.bilinear import bilinear_least_squares, sample_bilinear
from loadbayes.io.errors import DataError
from loadbayes.models.motor import COEFFICIENT_NAMES
from loadbayes.models.motor_fit import DATA_COLUMNS, PHYSICAL_NAMES, InductionMotorModel
from loadbayes.models.motor_library import MOTORS

MOTOR_NAMES = sorted(MOTORS)
FAST = {"draws": 600, "burn": 100, "chains": 2}


def _cols(df: pd.DataFrame) -> dict[str, np.ndarray]:
    return {k: df[k].to_numpy() for k in DATA_COLUMNS}


@pytest.fixture(scope="module")
def clean() -> dict[str, pd.DataFrame]:
    """Noise-free default-sag records (3001 samples each)."""
    return {name: simulate(name, noise=0.0) for name in MOTOR_NAMES}


@pytest.fixture(scope="module")
def noisy() -> pd.DataFrame:
    return simulate("krause_3hp", noise=0.05, seed=4)


def _truth(df: pd.DataFrame) -> np.ndarray:
    return np.array([df.attrs["coefficients"][k] for k in COEFFICIENT_NAMES])


# --- the model's columns and statistics -------------------------------------------------


def test_rows_follow_gram_columns(clean) -> None:
    cols = _cols(clean["small_industrial"])
    bare = InductionMotorModel()
    assert "h" not in bare.gram_columns
    with pytest.raises(ValueError, match="T0 is not resolved"):
        _ = bare.blocks
    model = bare.with_t0(0.6)
    rows = model.rows(cols)
    assert rows.shape == (len(cols["ud"]), len(model.gram_columns))
    named = dict(zip(model.gram_columns, rows.T, strict=True))
    np.testing.assert_allclose(named["h"], 0.6 * cols["w"] ** 2 - named["te"])
    np.testing.assert_array_equal(named["mid"], -cols["id"])
    np.testing.assert_allclose(
        named["yed"], cols["ded"] + model.wb * (cols["w"] - 1) * cols["eq"], rtol=1e-15
    )


def test_complete_adds_h_exactly(noisy) -> None:
    cols = _cols(noisy)
    bare = InductionMotorModel()
    model = bare.with_t0(0.6)
    derived = model.complete(accumulate(bare, [cols]))
    direct = accumulate(model, [cols])
    assert derived.names == direct.names
    np.testing.assert_allclose(derived.matrix, direct.matrix, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", MOTOR_NAMES)
def test_noise_free_record_gives_the_truth_in_both_forms(name, clean) -> None:
    df = clean[name]
    cols, truth = _cols(df), _truth(df)
    bare = InductionMotorModel(f_hz=MOTORS[name].f_hz)
    gram = accumulate(bare, [cols])
    first = bare.first_row(cols)
    t0 = bare.resolve_t0(gram, first)
    assert t0 == pytest.approx(df.attrs["t0"], rel=1e-8)
    measured = InductionMotorModel(currents="measured").with_t0(t0)
    est = least_squares(measured, measured.complete(gram)).settings["estimate"]
    np.testing.assert_allclose([est[k] for k in COEFFICIENT_NAMES], truth, rtol=1e-6)
    coupled = coupled_least_squares(bare, gram, first=first).settings["estimate"]
    np.testing.assert_allclose([coupled[k] for k in COEFFICIENT_NAMES], truth, rtol=1e-6)
    for key in ("rs", "xp", "x", "tp_s", "h_s"):
        assert coupled[key] == pytest.approx(getattr(MOTORS[name], key), rel=1e-5)


@pytest.mark.parametrize("t0", [None, 0.6])
def test_bilinear_sums_of_squares_match_the_residuals(noisy, t0) -> None:
    cols = _cols(noisy)
    model = InductionMotorModel(t0=t0)
    gram = accumulate(InductionMotorModel(), [cols])
    first = model.first_row(cols)
    st = model.bilinear_stats(gram, first)
    rng = np.random.default_rng(0)
    for _ in range(3):
        b1, b2, b3, ab, ac = _truth(noisy) * rng.uniform(0.5, 1.5, 5)
        ud, uq, ed, eq, w = (cols[k] for k in ("ud", "uq", "ed", "eq", "w"))
        dd, dq = ud - ed, uq - eq
        i_d, i_q = ab * dd + ac * dq, ab * dq - ac * dd
        t0v = t0 if t0 is not None else (ab * first["s1"] + ac * first["s2"]) / first["w2"]
        yed = cols["ded"] + model.wb * (w - 1) * eq
        yeq = cols["deq"] - model.wb * (w - 1) * ed
        direct = [
            np.sum((yed - b1 * ed - b2 * i_q) ** 2) + np.sum((yeq - b1 * eq + b2 * i_d) ** 2),
            np.sum((cols["dw"] - b3 * (t0v * w**2 - ed * i_d - eq * i_q)) ** 2),
            np.sum((cols["id"] - i_d) ** 2) + np.sum((cols["iq"] - i_q) ** 2),
        ]
        np.testing.assert_allclose(st.ssr([b1, b2, b3], [ab, ac]), direct, rtol=1e-8)
        # The conditional of each block is the exact quadratic of the sum of squares.
        tau = np.array([2.0, 3.0, 5.0])
        lam, lin = st.conditional("v", [b1, b2, b3], tau)
        x = np.array([ab, ac])
        full = tau @ st.ssr([b1, b2, b3], x)
        const = tau @ st.ssr([b1, b2, b3], [0.0, 0.0])
        assert full == pytest.approx(const + x @ lam @ x - 2 * lin @ x, rel=1e-9)


def test_transform_reports_coefficients_precisions_and_physics() -> None:
    c = MOTORS["krause_3hp"].coefficients()
    draws = {k: np.full((2, 3), v) for k, v in c.items()}
    draws.update(tau_e=np.ones((2, 3)), tau_w=np.ones((2, 3)), tau_i=np.ones((2, 3)))
    out = InductionMotorModel().transform(draws)
    assert list(out) == [*COEFFICIENT_NAMES, "tau_e", "tau_w", "tau_i", *PHYSICAL_NAMES]
    for key in PHYSICAL_NAMES:
        assert out[key][0, 0] == pytest.approx(getattr(MOTORS["krause_3hp"], key), rel=1e-12)


def test_model_validation() -> None:
    with pytest.raises(ValueError, match="currents"):
        InductionMotorModel(currents="noisy")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="t0"):
        InductionMotorModel(t0=-1.0)
    with pytest.raises(ValueError, match="closure"):
        InductionMotorModel(closure="xm=0")


# --- checks on the data --------------------------------------------------------------------


def test_check_refuses_a_steady_record_and_too_few_rows() -> None:
    df = simulate("large_industrial", disturbance=constant(1.0), noise=0.05, t_end_s=0.2)
    with pytest.raises(DataError, match="no excitation"):
        fit_im(_cols(df), sampler=SamplerSettings(**FAST))
    short = {k: v[:3] for k, v in _cols(simulate("krause_3hp", t_end_s=0.01)).items()}
    with pytest.raises(DataError, match="at least 4"):
        fit_im(short, sampler=SamplerSettings(**FAST))


def test_fit_im_refuses_bad_input(noisy) -> None:
    cols = _cols(noisy)
    # The CLI's messages: the column, and the 1-based row of the first bad value.
    with pytest.raises(DataError, match="column 'dw': not found"):
        fit_im({k: v for k, v in cols.items() if k != "dw"}, sampler=SamplerSettings(**FAST))
    bad = dict(cols, ed=cols["ed"].copy())
    bad["ed"][5] = np.nan
    with pytest.raises(DataError, match="column 'ed', row 6: missing value"):
        fit_im(bad, sampler=SamplerSettings(**FAST))
    with pytest.raises(ValueError, match="exact"):
        fit_im(cols, scheme="exact", sampler=SamplerSettings(**FAST))
    with pytest.raises(ValueError, match="non-conjugate"):
        fit_im(cols, priors=im_priors(conjugate=True), sampler=SamplerSettings(**FAST))
    with pytest.raises(ValueError, match="priors can be set on"):
        im_priors(per_coef={"a1": (0.0, 1.0)})


def test_measured_form_warns_about_noisy_currents(clean, noisy) -> None:
    warned = fit_im(_cols(noisy), currents="measured", sampler=SamplerSettings(**FAST)).warnings
    assert any("errors in variables" in w for w in warned)
    quiet = fit_im(
        _cols(clean["krause_3hp"]), currents="measured", sampler=SamplerSettings(**FAST)
    ).warnings
    assert not any("errors in variables" in w for w in quiet)


# --- fitting -----------------------------------------------------------------------------------


def test_fit_im_result_contract(noisy) -> None:
    post = fit_im(_cols(noisy), sampler=SamplerSettings(seed=3, **FAST))
    assert post.model == "im" and post.method == "gibbs-blocked"
    assert post.names == [*COEFFICIENT_NAMES, "tau_e", "tau_w", "tau_i", *PHYSICAL_NAMES]
    assert post.coefficients == list(COEFFICIENT_NAMES)
    assert post.n_chains == 2 and post.n_draws == 500
    s = post.settings
    assert s["currents"] == "modelled" and s["t0_source"] == "first sample"
    assert s["t0"] == pytest.approx(noisy.attrs["t0"], rel=2e-3)
    assert s["wb"] == pytest.approx(2 * np.pi * 60)
    truth = _truth(noisy)
    mean = np.array([post.mean()[k] for k in COEFFICIENT_NAMES])
    np.testing.assert_allclose(mean, truth, rtol=0.01)


def test_seed_makes_draws_reproducible_and_chains_independent_of_their_count(noisy) -> None:
    cols = _cols(noisy)
    a = fit_im(cols, sampler=SamplerSettings(seed=5, **FAST))
    b = fit_im(cols, sampler=SamplerSettings(seed=5, **FAST))
    c = fit_im(cols, sampler=SamplerSettings(seed=5, draws=600, burn=100, chains=3))
    for k in ("b2", "ac", "tau_e"):
        np.testing.assert_array_equal(a.draws[k], b.draws[k])
        np.testing.assert_array_equal(a.draws[k][0], c.draws[k][0])
    assert not np.array_equal(
        a.draws["b2"], fit_im(cols, sampler=SamplerSettings(seed=6, **FAST)).draws["b2"]
    )


def test_given_t0_and_single_site_scheme(noisy) -> None:
    post = fit_im(
        _cols(noisy), t0=noisy.attrs["t0"], scheme="single-site", sampler=SamplerSettings(**FAST)
    )
    assert post.settings["t0_source"] == "given" and post.method == "gibbs-single-site"
    assert post.mean()["b3"] == pytest.approx(noisy.attrs["coefficients"]["b3"], rel=0.01)


def test_file_fit_equals_in_memory_fit(noisy, tmp_path) -> None:
    csv, _ = write_csv(noisy, tmp_path / "rec.csv")
    mem = fit_im(_cols(noisy), sampler=SamplerSettings(seed=2, **FAST))
    post, model = fit_im_file(str(csv), sampler=SamplerSettings(seed=2, **FAST), chunk_rows=777)
    assert model.t0 == pytest.approx(post.settings["t0"])
    for k in ("b1", "b3", "ac", "tau_i"):
        np.testing.assert_array_equal(post.draws[k], mem.draws[k])
    assert post.settings["data"] == str(csv)


def test_v_starts_from_the_current_equations_not_from_the_prior(noisy) -> None:
    # (b2, b3, ab, ac) -> (b2/c, b3/c, c ab, c ac) fits the flux and speed equations
    # equally well; a chain whose (ab, ac) starts far off (a prior draw, as the paper
    # starts) can sit on that ridge for thousands of sweeps. Started from the current
    # equations alone, every chain is at the posterior from the first sweeps.
    model = InductionMotorModel()
    cols = _cols(noisy)
    gram = accumulate(model, [cols])
    st = model.bilinear_stats(gram, model.first_row(cols))
    priors = model.default_priors()
    ac = noisy.attrs["coefficients"]["ac"]
    kw = {"tau_shape": [1e-3] * 3, "tau_rate": [1e-9] * 3}
    kw["settings"] = SamplerSettings(draws=2000, burn=1000, chains=20, seed=0)
    args = (st, [priors["flux"], priors["speed"]], priors["current"])
    from_prior = sample_bilinear(*args, **kw)
    assert np.any(np.abs(from_prior["ac"][:, -1] / ac - 1) > 0.05)
    v_ls, v_cov, _ = model.current_estimate(gram)
    good = sample_bilinear(*args, v_start=(v_ls, v_cov), **kw)
    assert np.all(np.abs(good["ac"][:, 1:].mean(axis=1) / ac - 1) < 0.01)
    ml = bilinear_least_squares(st, v0=v_ls)
    np.testing.assert_allclose(np.r_[ml["u"], ml["v"]], _truth(noisy), rtol=5e-3)


def test_baselines_run_on_the_measured_blocks(noisy) -> None:
    cols = _cols(noisy)
    model = InductionMotorModel(currents="measured", t0=noisy.attrs["t0"])
    ls = least_squares(model, accumulate(model, [cols]))
    kf = kalman(model, cols)
    for post in (ls, kf):
        est = post.settings["estimate"]
        assert set(PHYSICAL_NAMES) <= set(est)
        # The current block has clean regressors: unbiased in both.
        assert est["ac"] == pytest.approx(noisy.attrs["coefficients"]["ac"], rel=5e-3)
    assert kf.settings["estimate"]["b1"] == pytest.approx(ls.settings["estimate"]["b1"], rel=1e-3)


def test_default_priors_are_weak() -> None:
    priors = InductionMotorModel().default_priors()
    assert set(priors) == {"flux", "speed", "current"}
    for p in priors.values():
        assert isinstance(p, BlockPrior) and not p.conjugate
        np.testing.assert_allclose(np.diag(p.precision), 1e-4)


def test_a_record_with_no_stator_current_is_refused_in_words(noisy, tmp_path) -> None:
    # id = iq = 0 throughout (an open breaker, current channels not recorded): the
    # equations are singular; it ended in the solver's bare "SVD did not converge".
    cols = _cols(noisy)
    dead = dict(cols, id=np.zeros_like(cols["id"]), iq=np.zeros_like(cols["iq"]))
    with pytest.raises(DataError, match=r"column 'id': the stator current \(id, iq\) is 0"):
        fit_im(dead, sampler=SamplerSettings(**FAST))
    path = tmp_path / "dead.csv"
    pd.DataFrame(dead).to_csv(path, index=False)
    with pytest.raises(DataError, match=r"dead.csv: column 'id': the stator current"):
        fit_im_file(str(path), sampler=SamplerSettings(**FAST))
