"""The list of samplers under test: one entry per sampler, with its design and notes."""

from __future__ import annotations

from loadbayes.studies.calibration.composite_sbc import composite_sampler
from loadbayes.studies.calibration.registry.motor import im_sampler
from loadbayes.studies.calibration.registry.online import online_sampler
from loadbayes.studies.calibration.registry.robust import robust_sampler
from loadbayes.studies.calibration.registry.zip import (
    BUS18_BAND,
    WIDE_BAND,
    ZIP_PRIOR,
    ZIP_PRIOR_AUTO,
    ZIP_PRIOR_CONJ,
    zip_sampler,
)
from loadbayes.testing.sbc import SamplerUnderTest


def entries() -> list[SamplerUnderTest]:
    """Every sampler under test, in the order SBC reports them."""
    return [
        zip_sampler(
            "zip-blocked",
            scheme="blocked",
            prior=ZIP_PRIOR,
            band=BUS18_BAND,
            with_q=True,
            thin=2,
            notes="P and Q, n = 50 on the bus-18 band (a1-a2 ridge); independent prior; thin 2",
        ),
        zip_sampler(
            "zip-single-site",
            scheme="single-site",
            prior=ZIP_PRIOR,
            band=WIDE_BAND,
            thin=50,
            kept=499,
            notes="P, n = 50 on a wide band (0.3-1.7 p.u.: a1-a2 correlation about -0.96 "
            "instead of -0.99); independent prior; thin 50",
        ),
        zip_sampler(
            "zip-exact",
            scheme="exact",
            prior=ZIP_PRIOR_CONJ,
            band=BUS18_BAND,
            with_q=True,
            notes="P and Q, n = 50 on the bus-18 band; conjugate prior; independent draws",
        ),
        zip_sampler(
            "zip-blocked-conjugate",
            scheme="blocked",
            prior=ZIP_PRIOR_CONJ,
            band=BUS18_BAND,
            thin=2,
            notes="P, n = 50 on the bus-18 band; conjugate prior through the Gibbs kernel; thin 2",
        ),
        zip_sampler(
            "zip-auto-blocked",
            scheme="blocked",
            prior=ZIP_PRIOR_AUTO,
            band=(0.85, 1.15),
            thin=2,
            auto=True,
            notes="P with unknown nominal power (block p0, d1, d2; shares d/p0), n = 50 "
            "on 0.85-1.15 p.u.; thin 2",
        ),
        im_sampler(
            "im-modelled-blocked",
            scheme="blocked",
            currents="modelled",
            thin=100,
            kept=99,
            notes="motor, modelled currents (the coupled sampler, the default); small "
            "industrial motor's sag record, n = 301; b3 and (ab, ac) decorrelate slowly "
            "(autocorrelation 0.73 at lag 1, 0.17 at lag 40), so 99 draws one in 100",
        ),
        im_sampler(
            "im-modelled-single-site",
            scheme="single-site",
            currents="modelled",
            thin=150,
            kept=99,
            notes="motor, modelled currents, one coefficient at a time (ab: autocorrelation "
            "0.96 at lag 1, 0.29 at lag 40); 99 draws one in 150",
        ),
        im_sampler(
            "im-measured-blocked",
            scheme="blocked",
            currents="measured",
            thin=2,
            notes="motor, the paper's form (three conjugate blocks, measured currents "
            "as regressors); thin 2",
        ),
        im_sampler(
            "im-measured-single-site",
            scheme="single-site",
            currents="measured",
            thin=5,
            kept=499,
            notes="motor, the paper's form, one coefficient at a time; thin 5",
        ),
        im_sampler(
            "im-measured-exact",
            scheme="exact",
            currents="measured",
            conjugate=True,
            notes="motor, the paper's form with conjugate priors; independent draws",
        ),
        robust_sampler(
            "robust-nu4",
            nu=4.0,
            kept=199,
            notes="Student-t Gibbs (latent weights), nu = 4 fixed; P, n = 50 on the bus-18 "
            "band, t4 noise; 199 draws, thin 5",
        ),
        robust_sampler(
            "robust-nu-auto",
            nu="auto",
            notes="Student-t Gibbs with nu sampled (Metropolis on log nu, weights "
            "integrated out) from its Gamma(2, 0.1) prior on [1, 1000]; 199 draws, thin 10",
            thin=10,
            kept=199,
        ),
        composite_sampler(
            "composite-mwg",
            # One in 80 (was 40, then 50): with the 5 ms RK4 step the lag-1 guard's
            # largest median came to 0.099 at one in 40, and with the sag's step instant
            # sampled too, 0.131 (log_t_prime) at one in 50. 39 kept draws (40 ranks, 2
            # per bin) keep the cost as it was.
            thin=80,
            kept=39,
            burn=600,
            # 50 in CI (10 bins, 5 ranks a bin expected; 100 until 30 Nov 2026, cut for
            # make test's 12 minutes), 100 in make validate's pytest, 1000 in
            # studies/calibration/run.py; the false-alarm rate stays near 1e-3 (2.3e-3
            # simulated at 50), the power to see a bias drops (tests/statistical/test_sbc.py).
            ci_replications=50,
            notes="composite ZIP + motor (adaptive Metropolis on the motor's scale-free "
            "coordinates with the linear block integrated out, then beta and tau exact); "
            "a 35% sag, 1.5 s at 30 samples/s, its step's instant drawn; 39 draws one in "
            "80 after 600",
        ),
        online_sampler(
            "online-exact",
            mode="exact",
            notes="online tracker, recursive Bayes over all 50 samples; the last "
            "posterior's marginals",
        ),
        online_sampler(
            "online-window",
            mode="window",
            notes="online tracker, sliding window of the last 30 of 50 samples",
        ),
        online_sampler(
            "online-drift",
            mode="drift",
            notes="online tracker, random-walk drift (sd 0.5 / sqrt(tau) per sample, a "
            "dynamic linear model): the truth is the coefficients at the last sample",
        ),
    ]
