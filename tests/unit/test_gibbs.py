import numpy as np
import pytest

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import RegressionStats
from loadbayes.inference.gibbs import exact_posterior, sample_block


def _stats(n=200, seed=0, noise=0.1, lo=0.7, hi=1.1):
    rng = np.random.default_rng(seed)
    x = rng.uniform(lo, hi, n)
    z = np.column_stack([x**2 - 1, x - 1])
    r = z @ np.array([0.4, 0.3]) + rng.normal(0, noise, n)
    return RegressionStats(z.T @ z, z.T @ r, float(r @ r), n)


@pytest.mark.parametrize("scheme", ["blocked", "single-site", "exact"])
def test_shapes_and_seed_reproducibility(scheme):
    st = _stats()
    prior = BlockPrior.weak(2, conjugate=scheme == "exact")
    a = sample_block(
        st,
        prior,
        scheme=scheme,
        settings=SamplerSettings(chains=3, draws=500, burn=100, thin=2, seed=5),
    )
    b = sample_block(
        st,
        prior,
        scheme=scheme,
        settings=SamplerSettings(chains=3, draws=500, burn=100, thin=2, seed=5),
    )
    assert a.coef.shape == (3, 200, 2) and a.tau.shape == (3, 200)
    assert np.array_equal(a.coef, b.coef) and np.array_equal(a.tau, b.tau)
    c = sample_block(
        st,
        prior,
        scheme=scheme,
        settings=SamplerSettings(chains=3, draws=500, burn=100, thin=2, seed=6),
    )
    assert not np.array_equal(a.coef, c.coef)
    assert np.all(np.isfinite(a.coef)) and np.all(a.tau > 0)


def test_chains_are_independent_of_how_many_run():
    st = _stats()
    prior = BlockPrior.weak(2)
    two = sample_block(st, prior, settings=SamplerSettings(chains=2, draws=300, burn=0, seed=9))
    four = sample_block(st, prior, settings=SamplerSettings(chains=4, draws=300, burn=0, seed=9))
    assert np.array_equal(two.coef, four.coef[:2])


def test_exact_requires_conjugate_prior():
    with pytest.raises(ValueError, match="conjugate"):
        sample_block(
            _stats(),
            BlockPrior.weak(2),
            scheme="exact",
            settings=SamplerSettings(draws=10, burn=0, seed=None),
        )


def test_bad_settings():
    st = _stats()
    with pytest.raises(ValueError, match="burn-in"):
        sample_block(st, BlockPrior.weak(2), settings=SamplerSettings(draws=10, burn=10, seed=None))
    with pytest.raises(ValueError, match="scheme"):
        sample_block(
            st,
            BlockPrior.weak(2),
            scheme="nuts",
            settings=SamplerSettings(draws=10, burn=0, seed=None),
        )
    with pytest.raises(ValueError, match="coefficients"):
        sample_block(st, BlockPrior.weak(3), settings=SamplerSettings(draws=10, burn=0, seed=None))


def test_exact_posterior_matches_direct_formula():
    st = _stats(n=50)
    prior = BlockPrior(mean=[0.1, -0.2], precision=[2.0, 3.0], shape=2.0, rate=0.5, conjugate=True)
    post = exact_posterior(st, prior)
    lam = prior.precision + st.ztz
    mn = np.linalg.solve(lam, prior.precision @ prior.mean + st.ztr)
    rate = 0.5 + 0.5 * (st.rtr + prior.mean @ prior.precision @ prior.mean - mn @ lam @ mn)
    np.testing.assert_allclose(post["mean"], mn, rtol=1e-10)
    np.testing.assert_allclose(post["rate"], rate, rtol=1e-8)
    assert post["shape"] == 2.0 + 25


def test_noise_free_data_stay_finite():
    rng = np.random.default_rng(0)
    x = rng.uniform(0.8, 1.2, 100)
    z = np.column_stack([x**2 - 1, x - 1])
    r = z @ np.array([0.4, 0.3])
    st = RegressionStats(z.T @ z, z.T @ r, float(r @ r), 100)
    for scheme in ("blocked", "single-site"):
        d = sample_block(
            st,
            BlockPrior.weak(2),
            scheme=scheme,
            settings=SamplerSettings(chains=2, draws=2000, burn=500, seed=1),
        )
        assert np.all(np.isfinite(d.coef)) and np.all(np.isfinite(d.tau))
        if scheme == "blocked":
            # Single-site crawls along the ridge when tau is huge: finite, not converged.
            np.testing.assert_allclose(d.coef.mean(axis=(0, 1)), [0.4, 0.3], atol=1e-6)


def test_prior_validation():
    with pytest.raises(ValueError):
        BlockPrior(mean=[0, 0], precision=[1.0, -1.0])
    with pytest.raises(ValueError):
        BlockPrior(mean=[0, 0], precision=[1.0, 1.0], shape=0.0)
    with pytest.raises(ValueError):
        BlockPrior.weak(2, sd=0.0)
    with pytest.raises(ValueError):
        BlockPrior(mean=[0, 0], precision=[0.0, 1.0], conjugate=True)


@pytest.mark.parametrize("scheme", ["blocked", "single-site"])
def test_a_requested_stop_ends_the_chains(scheme):
    # The CLI's signal handler calls request_stop; when a library swallows the
    # KeyboardInterrupt (a bare except during an import), the sampler must still stop
    # rather than run its draws and go on to summarise them (CI saw exactly that).
    from loadbayes.core.parallel import ChainsStopped, clear_stop, request_stop

    request_stop()
    try:
        with pytest.raises(ChainsStopped):
            sample_block(_stats(), BlockPrior.weak(2), scheme=scheme,
                         settings=SamplerSettings(chains=2, draws=200_000, seed=1))  # fmt: skip
    finally:
        clear_stop()
    sample_block(_stats(), BlockPrior.weak(2), scheme=scheme,
                 settings=SamplerSettings(chains=2, draws=500, burn=100, seed=1))  # fmt: skip
