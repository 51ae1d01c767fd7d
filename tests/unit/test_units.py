"""The unit-plausibility check (issue 14): what it refuses, what it suggests, what it lets by."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from loadbayes.io.errors import DataError
from loadbayes.measurements.units import (
    check_motor_units,
    check_power_units,
    level_at_nominal,
)
from loadbayes.measurements.wording import refuse

DATA = Path(__file__).parents[1] / "data"


def _feeder_day(seed=0, n=1440, kv=12.47, mw=5.0, mvar=2.0):
    """One day of 1-minute data of a ZIP load (shares 0.4/0.3/0.3), in per unit."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    x = 1 + 0.03 * np.sin(2 * np.pi * t / n) + 0.002 * np.cumsum(rng.normal(0, 0.05, n))
    shape = 0.4 * x**2 + 0.3 * x + 0.3
    return x, shape * (1 + rng.normal(0, 0.002, n)), shape * (1 + rng.normal(0, 0.002, n))


def test_per_unit_data_pass():
    x, p, q = _feeder_day()
    assert check_power_units(x, p, q) == []
    assert check_power_units(x, p, q, p0="auto", q0="auto") == []


def test_kv_without_v_base_names_the_base():
    x, p, q = _feeder_day()
    (pr,) = check_power_units(12.47 * x, p, q)
    assert pr.column == "v" and "--v-base 12.47" in str(pr) and "--accept-units" in str(pr)


def test_line_to_neutral_kv_is_recognised():
    x, p, q = _feeder_day()
    (pr,) = check_power_units(12.47 / np.sqrt(3) * x, p, q)
    assert "line-to-neutral" in pr.fix and "12.47" in pr.fix


def test_volts_with_a_kv_base_is_caught():
    x, p, q = _feeder_day()
    # V in volts, --v-base given in kV by mistake: V / v_base is about 1000
    (pr,) = check_power_units(1000 * x, p, q, v_base=12.47)
    assert "--v-base 12.47" in pr.seen and pr.column == "v"


def test_mw_with_unit_p0_is_refused_and_auto_is_offered():
    x, p, q = _feeder_day()
    probs = check_power_units(x, 5.0 * p, 2.0 * q)
    assert [pr.column for pr in probs] == ["p", "q"]
    assert "--p0 auto" in probs[0].fix and "about 5" in probs[0].seen
    # with the right base and a wrong Q0 (1 p.u. of the base: issue item 9), Q only
    (pr,) = check_power_units(x, p, 0.4 * q, s_base=5.0)
    assert pr.column == "q" and "--q0 auto" in pr.fix


def test_auto_refuses_watts_but_takes_kw():
    x, p, q = _feeder_day()
    assert check_power_units(x, 90.0 * p, 40.0 * q, p0="auto", q0="auto") == []
    (pr,) = check_power_units(x, 5e6 * p, None, p0="auto")
    assert pr.column == "p" and "--s-base" in pr.fix


def test_a_load_off_its_rating_within_a_factor_1_5_passes():
    x, p, q = _feeder_day()
    assert check_power_units(x, 0.7 * p, 1.4 * q) == []


def test_level_at_nominal_is_the_models_intercept():
    x, p, _ = _feeder_day()
    assert level_at_nominal(x, 3.0 * p) == pytest.approx(3.0, rel=2e-3)
    assert level_at_nominal(np.ones(10), np.full(10, 2.0)) == 2.0


def test_ieee33_bus18_in_kw_and_kv():
    """The 33-bus feeder's bus 18 (pandapower runs, stored): kV, kW, kvar as exported."""
    df = pd.read_csv(DATA / "ieee33_bus18_kw_kv.csv")
    v, p, q = (df[c].to_numpy() for c in ("v_kv", "p_kw", "q_kvar"))
    (pr,) = check_power_units(v, p, q)
    # bus 18 sits near 0.79 p.u. under these loads: the median is shown, not guessed
    assert pr.column == "v" and "--v-base" in pr.fix and "median is 9.98" in pr.fix
    probs = check_power_units(v / 12.66, p, q)
    assert [pr.column for pr in probs] == ["p", "q"]
    assert check_power_units(v / 12.66, p / 90.0, q / 40.0) == []
    assert check_power_units(v / 12.66, p, q, p0="auto", q0="auto") == []


def test_motor_states_in_physical_units():
    from loadbayes.cases.motor_sim import simulate

    df = simulate("small_industrial", t_end_s=0.3, seed=0)
    cols = {c: df[c].to_numpy() for c in ("ud", "uq", "w", "id", "iq", "ed", "eq")}
    assert check_motor_units(cols) == []
    (pr,) = check_motor_units({**cols, "w": 2 * np.pi * 60 * cols["w"]})
    assert pr.column == "w" and "rad/s" in pr.seen
    kv = {**cols, "ud": 4.16 * cols["ud"], "uq": 4.16 * cols["uq"]}
    assert [pr.column for pr in check_motor_units(kv)] == ["ud/uq"]


def test_refuse_names_the_users_column():
    x, p, q = _feeder_day()
    with pytest.raises(DataError, match=r"bus.csv: column 'V_kV': V / V0 has median"):
        refuse(check_power_units(12.47 * x, p, q), path="bus.csv", names={"v": "V_kV"})
    refuse([], path="bus.csv")  # nothing to say: no error
