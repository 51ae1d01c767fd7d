"""Degenerate but legal data: finite results and plain-words warnings, never NaN.

Covered: two distinct voltage levels (identifiable with a known P0, not with P0 = auto,
not when one level is V0 itself), a very narrow band, n = 3, noise-free data (tau
unbounded), very large n (through scaled sufficient statistics, up to 1e18 rows).
Voltage with no spread at all stays an error. pytest turns every RuntimeWarning into an
error here (``filterwarnings = error``), so an overflow or an invalid operation anywhere
on these paths fails the test.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import accumulate, fit_gram, fit_zip, zip_priors
from loadbayes.io.errors import DataError
from loadbayes.models.zip import ZIPModel

FAST = {"draws": 1500, "burn": 300, "chains": 2, "seed": 1}


def _zip(v, a=(0.3, 0.2, 0.5), noise=0.01, seed=0, with_q=False):
    rng = np.random.default_rng(seed)
    v = np.asarray(v, dtype=float)
    data = {"v": v, "p": a[0] * v**2 + a[1] * v + a[2] + noise * rng.standard_normal(v.size)}
    if with_q:
        data["q"] = a[2] * v**2 + a[0] * v + a[1] + noise * rng.standard_normal(v.size)
    return data


def _finite(post):
    for name, x in post.draws.items():
        assert np.all(np.isfinite(x)), name
    # The JSON contract holds no NaN or inf (json refuses them with allow_nan=False).
    json.dumps(post.to_dict(), allow_nan=False)


def _says(post, *words):
    text = " ".join(post.warnings)
    return all(w in text for w in words)


def test_two_voltage_levels_identify_a_known_nominal_power():
    post = fit_zip(
        _zip(np.repeat([0.9, 1.1], 50)),
        sampler=SamplerSettings(**FAST),
        spec=DataSpec(p0=1.0, q0=1.0),
    )
    _finite(post)
    # Two equations in two unknowns: identified, but only just; the ridge is reported.
    assert _says(post, "a1 and a2 cannot be told apart")
    m = post.mean()
    assert abs(m["a1"] + m["a2"] + m["a3"] - 1) < 1e-12


def test_two_voltage_levels_cannot_identify_three_coefficients():
    post = fit_zip(
        _zip(np.repeat([0.9, 1.1], 50)), sampler=SamplerSettings(**FAST), spec=DataSpec(p0=None)
    )
    _finite(post)
    assert _says(post, "cannot identify", "separately", "too few distinct voltage levels")


def test_a_level_at_nominal_voltage_carries_no_information_on_the_shares():
    # At V = V0 both regressors are 0: only one informative level is left.
    post = fit_zip(
        _zip(np.repeat([0.9, 1.0], 50)),
        sampler=SamplerSettings(**FAST),
        spec=DataSpec(p0=1.0, q0=1.0),
    )
    _finite(post)
    assert _says(post, "cannot identify a1, a2 separately")


@pytest.mark.parametrize("scheme", ["blocked", "single-site"])
def test_a_very_narrow_band_is_finite_and_said_so(scheme):
    v = np.random.default_rng(1).uniform(0.9995, 1.0005, 500)
    post = fit_zip(
        _zip(v), scheme=scheme, sampler=SamplerSettings(**FAST), spec=DataSpec(p0=1.0, q0=1.0)
    )
    _finite(post)
    assert _says(post, "voltage spans only", "hard to separate")


def test_three_samples_are_enough_for_a_known_nominal_power():
    post = fit_zip(
        _zip([0.9, 1.0, 1.1], with_q=True),
        sampler=SamplerSettings(**FAST),
        spec=DataSpec(p0=1.0, q0=1.0),
    )
    _finite(post)
    assert post.settings["n"] == 3


def test_three_samples_are_too_few_for_an_unknown_nominal_power():
    with pytest.raises(DataError, match="fewer than the 4 parameters"):
        fit_zip(_zip([0.9, 1.0, 1.1]), sampler=SamplerSettings(**FAST), spec=DataSpec(p0=None))


@pytest.mark.parametrize(
    ("scheme", "p0"), [("blocked", 1.0), ("single-site", 1.0), ("blocked", "auto")]
)
def test_noise_free_data_stay_finite(scheme, p0):
    v = np.random.default_rng(2).uniform(0.8, 1.2, 200)
    post = fit_zip(
        _zip(v, noise=0.0, with_q=True),
        scheme=scheme,
        sampler=SamplerSettings(**FAST),
        spec=DataSpec(p0=None if p0 == "auto" else p0, q0=None if p0 == "auto" else p0),
    )
    _finite(post)
    if scheme == "blocked":  # single-site crawls along the ridge when tau is this large
        assert np.all(post["tau_p"] > 1e6) and np.all(post["tau_q"] > 1e6)
        m = post.mean()
        np.testing.assert_allclose([m["a1"], m["a2"], m["a3"]], [0.3, 0.2, 0.5], atol=1e-6)
        np.testing.assert_allclose([m["a4"], m["a5"], m["a6"]], [0.5, 0.3, 0.2], atol=1e-6)


def test_noise_free_power_is_said_so():
    v = np.random.default_rng(2).uniform(0.8, 1.2, 200)
    post = fit_zip(
        _zip(v, noise=0.0), sampler=SamplerSettings(**FAST), spec=DataSpec(p0=1.0, q0=1.0)
    )
    assert _says(post, "the P data fit the model exactly (no noise)", "tau_p")


@pytest.mark.parametrize("p0", [1.0, "auto"])
def test_noise_free_reactive_power_is_said_so_too(p0):
    v = np.random.default_rng(2).uniform(0.8, 1.2, 200)
    post = fit_zip(
        _zip(v, noise=0.0, with_q=True),
        sampler=SamplerSettings(**FAST),
        spec=DataSpec(p0=None if p0 == "auto" else p0, q0=None if p0 == "auto" else p0),
    )
    assert _says(post, "the P data fit the model exactly", "the Q data fit the model exactly")


def test_exact_scheme_on_noise_free_data():
    v = np.random.default_rng(3).uniform(0.8, 1.2, 200)
    post = fit_zip(
        _zip(v, noise=0.0),
        scheme="exact",
        priors=zip_priors(conjugate=True),
        sampler=SamplerSettings(**FAST),
        spec=DataSpec(p0=1.0, q0=1.0),
    )
    _finite(post)


@pytest.mark.parametrize("rows", [1e9, 1e12, 1e18])
@pytest.mark.parametrize("scheme", ["blocked", "exact", "single-site"])
def test_very_large_n_through_the_statistics(rows, scheme):
    # The Gram of 1000 rows repeated `rows / 1000` times: what a file of `rows` rows with
    # the same spread would give. Posterior sds shrink as 1/sqrt(n), nothing overflows.
    v = np.random.default_rng(4).uniform(0.66, 0.89, 1000)
    model = ZIPModel(with_q=False)
    gram = accumulate(model, [_zip(v, a=(0.25, 0.25, 0.5), noise=0.1)])
    scale = rows / gram.n
    big = dataclasses.replace(gram, matrix=gram.matrix * scale, n=int(rows))
    priors = zip_priors(conjugate=scheme == "exact")
    small = fit_gram(model, gram, priors=priors, scheme=scheme, sampler=SamplerSettings(**FAST))
    post = fit_gram(model, big, priors=priors, scheme=scheme, sampler=SamplerSettings(**FAST))
    _finite(post)
    assert post.settings["n"] == int(rows)
    if scheme != "single-site":  # single-site is nowhere near converged on this ridge
        ratio = post["a3"].std() / small["a3"].std()
        assert 0.5 < ratio * np.sqrt(scale) < 2.0
        assert abs(post.mean()["a3"] - small.mean()["a3"]) < 5 * small["a3"].std()


def test_no_spread_at_all_stays_an_error():
    with pytest.raises(DataError, match="no spread"):
        fit_zip(
            _zip(np.full(20, 0.95)), sampler=SamplerSettings(**FAST), spec=DataSpec(p0=1.0, q0=1.0)
        )


@pytest.mark.parametrize("chunk_rows", [None, 7])
def test_power_zero_in_every_row_is_refused(tmp_path, chunk_rows):
    # An open breaker, or a PMU's current channel not recorded: P = 0 throughout. The
    # shares are fractions of P0 = 0; the fit used to "fit exactly" and report noise.
    from click.testing import CliRunner

    from loadbayes.cli import main

    v = np.linspace(0.95, 1.05, 40)
    data = {"v": v, "p": np.zeros_like(v), "q": 0.3 * v}
    with pytest.raises(DataError, match=r"P is 0 in all 40 rows: there is no load") as e:
        fit_zip(data, sampler=SamplerSettings(**FAST))
    assert e.value.column == "p"
    # From a file, streamed in chunks: the whole file is checked, not its first chunk.
    path = tmp_path / "dead.csv"
    path.write_text("v,p,q\n" + "".join(f"{x},0,{0.3 * x}\n" for x in v))
    chunks = [] if chunk_rows is None else ["--chunk-rows", str(chunk_rows)]
    args = ["fit", "zip", str(path), "--draws", "300", "--burn", "50", "--quiet", *chunks]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2 and "dead.csv: column 'p'" in res.output
    assert "P is 0 in every row" in res.output and "Traceback" not in res.output
    # A load that is off for its first rows (the first chunk) and then on is fitted.
    path.write_text(
        "v,p,q\n" + "".join(f"{x},{0.0 if i < 10 else x},{0.3 * x}\n" for i, x in enumerate(v))
    )
    assert CliRunner().invoke(main, args).exit_code == 0


def test_reactive_power_zero_in_every_row_says_fit_p_alone():
    v = np.linspace(0.95, 1.05, 40)
    with pytest.raises(DataError, match=r"Q is 0 in all 40 rows.*q_col=None") as e:
        fit_zip({"v": v, "p": v, "q": np.zeros_like(v)}, sampler=SamplerSettings(**FAST))
    assert e.value.column == "q"


def test_power_that_flows_out_is_fitted_and_said():
    # Generation (or a meter counting the other way): fitted as a negative load, said.
    v = np.linspace(0.95, 1.05, 60)
    data = _zip(v)
    data["p"] = -data["p"]
    post = fit_zip(data, sampler=SamplerSettings(**FAST))
    assert _says(post, "P has median", "< 0: the bus exports power")
    assert post.mean()["p0"] < 0
    assert not _says(fit_zip(_zip(v), sampler=SamplerSettings(**FAST)), "exports power")
