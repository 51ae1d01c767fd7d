"""The sampler settings of a fit: the defaults, and the one error for the old keywords.

Every ``fit_*`` function takes ``sampler: SamplerSettings | None`` (None: the fit's
defaults, :data:`MODEL_DEFAULTS` for most) and, for a table, ``spec: DataSpec | None``.
The loose keywords they took before (``draws=``, ``seed=``, ``v_col=`` ...) are refused
by :func:`~loadbayes.core.settings.new_spelling` in one line that gives the new spelling.
"""

from __future__ import annotations

from loadbayes.core.settings import SamplerSettings, new_spelling

__all__ = ["MODEL_DEFAULTS", "new_spelling"]

#: The sampler settings of a single fit when none are given: the paper's M and m.
MODEL_DEFAULTS = SamplerSettings(draws=40_000, burn=5_000)
