"""loadbayes: Bayesian identification of power-system load models.

The public API is imported lazily so that ``import loadbayes`` (and the CLI's ``--help``)
stays fast; numba, ArviZ and pandapower load only when a fit or a case needs them.
"""

from __future__ import annotations

import importlib
from typing import Any

from loadbayes._numba_cache import purge_stale
from loadbayes._version import __version__

# Before any compiled module loads: numba's cache does not see a callee's file change.
purge_stale()

__all__ = [
    "__version__",
    "BlockPrior",
    "CompositeModel",
    "DataSpec",
    "Posterior",
    "SamplerSettings",
    "ZIPModel",
    "cvr",
    "cvr_fleet",
    "fit_composite",
    "fit_exp",
    "fit_im",
    "fit_im_file",
    "fit_robust",
    "fit_steps",
    "fit_zip",
    "fit_drift_fleet",
    "fit_zip_drift",
    "fit_zip_file",
    "predict",
    "track_zip",
    "zip_priors",
]

_LAZY = {
    "BlockPrior": "loadbayes.core.priors",
    "CompositeModel": "loadbayes.models.zip_motor",
    "DataSpec": "loadbayes.core.settings",
    "Posterior": "loadbayes.posterior",
    "SamplerSettings": "loadbayes.core.settings",
    "ZIPModel": "loadbayes.models.zip",
    "cvr": "loadbayes.fit.cvr",
    "cvr_fleet": "loadbayes.fleet.cvr",
    "fit_drift_fleet": "loadbayes.fleet.drift",
    "fit_composite": "loadbayes.fit.composite",
    "fit_exp": "loadbayes.fit",
    "fit_im": "loadbayes.fit",
    "fit_im_file": "loadbayes.fit",
    "fit_robust": "loadbayes.fit",
    "fit_steps": "loadbayes.fit",
    "fit_zip": "loadbayes.fit",
    "fit_zip_drift": "loadbayes.fit.drift",
    "predict": "loadbayes.fit.composite.predict",
    "track_zip": "loadbayes.fit",
    "fit_zip_file": "loadbayes.fit",
    "zip_priors": "loadbayes.fit",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'loadbayes' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
