"""The data settings a fit records: its bases (:func:`bases`).

Where the data are and what their units are is a
:class:`~loadbayes.core.settings.DataSpec`, the ``spec`` of every fit of a table.
"""

from __future__ import annotations

__all__ = ["bases"]


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
