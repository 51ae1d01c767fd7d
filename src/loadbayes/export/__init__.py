"""Fitted load models out to simulators: pandapower, PSS/E, ANDES.

Each format is one module ``loadbayes.export.<fmt>`` exposing

- ``FORMAT``: its name;
- ``SUFFIXES``: the file suffixes it writes;
- ``write(values, out, *, model, header, options) -> list[Path]``: one parameter set
  (posterior mean, a quantile or one draw, named as in the composite naming contract)
  written at ``out``, with the posterior summary ``header`` as comments or a sidecar.

Modules are imported only when asked for (:func:`get`), so a missing optional simulator
package (ANDES) costs nothing to the others.
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["FORMATS", "MODELS", "check_model", "check_parameters", "get"]

#: Format name -> module path.
FORMATS = {
    "pandapower": "loadbayes.export.pandapower",
    "psse": "loadbayes.export.psse",
    "andes": "loadbayes.export.andes.writer",
}

#: Models the exports take (``slm``, ``cmld-lite``: models of parts, a ``composite`` fit
#: whose ``settings.model`` names them; :mod:`loadbayes.export.partsload`).
MODELS = ("zip", "exponential", "composite", "slm", "cmld-lite")


def get(fmt: str) -> ModuleType:
    """Import the writer of a format.

    Parameters
    ----------
    fmt : str
        ``"pandapower"``, ``"psse"`` or ``"andes"``.

    Returns
    -------
    module
        The module with ``FORMAT``, ``SUFFIXES`` and ``write``.

    Raises
    ------
    ValueError
        For an unknown format, or one whose module or simulator package is missing.
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r} (known: {', '.join(FORMATS)})")
    try:
        return importlib.import_module(FORMATS[fmt])
    except ModuleNotFoundError as exc:
        if exc.name == FORMATS[fmt]:
            raise ValueError(f"the {fmt} export is not part of this loadbayes build") from None
        raise ValueError(
            f"the {fmt} export needs {exc.name!r}, which is not installed "
            f"(pip install 'loadbayes[{'grid' if fmt == 'pandapower' else fmt}]')"
        ) from None


def check_model(model: str) -> None:
    """Refuse a model no export takes.

    Parameters
    ----------
    model : str
        The model name.

    Raises
    ------
    ValueError
        Unless ``model`` is one of :data:`MODELS`.
    """
    if model not in MODELS:
        raise ValueError(f"model {model!r} cannot be exported (exports take {', '.join(MODELS)})")


#: The parameters each model's export needs, and the ones that betray another model.
_NEEDS = {
    "zip": ("a1", "a2"),
    "exponential": ("np",),
    "composite": ("p0", "q0", "a1", "a2", "a4", "a5", "f_m", "rs", "xs", "xm", "rr", "xr",
                  "h_s", "t0"),
    "slm": ("p0", "q0", "v0", "a1", "a2", "f_s", "f_m", "rs", "x_open", "x_prime", "t_prime_s",
            "h_s", "t0", "x_fd", "r_fd", "cq2", "cq1", "cq0"),
    "cmld-lite": ("p0", "q0", "v0", "a1", "a2", "f_s", "f_m_a", "f_m_b", "f_d", "f_el",
                  "rs_a", "rs_b", "h_s_a", "h_s_b", "x_fd", "r_fd", "cq2", "cq1", "cq0"),
}  # fmt: skip
_BETRAY = {
    "zip": ("f_m", "rs", "t0", "np"),
    "exponential": ("a1", "f_m", "rs"),
    "composite": ("np",),
    "slm": ("f_m_a", "np"),
    "cmld-lite": ("f_m", "np"),
}


def check_parameters(model: str, names) -> str | None:
    """Why a parameter set cannot be ``model``'s, or None when it can.

    A file whose ``model`` was edited (a composite posterior relabelled ``zip``, whose
    ``a1 .. a3`` are then the shares of the static part only) or whose parameters were
    cut is refused before a writer turns it into wrong numbers.

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.
    names : iterable of str
        The parameters present.

    Returns
    -------
    str or None
        The reason, naming the parameters.
    """
    have = set(names)
    missing = [n for n in _NEEDS[model] if n not in have]
    if missing:
        return f"a {model} posterior needs parameters.{', parameters.'.join(missing)}: missing"
    foreign = [n for n in _BETRAY[model] if n in have]
    if foreign:
        return (
            f"'model' says {model} but the parameters include {', '.join(foreign)}, which "
            f"{model} has not: the file is from another fit (or was edited)"
        )
    return None
