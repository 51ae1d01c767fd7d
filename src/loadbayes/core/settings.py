"""The settings a fit is run with, declared and checked once.

:class:`SamplerSettings` holds how the chains run (iterations, burn-in, chains, thinning,
seed, threads, start, interval mass) and :class:`DataSpec` where the data are and what
their units are (columns, bases, nominal point, what to do with bad rows). Each is
validated when it is built, so a sampler or a fit that takes one needs no check of its
own; the CLI's option decorators (``commands/options.py``) build them from the options,
the Python API from keywords.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, fields, replace
from typing import Any, Literal, TypeVar

import numpy as np

__all__ = ["DataSpec", "SamplerSettings", "check_iterations", "new_spelling"]


def check_iterations(draws: int, burn: int, thin: int = 1, chains: int = 1) -> None:
    """Refuse iteration counts no sampler can run: the one copy of the rule.

    Raises
    ------
    ValueError
        Unless ``chains, draws, thin >= 1`` and ``0 <= burn < draws``.
    """
    if chains < 1 or draws < 1 or thin < 1 or burn < 0:
        raise ValueError("chains, draws and thin must be >= 1 and burn >= 0")
    if burn >= draws:
        raise ValueError(f"burn-in ({burn}) must be smaller than the draws ({draws})")


@dataclass(frozen=True)
class SamplerSettings:
    """How the chains run.

    Parameters
    ----------
    draws : int
        Iterations per chain, burn-in included (the paper's M).
    burn : int
        Leading iterations discarded (the paper's m); ``0 <= burn < draws``.
    chains : int
        Independent chains (R-hat needs two or more).
    thin : int
        Keep every ``thin``-th iteration after the burn-in.
    seed : int, SeedSequence, Generator or None
        Root of the per-chain generators (:func:`loadbayes.core.parallel.chain_generators`).
    threads : int or None
        Threads for the chains; ``None``: ``LOADBAYES_NUM_THREADS`` or the CPUs available.
    init : {"prior", "dispersed"}
        Start from a prior draw, or scattered around the least-squares fit.
    hdi_prob : float
        Mass of the reported intervals.
    until_converged : bool or None
        After ``draws`` iterations, run on until converged (a fit that can: the
        composite); None: that fit's default.
    max_seconds : float or None
        Time budget of a run until converged (s); None: the fit's default.
    move : str or None
        The Metropolis move of a Metropolis-within-Gibbs fit, by name; None: its default.
    """

    draws: int = 2_500
    burn: int = 500
    chains: int = 4
    thin: int = 1
    seed: Any = 0
    threads: int | None = None
    init: Literal["prior", "dispersed"] = "prior"
    hdi_prob: float = 0.95
    until_converged: bool | None = None
    max_seconds: float | None = None
    move: str | None = None

    def __post_init__(self) -> None:
        check_iterations(self.draws, self.burn, self.thin, self.chains)
        m = self.max_seconds
        if m is not None and not (isinstance(m, (int, float)) and 0 < m < 1e9):
            raise ValueError(
                f"max_seconds {m}: the time budget must be a positive number of seconds"
            )
        if self.threads is not None and self.threads < 1:
            raise ValueError(f"threads must be >= 1, got {self.threads}")
        if self.init not in ("prior", "dispersed"):
            raise ValueError(f"init must be 'prior' or 'dispersed', got {self.init!r}")
        if not 0.0 < self.hdi_prob < 1.0:
            raise ValueError(f"hdi_prob must be in (0, 1), got {self.hdi_prob}")

    @property
    def kept(self) -> int:
        """Draws kept per chain: ``len(range(burn, draws, thin))``."""
        return len(range(self.burn, self.draws, self.thin))

    def generators(self) -> list[np.random.Generator]:
        """One independent generator per chain, spawned from :attr:`seed`."""
        from loadbayes.core.parallel import chain_generators

        return chain_generators(self.seed, self.chains)

    def with_(self, **changes: Any) -> SamplerSettings:
        """A copy with some settings changed (and checked again)."""
        return replace(self, **changes)

    @classmethod
    def of(cls, settings: SamplerSettings | None = None, /, **changes: Any) -> SamplerSettings:
        """``settings`` (or the defaults) with the keyword ``changes`` that are not None."""
        base = settings if settings is not None else cls()
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise TypeError(f"unknown sampler setting(s): {', '.join(unknown)}")
        return replace(base, **{k: v for k, v in changes.items() if v is not None})


@dataclass(frozen=True)
class DataSpec:
    """Where the data are and what their units are.

    Parameters
    ----------
    v_col, p_col : str
        Voltage-magnitude and active-power columns.
    q_col : str or None
        Reactive-power column; ``None`` for P only.
    f_col, t_col : str or None
        Frequency (Hz) and time columns, when used.
    angle_col, event_col : str or None
        Voltage-angle (rad) and event-id columns, when used (the composite's events).
    v_base, s_base : float or None
        Bases: data / base = per unit (positive); ``None`` when the data are per unit
        already.
    v0 : float
        Nominal voltage, per unit (positive).
    p0, q0 : float or None
        Nominal powers, per unit, finite and non-zero (a capacitive load has ``q0 < 0``;
        a negative ``p0`` is left to the fit's unit check, which explains it better);
        ``None``: estimated from the data.
    drop_invalid : bool
        Skip rows with missing or non-physical values instead of stopping at the first.
    accept_units : bool
        Fit data that do not look per unit (warn instead of refusing).
    """

    v_col: str = "v"
    p_col: str = "p"
    q_col: str | None = "q"
    f_col: str | None = None
    t_col: str | None = None
    angle_col: str | None = None
    event_col: str | None = None
    v_base: float | None = None
    s_base: float | None = None
    v0: float = 1.0
    p0: float | None = None
    q0: float | None = None
    drop_invalid: bool = False
    accept_units: bool = False

    def __post_init__(self) -> None:
        if self.q_col is not None and self.q_col.strip().lower() == "none":
            object.__setattr__(self, "q_col", None)
        for name in ("v_base", "s_base", "v0"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        for name in ("p0", "q0"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value != 0):
                raise ValueError(f"{name} must be a finite non-zero number or None, got {value}")
        cols = [self.v_col, self.p_col, self.q_col, self.f_col, self.t_col, self.angle_col]
        cols = [c for c in cols if c]
        dup = sorted({c for c in cols if cols.count(c) > 1})
        if dup:
            raise ValueError(f"column {dup[0]!r} is given for two quantities")

    @property
    def with_q(self) -> bool:
        """Whether a reactive-power column is read."""
        return self.q_col is not None

    def with_(self, **changes: Any) -> DataSpec:
        """A copy with some fields changed (and checked again)."""
        return replace(self, **changes)

    @classmethod
    def of(cls, spec: DataSpec | None = None, /, **changes: Any) -> DataSpec:
        """``spec`` (or the defaults) with the keyword ``changes`` that are not None.

        As :meth:`SamplerSettings.of`: None means "not given", so a field can be set to
        None (``q_col=None``, no base) only with :meth:`with_`.
        """
        base = spec if spec is not None else cls()
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise TypeError(f"unknown data setting(s): {', '.join(unknown)}")
        return replace(base, **{k: v for k, v in changes.items() if v is not None})


#: The keywords that became ``SamplerSettings`` fields (every fit refuses them loose).
SAMPLER_KEYWORDS = tuple(f.name for f in fields(SamplerSettings))

F = TypeVar("F", bound=Callable[..., Any])


def _value(name: str, value: Any) -> str:
    if name in ("p0", "q0") and value == "auto":
        value = None  # DataSpec's "estimate it"
    text = repr(value)
    return text if len(text) <= 40 and "\n" not in text else "..."


def new_spelling(
    data: Iterable[str] = (),
    *,
    sampler: str = "sampler",
    more: Mapping[str, str] | None = None,
) -> Callable[[F], F]:
    """Refuse the sampler keywords (and the ``data`` keywords) a function no longer takes.

    The one copy of the rule "settings objects, not loose keywords": ``sampler`` names
    the function's :class:`SamplerSettings` parameter (the samplers in
    :mod:`loadbayes.inference` call it ``settings``), ``data`` the :class:`DataSpec`
    fields it took loose (``spec``), ``more`` any other keyword's new spelling as a
    template with ``{value}`` (``{"torque": "model=CompositeModel(torque={value})"}``).

    ``fit_zip(x, draws=4000, v_col="V")`` raises, in one line::

        TypeError: fit_zip: draws= is now sampler=SamplerSettings(draws=4000);
        v_col= is now spec=DataSpec(v_col='V')

    A keyword the function still has (``fit_steps``'s ``v0``) passes through.
    """
    moved = {k: (sampler, "SamplerSettings") for k in SAMPLER_KEYWORDS}
    moved.update({k: ("spec", "DataSpec") for k in data})
    more = dict(more or {})

    def deco(func: F) -> F:
        own = set(inspect.signature(func).parameters)
        refused = {k: v for k, v in moved.items() if k not in own and k not in more}
        other = {k: v for k, v in more.items() if k not in own}

        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            old = [k for k in kwargs if k in refused]
            odd = [k for k in kwargs if k in other]
            if old or odd:
                parts = []
                for keyword, cls in ((sampler, "SamplerSettings"), ("spec", "DataSpec")):
                    names = [k for k in old if refused[k][0] == keyword]
                    if names:
                        given = ", ".join(f"{k}={_value(k, kwargs[k])}" for k in names)
                        verb = "is" if len(names) == 1 else "are"
                        parts.append(
                            f"{', '.join(k + '=' for k in names)} {verb} now "
                            f"{keyword}={cls}({given})"
                        )
                parts += [f"{k}= is now {other[k].format(value=_value(k, kwargs[k]))}" for k in odd]
                raise TypeError(f"{func.__name__}: {'; '.join(parts)}")
            return func(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return deco
