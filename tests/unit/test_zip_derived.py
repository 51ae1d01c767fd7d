"""The ``derived`` section of a ZIP fit: dP/dV and dQ/dV at v0, draw by draw (issue 22)."""

import json

import numpy as np
import pytest

from loadbayes import fit_zip
from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.report.text import summary_table


@pytest.fixture(scope="module")
def post():
    # A generator written here: a1, a2, a3 = 0.3, 0.2, 0.5 (dP/dV = 0.8), Q 0.6, 0.1 (1.3).
    rng = np.random.default_rng(4)
    v = rng.uniform(0.9, 1.1, 400)
    p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, v.size)
    q = 0.6 * v**2 + 0.1 * v + 0.3 + rng.normal(0, 0.01, v.size)
    return fit_zip(
        {"v": v, "p": p, "q": q},
        sampler=SamplerSettings(draws=1500, burn=300, chains=2, seed=3),
        warn=False,
    )


def test_derived_is_2a1_plus_a2_per_draw(post):
    np.testing.assert_array_equal(post.derived["dP/dV"], 2 * post["a1"] + post["a2"])
    np.testing.assert_array_equal(post.derived["dQ/dV"], 2 * post["a4"] + post["a5"])


def test_derived_in_json_covers_truth(post):
    d = json.loads(json.dumps(post.to_dict()))["derived"]
    for name, truth in (("dP/dV", 0.8), ("dQ/dV", 1.3)):
        row = d[name]
        assert set(row) >= {"mean", "sd", "hdi_low", "hdi_high", "unit"}
        assert row["hdi_low"] < truth < row["hdi_high"]
        # the sensitivity is far better determined than a1 or a2 alone
        assert row["sd"] < 0.2 * float(post["a1"].std())
        assert "per unit of P0" in row["unit"]


def test_derived_printed_in_table(post):
    text = summary_table(post)
    assert "dP/dV" in text and "dQ/dV" in text
    assert max(len(line) for line in text.splitlines()) <= 80


def test_report_shows_no_green_box_over_a_confounded_fit(post):
    from loadbayes.report.fit_report import fit_report

    d = json.loads(json.dumps(post.to_dict()))
    page = fit_report(d)
    assert "<p class='ok'>Chains agree" in page and "dP/dV" in page
    d["warnings"].append(
        "the load level changes over the record and the voltage follows it: the fit "
        "confuses the two; use --level drift or fit the voltage steps (dP/dV < 0)."
    )
    page = fit_report(d)
    assert "<p class='ok'>Chains agree" not in page
    assert "<p class='warn'>The chains agree, but on a confounded answer" in page


def test_negative_dp_dv_is_said_without_a_time_column():
    # A load whose power falls as the voltage rises (dP/dV = -1): not a load.
    rng = np.random.default_rng(8)
    v = rng.uniform(0.95, 1.05, 300)
    p = 1.0 - (v - 1.0) + rng.normal(0, 0.002, v.size)
    fit = fit_zip(
        {"v": v, "p": p},
        sampler=SamplerSettings(draws=800, burn=200, chains=2),
        spec=DataSpec(q_col=None),
        warn=False,
    )
    said = [w for w in fit.warnings if "the load level changes over the record" in w]
    assert said and "dP/dV at v0 is negative" in said[0] and "--t-col" in said[0]
