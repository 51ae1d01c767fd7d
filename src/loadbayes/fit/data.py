"""The data settings of a fit: a :class:`DataSpec` and the fit's own keywords over it.

Every file fit (``fit_zip``, ``fit_zip_file``, ``fit_exp``, ``fit_im_file``) takes
``spec: DataSpec | None`` beside its column, base, nominal-point and drop keywords;
:func:`data_of` turns them into the values it runs with, so a call without ``spec`` runs
exactly as before.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import fields
from typing import Any

from loadbayes.core.settings import DataSpec

__all__ = ["bases", "data_of"]

_FIELDS = frozenset(f.name for f in fields(DataSpec))


def _at_default(value: Any, default: Any) -> bool:
    if value is default:
        return True
    try:
        return bool(value == default)
    except (TypeError, ValueError):  # an array compared with a scalar
        return False


def data_of(spec: DataSpec | None, fit: Callable[..., Any], **given: Any) -> tuple[Any, ...]:
    """The values of ``given`` (the fit's data keywords) that ``fit`` runs with, in order.

    Without ``spec``: ``given`` unchanged. With it: each keyword that is a
    :class:`DataSpec` field takes the spec's value unless the call changed it from the
    fit's default (as :meth:`DataSpec.of`, keywords override the spec; a keyword left at
    its default keeps the spec's value). The spec's "estimate the nominal power"
    (``p0``/``q0`` None) is the fits' ``"auto"``. Keywords that are not fields
    (``with_q``, ``units`` ...) are returned as given.
    """
    if spec is None:
        return tuple(given.values())
    params = inspect.signature(fit).parameters
    out = []
    for name, value in given.items():
        if name in _FIELDS and _at_default(value, params[name].default):
            value = getattr(spec, name)
            if name in ("p0", "q0") and value is None:
                value = "auto"
        out.append(value)
    return tuple(out)


def bases(v_base: float | None, s_base: float | None, f_hz: float | None = None) -> dict:
    """The bases every fit's ``settings`` carries, so an export can write physical units.

    Parameters
    ----------
    v_base : float or None
        kV per p.u. of the voltage (None: the data were per unit).
    s_base : float or None
        MVA per p.u. of the powers (None: the data were per unit).
    f_hz : float or None
        Nominal frequency (None when the fit has no frequency in it).

    Returns
    -------
    dict
        ``{"v_base_kv", "s_base_mva", "f_hz"}``.
    """
    return {
        "v_base_kv": None if v_base is None else float(v_base),
        "s_base_mva": None if s_base is None else float(s_base),
        "f_hz": None if f_hz is None else float(f_hz),
    }
