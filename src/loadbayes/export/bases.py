"""The bases of an export: the fit's own (``settings``), the command's overrides, or a default.

Every fit records ``v_base_kv``, ``s_base_mva`` (None when its data were per unit) and
``f_hz`` in its settings (:func:`loadbayes.fit.data.bases`); an export writes MW and kV
with them unless ``--s-base``/``--v-base`` say otherwise, and says which.
"""

from __future__ import annotations

__all__ = ["BASE_KEYS", "DEFAULT_BASES", "resolve_bases"]

#: The bases a fit records in its settings (``fit/data.py: bases``).
BASE_KEYS = ("v_base_kv", "s_base_mva", "f_hz")
#: What each writer assumes when neither the fit nor the command gives a base.
DEFAULT_BASES = {"pandapower": (1.0, 20.0), "psse": (100.0, 230.0), "andes": (100.0, 110.0)}


def resolve_bases(
    settings: dict, fmt: str, *, s_base: float | None, v_base: float | None
) -> tuple[float | None, float | None, list[str]]:
    """The MVA and kV bases an export uses, and what to tell the user about them.

    The fit's ``settings`` carry ``s_base_mva`` and ``v_base_kv`` (``s_base``/``v_base`` in
    results written before issue 23); the command's ``--s-base``/``--v-base`` override them,
    and the run says so. A per-unit fit with no bases gets the writer's default, said
    with the options that would give the study's units.

    Parameters
    ----------
    settings : dict
        The posterior's settings.
    fmt : str
        The export format (its defaults name the values used).
    s_base, v_base : float or None
        The command's ``--s-base`` and ``--v-base``.

    Returns
    -------
    s_base_mva, v_base_kv : float or None
        None leaves the writer's default.
    notes : list of str
        One line each: overrides, defaults used.
    """
    fit_s = settings.get("s_base_mva", settings.get("s_base"))
    fit_v = settings.get("v_base_kv", settings.get("v_base"))
    notes = []
    for name, unit, given, fitted in (("--s-base", "MVA", s_base, fit_s),
                                      ("--v-base", "kV", v_base, fit_v)):  # fmt: skip
        if given is not None and fitted is not None and float(given) != float(fitted):
            notes.append(
                f"{name} {given:g} {unit} overrides the fit's base of {float(fitted):g} {unit}"
            )
    s_used = s_base if s_base is not None else fit_s
    v_used = v_base if v_base is not None else fit_v
    missing = [n for n, v in (("--s-base MVA", s_used), ("--v-base kV", v_used)) if v is None]
    if missing:
        s_def, v_def = DEFAULT_BASES.get(fmt, (None, None))
        used = []
        if s_used is None and s_def is not None:
            used.append(f"{s_def:g} MVA per p.u.")
        if v_used is None and v_def is not None:
            used.append(f"a {v_def:g} kV bus")
        notes.append(
            "the fit was in per unit and records no "
            + " or ".join(
                ("power base", "voltage base")[k]
                for k, v in enumerate((s_used, v_used))
                if v is None
            )  # fmt: skip
            + f": the {fmt} export assumes {' and '.join(used)}; give "
            + " and ".join(missing)
            + " for the study's units"
        )
    return (None if s_used is None else float(s_used),
            None if v_used is None else float(v_used), notes)  # fmt: skip
