"""The sampler settings of a fit: the defaults, keyword overrides, the one-line checks.

Every ``fit_*`` function takes ``sampler: SamplerSettings | None`` and keyword overrides
(``draws=..., seed=...``); :func:`sampler_of` turns them into the settings it runs with.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from loadbayes.core.settings import SamplerSettings
from loadbayes.io.errors import OptionError

__all__ = ["MODEL_DEFAULTS", "check_sampler", "sampler_kwargs", "sampler_of"]

#: The sampler settings of a single fit when none are given: the paper's M and m.
MODEL_DEFAULTS = SamplerSettings(draws=40_000, burn=5_000)


def sampler_of(
    sampler: SamplerSettings | None,
    overrides: Mapping[str, Any],
    *,
    check: bool = False,
) -> SamplerSettings:
    """The settings a fit runs with: ``sampler`` (or :data:`MODEL_DEFAULTS`) and keywords.

    ``overrides`` are the fit's keyword arguments (``draws=..., seed=...``), resolved by
    :meth:`SamplerSettings.of`; an explicit ``seed=None`` (fresh entropy) is kept. With
    ``check``, the iteration counts are refused first by
    :func:`check_sampler` (its one-line ``OptionError``).
    """
    base = sampler if sampler is not None else MODEL_DEFAULTS
    if check:
        counts = {
            k: overrides[k] if overrides.get(k) is not None else getattr(base, k)
            for k in ("draws", "burn", "chains", "thin")
        }
        check_sampler(**counts)
    out = SamplerSettings.of(base, **overrides)
    if "seed" in overrides and overrides["seed"] is None:
        out = out.with_(seed=None)
    return out


def check_sampler(*, draws: int, burn: int, chains: int, thin: int) -> None:
    """The CLI's checks of the sampler settings, as ``OptionError`` in one line."""
    for name, value, low in (("draws", draws, 1), ("chains", chains, 1), ("thin", thin, 1),
                             ("burn", burn, 0)):  # fmt: skip
        if int(value) != value or value < low:
            raise OptionError(f"{name} must be an integer >= {low}, got {value!r}")
    if burn >= draws:
        raise OptionError(f"burn ({burn}) must be smaller than draws ({draws})")


def sampler_kwargs(sampler: SamplerSettings) -> dict[str, Any]:
    """``chains, draws, burn, thin, init, seed`` of ``sampler`` as the samplers' keywords."""
    return {
        "chains": sampler.chains,
        "draws": sampler.draws,
        "burn": sampler.burn,
        "thin": sampler.thin,
        "init": sampler.init,
        "seed": sampler.seed,
    }
