"""Unit tests of the third-order induction-motor physics and its simulator."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from loadbayes.cases.motor_sim import (
    COLUMNS,
    MOTORS,
    constant,
    from_file,
    ramp,
    random_walk,
    read_csv,
    sag,
    simulate,
    write_csv,
)
from loadbayes.models.motor import (
    COEFFICIENT_NAMES,
    MotorParams,
    currents,
    derivatives,
    inverse,
    power,
    steady_state,
)

MOTOR_NAMES = sorted(MOTORS)


@pytest.fixture(scope="module")
def records() -> dict[str, pd.DataFrame]:
    """One noiseless default-sag record per motor (shared: each costs ~0.1 s)."""
    return {name: simulate(name, noise=0.0) for name in MOTOR_NAMES}


# --- steady state --------------------------------------------------------------------


@pytest.mark.parametrize("name", MOTOR_NAMES)
@pytest.mark.parametrize("loading", [{"t0": 0.6}, {"t0": 1.0}, {"slip": 0.004}, {"p_pu": 0.8}])
def test_steady_state_is_an_equilibrium(name: str, loading: dict) -> None:
    params = MOTORS[name]
    op = steady_state(params, **loading)
    rhs = derivatives(op.state, op.ud, op.uq, params, t0=op.t0)
    assert np.max(np.abs(rhs)) < 1e-10
    assert 0 < op.slip < 0.1
    assert op.slip < op.breakdown_slip
    assert op.p > 0 and op.q > 0
    id_, iq = currents(op.ud, op.uq, op.ed, op.eq, params)
    assert (op.id, op.iq) == pytest.approx((id_, iq), abs=1e-14)
    # Power balance: P in = air-gap power + stator copper loss.
    assert op.p == pytest.approx(op.te + params.rs * (op.id**2 + op.iq**2), abs=1e-12)
    if "slip" in loading:
        assert op.slip == pytest.approx(loading["slip"], abs=1e-12)
    if "p_pu" in loading:
        assert op.p == pytest.approx(loading["p_pu"], abs=1e-10)


def test_steady_state_rejects_overload_and_bad_loading() -> None:
    params = MOTORS["small_industrial"]
    with pytest.raises(ValueError, match="breakdown"):
        steady_state(params, t0=5.0)
    with pytest.raises(ValueError, match="exactly one"):
        steady_state(params, t0=0.5, slip=0.01)
    with pytest.raises(ValueError, match="motoring"):
        steady_state(params, t0=-0.5)


def test_power_sign_convention() -> None:
    # A pure inductive load (current lagging the voltage by 90 degrees) absorbs Q > 0.
    p, q = power(1.0, 0.0, 0.0, -1.0)
    assert (p, q) == (0.0, 1.0)


def test_motor_params_validation() -> None:
    with pytest.raises(ValueError, match="a \\+ b \\+ c"):
        MotorParams(0.01, 0.1, 3.0, 0.01, 0.1, 1.0, a=0.5)
    with pytest.raises(ValueError, match="h_s"):
        MotorParams(0.01, 0.1, 3.0, 0.01, 0.1, 0.0)


# --- coefficients and their inverse ---------------------------------------------------


@pytest.mark.parametrize("name", MOTOR_NAMES)
def test_inverse_recovers_identifiable_parameters(name: str) -> None:
    params = MOTORS[name]
    coefs = params.coefficients()
    assert coefs["b1"] < 0 and coefs["b2"] < 0 and coefs["b3"] < 0
    phys = inverse(coefs, f_hz=params.f_hz)
    for key, true in [
        ("rs", params.rs),
        ("xp", params.xp),
        ("x", params.x),
        ("tp_s", params.tp_s),
        ("h_s", params.h_s),
    ]:
        np.testing.assert_allclose(phys[key], true, rtol=1e-12)


@pytest.mark.parametrize("name", ["krause_3hp", "krause_2250hp"])
def test_inverse_closure_recovers_motor_with_xs_equal_xr(name: str) -> None:
    params = MOTORS[name]
    assert params.xs == params.xr
    phys = inverse(params.coefficients(), "xs=xr", f_hz=params.f_hz)
    for key in ("xs", "xm", "xr", "rr"):
        np.testing.assert_allclose(phys[key], getattr(params, key), rtol=1e-12)


def test_inverse_is_vectorised_and_nan_without_real_root() -> None:
    params = replace(MOTORS["small_industrial"], xr=MOTORS["small_industrial"].xs)
    coefs = {k: np.full(4, v) for k, v in params.coefficients().items()}
    # X - X' = -X'/2 makes X (X - X') < 0: the closure has no real solution.
    coefs["b2"][1] = coefs["b1"][1] * (-params.xp / 2)
    phys = inverse(coefs, f_hz=params.f_hz)
    assert phys["xm"].shape == (4,)
    assert np.isnan(phys["xm"][1]) and np.isnan(phys["rr"][1])
    np.testing.assert_allclose(phys["xm"][[0, 2, 3]], params.xm, rtol=1e-12)
    assert set(inverse(params.coefficients(), None)) == {"rs", "xp", "x", "tp_s", "h_s"}


def test_time_base_scales_with_nominal_frequency() -> None:
    p60 = MOTORS["small_industrial"]
    p50 = replace(p60, f_hz=50.0)
    c60, c50 = p60.coefficients(), p50.coefficients()
    # T' = (Xr + Xm)/(wb Rr): b1 and b2 scale with wb; b3, ab, ac do not depend on it.
    assert c50["b1"] / c60["b1"] == pytest.approx(50 / 60, rel=1e-14)
    assert c50["b2"] / c60["b2"] == pytest.approx(50 / 60, rel=1e-14)
    for key in ("b3", "ab", "ac"):
        assert c50[key] == c60[key]


# --- simulator against the regression form --------------------------------------------


@pytest.mark.parametrize("name", MOTOR_NAMES)
def test_regression_identities_hold_on_simulated_data(name: str, records) -> None:
    df = records[name]
    c, wb, t0 = df.attrs["coefficients"], df.attrs["wb"], df.attrs["t0"]
    assert list(df.columns[: len(COLUMNS)]) == list(COLUMNS)
    ud, uq, ed, eq, w, id_, iq = (
        df[k].to_numpy() for k in ("ud", "uq", "ed", "eq", "w", "id", "iq")
    )
    ded, deq, dw = (df[k].to_numpy() for k in ("ded", "deq", "dw"))
    residuals = {
        "Ed": ded + wb * (w - 1) * eq - (c["b1"] * ed + c["b2"] * iq),
        "Eq": deq - wb * (w - 1) * ed - (c["b1"] * eq - c["b2"] * id_),
        "w": dw - c["b3"] * (t0 * w**2 - (ed * id_ + eq * iq)),
        "Id": id_ - (c["ab"] * (ud - ed) + c["ac"] * (uq - eq)),
        "Iq": iq - (c["ab"] * (uq - eq) - c["ac"] * (ud - ed)),
    }
    for key, r in residuals.items():
        assert np.max(np.abs(r)) < 1e-8, key
    # The derivative columns are the ODE's own slope: finite differences agree.
    fd = np.gradient(ed, df["t_s"].to_numpy())
    calm = np.abs(df["t_s"].to_numpy() - 0.575) > 0.1  # away from the voltage steps
    assert np.max(np.abs(fd - ded)[calm]) < 1e-3 * np.max(np.abs(ded))


@pytest.mark.parametrize("name", MOTOR_NAMES)
def test_tight_tolerance_rerun_agrees(name: str, records) -> None:
    # Default rtol 1e-9 / atol 1e-11 against 1e-12 / 1e-14: states agree to 1e-8 p.u.;
    # currents and derivatives amplify state error by up to |b| and wb, hence looser.
    loose = records[name]
    tight = simulate(name, noise=0.0, rtol=1e-12, atol=1e-14)
    tolerance = {
        "ed": 1e-8,
        "eq": 1e-8,
        "w": 1e-8,
        "id": 1e-7,
        "iq": 1e-7,
        "ded": 1e-6,
        "deq": 1e-6,
        "dw": 1e-6,
    }
    for key, tol in tolerance.items():
        assert np.max(np.abs(loose[key] - tight[key])) < tol, key


def test_constant_voltage_stays_at_steady_state() -> None:
    df = simulate("large_industrial", disturbance=constant(0.95), noise=0.0, t_end_s=2.0)
    op = df.attrs["steady_state"]
    for key in ("ed", "eq", "w"):
        assert np.max(np.abs(df[key] - op[key])) < 1e-10, key
    assert np.max(np.abs(df[["ded", "deq", "dw"]].to_numpy())) < 1e-10


def test_flux_decay_with_voltage_removed_and_rotor_held() -> None:
    # With H -> infinity the speed is frozen at w0 and, for U = 0, I = -E'/Z, so
    # dE'/dt = lam E' with lam = -(1 + j (X - X')/Z)/T' + j wb (w0 - 1): E' decays
    # (and turns) exponentially. With Rs = 0 the decay time is T' X'/X.
    params = replace(MOTORS["small_industrial"], h_s=1e12)
    df = simulate(params, disturbance=sag(1.0, 0.1, 10.0), t_end_s=0.6, noise=0.0)
    t = df["t_s"].to_numpy()
    w0 = df.attrs["steady_state"]["w"]
    z = params.rs + 1j * params.xp
    lam = -(1 + 1j * (params.x - params.xp) / z) / params.tp_s + 1j * params.wb * (w0 - 1)
    after = t >= 0.1 - 1e-12
    e = (df["ed"] + 1j * df["eq"]).to_numpy()[after]
    k0 = np.flatnonzero(after)[0]
    expected = e[0] * np.exp(lam * (t[after] - t[k0]))
    assert np.max(np.abs(e - expected)) < 1e-8
    assert abs(e[-1]) < 0.05 * abs(e[0])  # it really decayed


def test_sag_makes_speed_dip_and_recover(records) -> None:
    for name, df in records.items():
        w, t = df["w"].to_numpy(), df["t_s"].to_numpy()
        w0 = df.attrs["steady_state"]["w"]
        dip = w0 - w.min()
        assert dip > 1e-3, name
        assert 0.5 < t[np.argmin(w)] < 0.8, name  # lowest at the end of the sag
        assert abs(w[-1] - w0) < 0.05 * dip, name


# --- noise -----------------------------------------------------------------------------


def test_noise_sd_is_fraction_of_channel_rms() -> None:
    noise = 0.05
    df = simulate("small_industrial", noise=noise, seed=3, noise_on_regressors=True)
    n = len(df)
    for key in ("ded", "deq", "dw", "id", "iq", "ed", "eq", "w", "ud"):
        true = df[f"{key}_true"].to_numpy()
        expected = noise * np.sqrt(np.mean(true**2))
        added = df[key].to_numpy() - true
        # The sd of n normal draws has relative sd 1/sqrt(2n) (1.3% here); allow 4 of them.
        assert np.std(added) == pytest.approx(expected, rel=4 / np.sqrt(2 * n)), key
        assert df.attrs["noise_sd"][key] == pytest.approx(expected, rel=1e-12)
    assert (df["uq"] == 0).all()  # zero RMS, zero noise


def test_noise_is_reproducible_and_targets_only_by_default() -> None:
    a = simulate("large_industrial", seed=7)
    b = simulate("large_industrial", seed=7)
    pd.testing.assert_frame_equal(a, b)
    for key in ("ed", "eq", "w", "ud", "uq"):
        np.testing.assert_array_equal(a[key], a[f"{key}_true"])
    assert not np.array_equal(a["ded"], a["ded_true"])


# --- disturbances and files ---------------------------------------------------------------


def test_disturbance_profiles() -> None:
    s = sag(0.25, 0.5, 0.2, recovery_s=0.1)
    np.testing.assert_allclose(
        s([0.0, 0.4999, 0.5, 0.6, 0.7, 0.75, 0.8, 5.0]), [1, 1, 0.75, 0.75, 0.75, 0.875, 1, 1]
    )
    assert s.left_limit(0.5) == 1.0 and s(0.5) == 0.75
    r = ramp(0.9, 1.0, 2.0)
    np.testing.assert_allclose(r([0.0, 1.0, 2.0, 3.0, 9.0]), [1, 1, 0.95, 0.9, 0.9])
    rw = random_walk(0.05, seed=1, t_end_s=3.0)
    v = rw(np.linspace(0, 3, 301))
    assert v[0] == 1.0 and np.std(np.diff(v)) > 0
    np.testing.assert_array_equal(v, random_walk(0.05, seed=1, t_end_s=3.0)(np.linspace(0, 3, 301)))


def test_from_file_and_csv_round_trip(tmp_path) -> None:
    profile = tmp_path / "v.csv"
    pd.DataFrame({"t_s": [0.0, 0.5, 0.5, 0.7, 0.9], "v_pu": [1.0, 1.0, 0.8, 0.8, 1.0]}).to_csv(
        profile, index=False
    )
    d = from_file(profile)
    np.testing.assert_allclose(d([0.2, 0.5, 0.6, 0.8, 2.0]), [1.0, 0.8, 0.8, 0.9, 1.0])
    assert d.breakpoints == (0.5,)
    df = simulate("krause_2250hp", disturbance=d, t_end_s=1.0, seed=2)
    csv_path, json_path = write_csv(df, tmp_path / "run.csv")
    assert json_path == tmp_path / "run.json"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.json", "v.csv"]
    meta = json.loads(json_path.read_text())
    assert meta["coefficients"] == df.attrs["coefficients"]
    back = read_csv(csv_path)
    pd.testing.assert_frame_equal(back, df, check_exact=True)
    assert back.attrs["t0"] == df.attrs["t0"]
    for key in COEFFICIENT_NAMES:
        assert back.attrs["coefficients"][key] == MOTORS["krause_2250hp"].coefficients()[key]
