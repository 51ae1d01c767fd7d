"""The settings objects: built once, checked once (core/settings.py), and the chain runner."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.commands.options import MOTOR_NAMES
from loadbayes.core.parallel import chain_generators, run_chains
from loadbayes.core.settings import DataSpec, SamplerSettings, check_iterations
from loadbayes.models.motor_library import MOTORS


def test_the_cli_names_every_library_motor():
    assert MOTOR_NAMES == tuple(MOTORS)


@pytest.mark.parametrize(
    "bad",
    [
        {"burn": 10, "draws": 10},
        {"burn": -1},
        {"chains": 0},
        {"thin": 0},
        {"draws": 0, "burn": 0},
        {"hdi_prob": 1.0},
        {"init": "random"},
        {"threads": 0},
    ],
)
def test_sampler_settings_refuse_what_no_sampler_can_run(bad):
    with pytest.raises(ValueError):
        SamplerSettings(**bad)


def test_kept_draws_and_overrides():
    s = SamplerSettings(draws=1000, burn=100, thin=7)
    assert s.kept == len(range(100, 1000, 7))
    assert SamplerSettings.of(s, seed=3, chains=None) == s.with_(seed=3)
    with pytest.raises(TypeError, match="unknown sampler setting"):
        SamplerSettings.of(s, drawz=3)
    with pytest.raises(ValueError, match="burn-in"):
        check_iterations(5, 5)


def test_data_spec_reads_none_as_no_q_and_refuses_bad_values():
    assert DataSpec(q_col="none").q_col is None and not DataSpec(q_col="None").with_q
    with pytest.raises(ValueError, match="positive"):
        DataSpec(s_base=0.0)
    with pytest.raises(ValueError, match="two quantities"):
        DataSpec(p_col="v")


def test_data_spec_takes_any_finite_non_zero_nominal_power():
    # A capacitive load has q0 < 0; a negative p0 is refused later, by the unit check.
    assert DataSpec(q0=-0.3).q0 == -0.3 and DataSpec(p0=-1.0).p0 == -1.0
    for bad in (0.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="q0 must be a finite non-zero number"):
            DataSpec(q0=bad)
        with pytest.raises(ValueError, match="p0 must be a finite non-zero number"):
            DataSpec(p0=bad)
    for name in ("v_base", "s_base", "v0"):
        with pytest.raises(ValueError, match=f"{name} must be a positive number"):
            DataSpec(**{name: -1.0})


def test_data_spec_of_keeps_what_is_not_given():
    d = DataSpec(v_col="V", v_base=400.0)
    assert DataSpec.of(d, p_col="P", v_base=None) == DataSpec(v_col="V", p_col="P", v_base=400.0)
    assert DataSpec.of(None, q0=-0.5) == DataSpec(q0=-0.5)
    with pytest.raises(TypeError, match="unknown data setting"):
        DataSpec.of(d, vcol="x")
    with pytest.raises(ValueError, match="positive"):
        DataSpec.of(d, s_base=-2.0)


@pytest.mark.parametrize("workers", [1, 2, 3, 5])
def test_run_chains_results_do_not_depend_on_the_threads(workers):
    def chain(i, rng):
        return i, rng.standard_normal(4)

    ref = [(i, g.standard_normal(4)) for i, g in enumerate(chain_generators(11, 5))]
    out = run_chains(chain, chain_generators(11, 5), workers=workers)
    assert [i for i, _ in out] == list(range(5))
    for (_, a), (_, b) in zip(ref, out, strict=True):
        np.testing.assert_array_equal(a, b)


def test_run_chains_raises_a_chains_error():
    def chain(i, rng):
        if i == 2:
            raise RuntimeError("chain 2 failed")
        return i

    with pytest.raises(RuntimeError, match="chain 2"):
        run_chains(chain, chain_generators(0, 4), workers=2)
