"""The samplers under test: one :class:`~loadbayes.testing.sbc.SamplerUnderTest` each.

:data:`REGISTRY` is what the SBC and coverage tests (``tests/statistical``) and
``make validate`` iterate over. To put a new sampler under test (the exponential model,
a composite ZIP + motor estimator), write its prior simulator, data simulator and fit
function and add one entry to :func:`~.entries.entries`; nothing else changes.

Every fit goes through the package's own path (the model's Gram columns, the block
statistics, the sampler, the transforms), with one chain thinned until the kept draws
are nearly independent; the lag-1 autocorrelation of what is kept is reported by SBC.

Designs (why they are what they are)
------------------------------------
ZIP, blocked and exact: the paper's bus-18 voltage band (0.66-0.89 p.u.), where a1 and
a2 sit on a ridge (posterior correlation near -0.99): the case blocking is for.
ZIP, single-site: one coefficient at a time crawls along that ridge (lag-1
autocorrelation ~0.98 per sweep), so its SBC uses a wide band (0.3-1.7 p.u., correlation
about -0.96) and keeps one sweep in 50; the ridge itself is covered by the comparison
with the exact posterior in ``tests/statistical/test_zip_posterior.py``.
Motor: a clean simulated record of the small industrial motor (the default 25% sag),
every 10th sample (n = 301), T0 given; the targets are redrawn from the regression model
given the coefficients, with one noise precision per block as the model has it.
Student-t: ZIP P on the bus-18 band with t noise (nu fixed at 4, or drawn from the
sampler's own prior on nu). Online: the tracker's last posterior, exact, over a sliding
window, and with random-walk drift (then the truth is the end of the simulated walk).
Composite: ``studies/calibration/composite_sbc.py`` (a short sag, the motor's scale-free
coordinates, the seven linear coefficients and the noise precisions drawn from the fit's
prior); 200 replications in CI (each fit runs a few thousand ODE solves).

Layout: one module per model (``zip``, ``motor``, ``robust``, ``online``) builds its
samplers under test; ``entries`` lists them; every public name is importable from here.
"""

from __future__ import annotations

from loadbayes.studies.calibration.registry.entries import entries
from loadbayes.studies.calibration.registry.motor import im_sampler, im_truth
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

__all__ = [
    "BUS18_BAND",
    "REGISTRY",
    "WIDE_BAND",
    "ZIP_PRIOR",
    "ZIP_PRIOR_AUTO",
    "ZIP_PRIOR_CONJ",
    "im_sampler",
    "im_truth",
    "online_sampler",
    "robust_sampler",
    "zip_sampler",
]

#: Every sampler under test, by name.
REGISTRY: dict[str, SamplerUnderTest] = {e.name: e for e in entries()}
