"""A given P0 (Q0) that the data place away from the power at V0 is said in a warning.

Inside the unit check's range (1/1.5 to 1.5) the fit runs, but the model holds
P(V0) = P0, so the shares take up the difference (a red-team bus given P0 1.0 for a true
0.714 came out with a1 near 30 and no word).
"""

import numpy as np
import pandas as pd

from loadbayes.fleet.partitions import ReadSpec
from loadbayes.fleet.run import fleet_statistics
from loadbayes.measurements.units import nominal_level_warnings, nominal_level_warnings_gram


def _bus(rng, level, n=300, noise=0.003):
    v = 1.0 + rng.uniform(-0.03, 0.03, n)
    p = level * (0.3 * v**2 + 0.3 * v + 0.4) * (1 + noise * rng.standard_normal(n))
    return v, p


def _two_bus_fleet(rng, folder) -> str:
    """b0 at 0.714 of the P0 (Q0) the fleet will be given, b1 at it: one Parquet file."""
    frames = []
    for b, level in (("b0", 0.714), ("b1", 1.0)):
        v, p = _bus(rng, level)
        frames.append(pd.DataFrame({"bus_id": b, "v": v, "p": p, "q": 0.5 * p}))
    path = folder / "f.parquet"
    pd.concat(frames).to_parquet(path)
    return str(path)


def test_an_off_p0_is_said_and_a_right_one_or_auto_is_not():
    rng = np.random.default_rng(0)
    v, p = _bus(rng, 0.714)
    (words,) = nominal_level_warnings(v, p, p0=1.0)
    assert "P / P0 is about 0.714" in words and "--p0 auto" in words
    assert nominal_level_warnings(v, p, p0=0.714) == []
    assert nominal_level_warnings(v, p, p0=0.73) == []  # 2% off: within 5%
    assert nominal_level_warnings(v, p, p0="auto") == []
    assert "p0='auto'" in nominal_level_warnings(v, p, p0=1.0, wording="python")[0]


def test_silent_when_the_data_cannot_place_the_level():
    # 6 rows of 30% noise: 10% off is well inside 4 standard errors
    rng = np.random.default_rng(1)
    v, p = _bus(rng, 0.9, n=6, noise=0.3)
    assert nominal_level_warnings(v, p, p0=1.0) == []
    # no voltage spread: nothing said here (the fit's own checks speak)
    assert nominal_level_warnings(np.ones(50), np.full(50, 0.7), p0=1.0) == []


def test_the_fleet_form_from_the_gram_matrix_agrees(tmp_path):
    path = _two_bus_fleet(np.random.default_rng(2), tmp_path)
    stats, model, _ = fleet_statistics(path, ReadSpec(), p0=1.0, q0=0.5)
    nominal = {"p": 1.0, "q": 0.5}
    said = {
        str(stats.buses[i]): nominal_level_warnings_gram(stats.bus_gram(i), nominal=nominal)
        for i in range(stats.buses.size)
    }
    assert said["b1"] == []
    assert len(said["b0"]) == 2 and "0.714" in said["b0"][0]


def test_a_fleet_with_a_given_p0_puts_the_words_on_the_bus_rows(tmp_path):
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fleet.run import run_fleet

    path = _two_bus_fleet(np.random.default_rng(3), tmp_path)
    res = run_fleet(
        path, ReadSpec(), pool="none", p0=1.0, q0=0.5,
        sampler=SamplerSettings(chains=2, draws=200, burn=50),
    )  # fmt: skip
    words = res.table[res.table["level"] == "bus"].groupby("bus")["warnings"].first()
    assert "P / P0 is about 0.714" in words["b0"]
    assert "P / P0" not in words["b1"]


def test_a_bus_the_unit_check_spoke_of_gets_its_words_not_these_too(tmp_path):
    # --accept-units: b0 at 1.6 times the given P0 (outside 1/1.5..1.5) is fitted with the
    # unit check's words; the level words would repeat them, as one bus's fit does not.
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fleet.run import run_fleet

    rng = np.random.default_rng(4)
    v, p = _bus(rng, 1.6)
    path = tmp_path / "f.parquet"
    pd.DataFrame({"bus_id": "b0", "v": v, "p": p, "q": 0.5 * p}).to_parquet(path)
    res = run_fleet(
        str(path), ReadSpec(), pool="none", p0=1.0, q0=0.5, accept_units=True,
        sampler=SamplerSettings(chains=2, draws=200, burn=50),
    )  # fmt: skip
    words = res.table.loc[res.table["level"] == "bus", "warnings"].iloc[0]
    assert words.startswith("units: ")
    assert "P / P0 is about" not in words
