"""The registry of dynamic load models: a name (``--model``) -> the model's class.

A dynamic model is one module in ``models/`` against
:class:`~loadbayes.models.base.DynamicLoadModel` plus its line here;
:func:`loadbayes.fit.composite.fit_composite` fits any of them.
"""

from __future__ import annotations

from typing import Any

from loadbayes.io.errors import OptionError
from loadbayes.models.cmld_lite import CmldLite
from loadbayes.models.slm import SynthesisLoad
from loadbayes.models.zip_motor import CompositeModel

__all__ = ["DYNAMIC_MODELS", "dynamic_model"]

#: Every dynamic model by its name: a new model is its module and one line here.
DYNAMIC_MODELS: dict[str, type] = {
    CompositeModel.name: CompositeModel,
    SynthesisLoad.name: SynthesisLoad,
    CmldLite.name: CmldLite,
}


def dynamic_model(name: str, **options: Any) -> Any:
    """The model called ``name``, built (and checked) with ``options``."""
    try:
        cls = DYNAMIC_MODELS[name]
    except KeyError:
        raise OptionError(f"model {name!r}: one of {', '.join(DYNAMIC_MODELS)}") from None
    return cls(**options)
