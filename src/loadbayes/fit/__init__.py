"""Fit a load model: one driver (:mod:`loadbayes.fit.core`) and a thin entry per model.

``fit_zip`` / ``fit_zip_file`` (ZIP), ``fit_exp`` (exponential), ``fit_im`` /
``fit_im_file`` (motor from its states), ``fit_robust`` (Student-t on any linear model),
``fit_steps`` (ZIP from the windows around voltage steps);
each builds a model from :mod:`loadbayes.models`, hands its likelihood pieces to a
sampler of :mod:`loadbayes.inference` and returns a :class:`~loadbayes.posterior.Posterior`.
Each takes ``sampler`` (a :class:`~loadbayes.core.settings.SamplerSettings`) and keyword
overrides of it (:mod:`loadbayes.fit.sampler`). ``track_zip`` follows the ZIP
coefficients sample by sample instead (online Bayes, :mod:`loadbayes.fit.track`).
"""

from loadbayes.fit.core import accumulate, fit_gram, prior_settings
from loadbayes.fit.exp import fit_exp
from loadbayes.fit.motor import fit_im, fit_im_file, im_priors
from loadbayes.fit.robust import fit_robust
from loadbayes.fit.steps import fit_steps
from loadbayes.fit.track import track_zip
from loadbayes.fit.zip import fit_zip, fit_zip_file, zip_priors

__all__ = [
    "accumulate",
    "fit_exp",
    "fit_gram",
    "fit_im",
    "fit_im_file",
    "fit_robust",
    "fit_steps",
    "fit_zip",
    "fit_zip_file",
    "im_priors",
    "prior_settings",
    "track_zip",
    "zip_priors",
]
