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

from importlib import import_module
from typing import Any

# Each name's module, imported on first use (PEP 562): ``fit composite`` imports
# ``loadbayes.fit.composite`` through this package and needs none of them.
_WHERE = {
    "accumulate": "core",
    "fit_gram": "core",
    "prior_settings": "core",
    "fit_exp": "exp",
    "fit_im": "motor",
    "fit_im_file": "motor",
    "im_priors": "motor",
    "fit_robust": "robust",
    "fit_steps": "steps",
    "track_zip": "track",
    "fit_zip": "zip",
    "fit_zip_file": "zip",
    "zip_priors": "zip",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        value = getattr(import_module(f"loadbayes.fit.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'loadbayes.fit' has no attribute {name!r}")


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
