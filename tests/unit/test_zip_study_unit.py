"""Fast pieces of the ZIP study: error definitions, Table II, the needed-n law, the report."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from loadbayes.studies import zip_paper as zip_study
from loadbayes.studies.zip_paper import PAPER_TABLE2, error_pct, required_n, table2


def test_error_pct_is_mean_absolute_relative_error_in_percent():
    assert error_pct([1.01, 0.99, 2.0], [1.0, 1.0, 2.0]) == pytest.approx(100 * (0.01 + 0.01) / 3)
    # Sign does not matter, the reference does: |est - true| / |true|.
    assert error_pct([0.9], [1.0]) == pytest.approx(10.0)
    assert error_pct([1.0], [0.9]) == pytest.approx(100 * 0.1 / 0.9)


def test_error_pct_leaves_out_failed_power_flows():
    assert error_pct([1.1, np.nan, 1.0], [1.0, 1.0, np.nan]) == pytest.approx(10.0)
    assert math.isnan(error_pct([np.nan], [1.0]))


def test_required_n_follows_one_over_sqrt_n():
    # sd 0.4 at n = 1000 -> sd 0.004 needs 100^2 times the data.
    assert required_n(0.4, 1000, 0.004) == pytest.approx(1e7)
    assert required_n(0.1, 500, 0.1) == pytest.approx(500)
    with pytest.raises(ValueError, match="positive"):
        required_n(0.0, 1000, 0.01)


def _validation(n: int = 50) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    v = rng.uniform(0.7, 0.9, n)
    p = rng.uniform(0.8, 0.95, n)
    cols = {"v_true_pu": v, "p_true_pu": p}
    for m, rel in (("gs", 1e-4), ("ls", 2e-4), ("kf", 3e-4), ("other", 5e-4)):
        sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
        cols[f"v_{m}_pu"] = v * (1 + sign * rel)
        cols[f"p_{m}_pu"] = p * (1 + sign * 100 * rel)
    return pd.DataFrame(cols)


def _estimate(a1: float, a2: float) -> dict[str, float]:
    return {"a1": a1, "a2": a2, "a3": 1 - a1 - a2}


def test_table2_rows_columns_and_paper_values():
    est = {"gs": _estimate(0.3, 0.2), "ls": _estimate(0.35, 0.1), "kf": _estimate(0.25, 0.25)}
    t = table2(_validation(), est)
    assert list(t.index) == ["GS", "LS", "KF"]
    for col in ("voltage_error_pct", "power_error_pct", "a1", "a2", "a3", "a1_err"):
        assert col in t.columns
    np.testing.assert_allclose(t.voltage_error_pct, [0.01, 0.02, 0.03], rtol=1e-9)
    np.testing.assert_allclose(t.power_error_pct, [1.0, 2.0, 3.0], rtol=1e-9)
    for row, (v, p) in PAPER_TABLE2.items():
        assert t.loc[row, "paper_voltage_error_pct"] == v
        assert t.loc[row, "paper_power_error_pct"] == p
    assert t.loc["GS", "a1_err"] == pytest.approx(0.05)
    assert t.loc["LS", "a2_err"] == pytest.approx(-0.15)
    assert t.loc["KF", "a3_err"] == pytest.approx(0.0, abs=1e-15)
    assert (t.n_failed == 0).all()


def test_table2_keeps_other_methods_without_a_paper_value():
    t = table2(_validation(), {"other": _estimate(0.2, 0.3)})
    assert list(t.index) == ["other"]
    assert math.isnan(t.loc["other", "paper_voltage_error_pct"])
    assert t.loc["other", "voltage_error_pct"] == pytest.approx(0.05)


def test_table2_counts_failed_flows():
    val = _validation()
    val.loc[3, "v_gs_pu"] = np.nan
    val.loc[3, "p_gs_pu"] = np.nan
    t = table2(val, {"gs": _estimate(0.25, 0.25)})
    assert t.loc["GS", "n_failed"] == 1
    assert np.isfinite(t.loc["GS", "voltage_error_pct"])


def test_needed_n_uses_the_largest_n_of_each_noise():
    sweep = pd.DataFrame(
        {
            "noise": [0.1, 0.1, 0.01, 0.01],
            "n": [100, 1000, 100, 1000],
            "n_used": [100, 1000, 100, 1000],
            "a1_sd_ls": [1.2, 0.4, 0.12, 0.04],
        }
    )
    need = zip_study.needed_n(sweep, targets=(0.004,))
    got = dict(zip(need.noise, need["n_for_sd_0.004"], strict=True))
    assert got[0.1] == pytest.approx(1e7)
    assert got[0.01] == pytest.approx(1e5)


def test_validation_seed_is_fresh_and_reproducible():
    s = zip_study._validation_seed(0)
    assert s == zip_study._validation_seed(0)
    assert s not in (0, 1) and s != zip_study._validation_seed(1)


def test_run_refuses_bad_settings_before_any_power_flow():
    with pytest.raises(ValueError, match="noise"):
        zip_study.run(noise=0.0, quick=True)
    with pytest.raises(ValueError, match="at least 10"):
        zip_study.run(n=5, quick=True)
    with pytest.raises(ValueError, match="burn"):
        zip_study.run(quick=True, sampler={"draws": 100, "burn": 100})


def test_output_paths_hold_the_issue_files(tmp_path):
    names = {p.name for p in zip_study.output_paths(tmp_path)}
    for need in (
        "experiments.csv",
        "summary.json",
        "posterior.nc",
        "table2.csv",
        "validation.csv",
        "sweep.png",
        "fig2_posterior.png",
        "fig5_burn_in.png",
    ):
        assert need in names
    assert all(p.parent == tmp_path / "zip" for p in zip_study.output_paths(tmp_path))


def test_update_report_replaces_its_own_section_and_keeps_others(tmp_path):
    path = tmp_path / "report.html"
    zip_study.update_report(path, "<section>zip one</section>")
    text = path.read_text()
    assert text.startswith("<!DOCTYPE html>") and "zip one" in text
    # Another study's section, as the motor study writes it.
    im_block = zip_study.marked("<section>motor</section>", "loadbayes:section im")
    path.write_text(text.replace("</body>", im_block + "\n</body>"))
    zip_study.update_report(path, "<section>zip two</section>")
    text = path.read_text()
    assert "zip two" in text and "zip one" not in text and "motor" in text
    assert text.count("<!-- loadbayes:section zip -->") == 1
    assert text.index("zip two") < text.index("motor")
