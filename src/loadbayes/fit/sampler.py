"""The sampler settings of a fit: the defaults, and the one error for the old keywords.

Every ``fit_*`` function takes ``sampler: SamplerSettings | None`` (None: the fit's
defaults, :data:`MODEL_DEFAULTS` for most) and, for a table, ``spec: DataSpec | None``.
The loose keywords they took before (``draws=``, ``seed=``, ``v_col=`` ...) are refused
by :func:`new_spelling` in one line that gives the new spelling.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterable
from dataclasses import fields
from typing import Any, TypeVar

from loadbayes.core.settings import DataSpec, SamplerSettings

__all__ = ["DATA_KEYWORDS", "MODEL_DEFAULTS", "new_spelling"]

#: The sampler settings of a single fit when none are given: the paper's M and m.
MODEL_DEFAULTS = SamplerSettings(draws=40_000, burn=5_000)

#: The keywords that became ``SamplerSettings`` fields (every fit refuses them loose).
SAMPLER_KEYWORDS = tuple(f.name for f in fields(SamplerSettings))
#: The keywords that became ``DataSpec`` fields (a table's fit refuses them loose).
DATA_KEYWORDS = tuple(f.name for f in fields(DataSpec))

F = TypeVar("F", bound=Callable[..., Any])


def _value(name: str, value: Any) -> str:
    if name in ("p0", "q0") and value == "auto":
        value = None  # DataSpec's "estimate it"
    text = repr(value)
    return text if len(text) <= 40 and "\n" not in text else "..."


def new_spelling(data: Iterable[str] = ()) -> Callable[[F], F]:
    """Refuse the sampler keywords (and the ``data`` keywords) a fit no longer takes.

    ``fit_zip(x, draws=4000, v_col="V")`` raises, in one line::

        TypeError: fit_zip: draws= is now sampler=SamplerSettings(draws=4000);
        v_col= is now spec=DataSpec(v_col='V')

    A keyword the function still has (``fit_steps``'s ``v0``) passes through.
    """
    moved = {k: ("sampler", "SamplerSettings") for k in SAMPLER_KEYWORDS}
    moved.update({k: ("spec", "DataSpec") for k in data})

    def deco(func: F) -> F:
        own = set(inspect.signature(func).parameters)
        refused = {k: v for k, v in moved.items() if k not in own}

        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            old = [k for k in kwargs if k in refused]
            if old:
                parts = []
                for keyword, cls in (("sampler", "SamplerSettings"), ("spec", "DataSpec")):
                    names = [k for k in old if refused[k][0] == keyword]
                    if names:
                        given = ", ".join(f"{k}={_value(k, kwargs[k])}" for k in names)
                        verb = "is" if len(names) == 1 else "are"
                        parts.append(
                            f"{', '.join(k + '=' for k in names)} {verb} now "
                            f"{keyword}={cls}({given})"
                        )
                raise TypeError(f"{func.__name__}: {'; '.join(parts)}")
            return func(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return deco


# The keyword overrides of the fits not yet moved to settings objects (removed with them).
from collections.abc import Mapping  # noqa: E402

from loadbayes.io.errors import OptionError  # noqa: E402


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
