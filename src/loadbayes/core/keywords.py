"""Keywords an entry no longer takes, refused in one line that names their new place.

The fits take settings objects (a model, :class:`~loadbayes.core.settings.SamplerSettings`,
:class:`~loadbayes.core.settings.DataSpec`) in place of loose keywords; a call written
for the old signature gets a ``TypeError`` that says where each keyword went, not
Python's bare "unexpected keyword argument".
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["moved_keywords"]


def moved_keywords(entry: str, given: Mapping[str, Any], moved: Mapping[str, str]) -> str:
    """The one-line message for keywords ``given`` that ``entry`` no longer takes.

    Parameters
    ----------
    entry : str
        The function's name as the user calls it.
    given : mapping
        The unexpected keywords and their values.
    moved : mapping of str to str
        Old keyword -> its new spelling, with ``{value}`` where the value goes
        (``"draws": "sampler=SamplerSettings(draws={value})"``).

    Examples
    --------
    >>> moved_keywords("fit_x", {"draws": 400}, {"draws": "sampler=SamplerSettings(draws={value})"})
    'fit_x: draws=400 is now sampler=SamplerSettings(draws=400)'
    """
    parts = []
    for name, value in given.items():
        if name in moved:
            parts.append(f"{name}={value!r} is now {moved[name].format(value=repr(value))}")
        else:
            parts.append(f"unexpected keyword {name}=")
    return f"{entry}: " + "; ".join(parts)
