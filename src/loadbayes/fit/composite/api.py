"""``loadbayes.fit_composite``: read the events, then the one fit of a dynamic load model.

The Python face of ``loadbayes fit composite``. Reading is :func:`read` (files, tables
or events, with the CLI's checks and one-line :class:`~loadbayes.io.errors.DataError`);
the model (:class:`~loadbayes.models.zip_motor.CompositeModel`) checked its options when
it was built; :func:`fit_composite` reads and calls
:func:`loadbayes.fit.composite.driver.fit_composite`, which the command calls too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from loadbayes.core.settings import DataSpec, SamplerSettings, new_spelling
from loadbayes.fit.composite.driver import (
    DATA_KEYWORDS,
    MOVED,
    CompositeFit,
    SamplingProgress,
)
from loadbayes.fit.composite.driver import fit_composite as fit_events
from loadbayes.io.errors import DataError, OptionError
from loadbayes.measurements.events import events_from_arrays, read_events, refuse_repeats
from loadbayes.measurements.frame import is_path, read_frame
from loadbayes.measurements.record import (
    SEQUENCE_COLUMNS,
    EventRecord,
    check_units,
    sequence_phasors,
)
from loadbayes.models.base import DynamicLoadModel

__all__ = ["fit_composite", "read"]

#: The composite's columns when the spec leaves them unset.
_T_COL, _EVENT_COL = "t_s", "event"


@new_spelling(data=DATA_KEYWORDS)
def read(data: Any, spec: DataSpec | None = None, *, f_hz: float = 60.0):
    """Events from files, tables or events (the readers and checks of the CLI).

    ``data`` is a file name, a DataFrame (or mapping of columns), an
    :class:`EventRecord`, or a list of any of them; ``spec`` names the columns
    (``t_col`` default ``t_s``, ``event_col`` default ``event``; ``f_col``/``angle_col``
    default to ``f`` and ``angle_rad`` when present) and the bases (data / base = per
    unit). ``f_hz`` is the nominal frequency a frequency or angle column is read against.
    """
    spec = spec if spec is not None else DataSpec()
    t_col, event_col = spec.t_col or _T_COL, spec.event_col or _EVENT_COL
    v_col, p_col, q_col = spec.v_col, spec.p_col, spec.q_col or "q"
    f_col, angle_col, v_base, s_base = spec.f_col, spec.angle_col, spec.v_base, spec.s_base
    items = list(data) if isinstance(data, (list, tuple)) else [data]
    if not items:
        raise OptionError("no events to fit: give one or more files, tables or events")
    cols = {"t_col": t_col, "v_col": v_col, "p_col": p_col, "q_col": q_col, "f_col": f_col,
            "angle_col": angle_col, "event_col": event_col}  # fmt: skip
    out: list[EventRecord] = []
    for item in items:
        if isinstance(item, EventRecord):
            out.append(item)
        elif is_path(item):
            out += read_events([str(item)], v_base=v_base, s_base=s_base, f_hz=f_hz, **cols)
        else:
            names = {"t": t_col, "v": v_col, "p": p_col, "q": q_col, "f": f_col or "f",
                     "angle": angle_col or "angle_rad", "event": event_col}  # fmt: skip
            optional = [names["f"], names["angle"], event_col, *SEQUENCE_COLUMNS]
            ids = _text_ids(item, event_col)
            if ids is not None:  # event ids written as text ('sag A'): not numbers
                optional.remove(event_col)
            tab = read_frame(item, [t_col, v_col, p_col, q_col], optional=optional,
                             positive=[v_col])  # fmt: skip
            arrays = {k: tab.data[c] for k, c in names.items() if c in tab.data}
            if ids is not None:
                arrays["event"] = ids[np.asarray(tab.rows) - 1]
            for want, key in ((f_col, "f"), (angle_col, "angle")):
                if want and key not in arrays:
                    raise DataError("missing column", "data", want)
            if v_base is not None:
                arrays["v"] = arrays["v"] / v_base
            if s_base is not None:
                arrays["p"], arrays["q"] = arrays["p"] / s_base, arrays["q"] / s_base
            arrays |= sequence_phasors(tab.data, path="data", v_base=v_base, s_base=s_base)
            out += events_from_arrays(arrays, tab.rows, path="data", names=names, f_hz=f_hz)
    refuse_repeats(out, v_col)
    return out


def _text_ids(table: Any, column: str) -> np.ndarray | None:
    """A table's event ids as stripped text, when they are text; else None."""
    try:
        raw = np.asarray(table[column])
    except (KeyError, IndexError, TypeError, ValueError):
        return None
    if raw.dtype.kind not in "OUS" or raw.ndim != 1:
        return None
    return np.char.strip(raw.astype(str))


@new_spelling(data=DATA_KEYWORDS, more=MOVED)
def fit_composite(
    model: DynamicLoadModel,
    data: Any = None,
    *,
    sampler: SamplerSettings | None = None,
    progress: SamplingProgress | None = None,
    spec: DataSpec | None = None,
    provenance: Mapping[str, Any] | None = None,
) -> CompositeFit:
    """Fit a dynamic load model (``zip+motor``: ZIP + induction motor) to recorded events.

    The Python face of ``loadbayes fit composite``: the same checks, the same one-line
    errors; every event is fitted jointly (one motor, each event its own operating point
    and mix).

    Parameters
    ----------
    model : DynamicLoadModel
        The model (``models/dynamic.py``); for ``zip+motor`` a
        :class:`~loadbayes.models.zip_motor.CompositeModel` and its options (torque law,
        steps, shares, noise, likelihood, phasor window, frequency, priors by name),
        checked when it is built:
        ``CompositeModel(torque="estimate", priors={"h_s": (0.7, 0.3)})``.
    data : str, path, DataFrame, mapping, EventRecord, or a list of them
        Files (CSV or Parquet) or tables with columns ``t_s, v, p, q`` (optionally a
        frequency ``f`` in Hz or an angle ``angle_rad`` in rad, and an ``event`` column:
        one event per distinct value), or events already read.
    sampler : SamplerSettings, optional
        Default :data:`~loadbayes.fit.composite.driver.COMPOSITE_DEFAULTS` (a model of
        parts: ``driver.parts_defaults``; run on until converged); settings given run exactly
        their draws unless ``until_converged``.
    progress : SamplingProgress, optional
        Told the cost before sampling and the iterations as they are done.
    spec : DataSpec, optional
        The columns and bases of the data (``DataSpec(t_col="time", v_col="V_kV",
        v_base=11, s_base=5)``), and ``accept_units`` (fit data that do not look per unit,
        with a warning).
    provenance : mapping, optional
        Extra settings recorded in the result; the files read are recorded under
        ``files``.

    Returns
    -------
    CompositeFit
        ``.posterior`` (the JSON contract, :meth:`~loadbayes.posterior.Posterior.to_json`),
        ``.baseline`` (the NLS estimate's Gaussian approximation), the problem, the start
        and the timings.

    Raises
    ------
    TypeError
        A keyword of the old signature (``draws=``, ``torque=``, ``v_col=`` ...), with
        its new place.
    loadbayes.io.errors.DataError
        Data the CLI refuses (file, column and row named): a missing column, time going
        backwards, a gap, no voltage change, V not per unit ...
    loadbayes.io.errors.OptionError
        Too few draws, a negative seed.

    Examples
    --------
    >>> import loadbayes
    >>> from loadbayes import CompositeModel, SamplerSettings
    >>> fit = loadbayes.fit_composite(CompositeModel(), ["sag1.csv", "sag2.csv"],
    ...     sampler=SamplerSettings(draws=4000, burn=1000, seed=1))  # doctest: +SKIP
    >>> fit.posterior.to_json("composite.json")  # doctest: +SKIP
    """
    from loadbayes.fit.composite.checks import check_run

    if not isinstance(model, DynamicLoadModel):
        raise TypeError(
            "fit_composite: the first argument is the model (loadbayes.CompositeModel, or "
            f"another of models/dynamic.py), got {type(model).__name__}: "
            "fit_composite(CompositeModel(...), data, sampler=...)"
        )
    if data is None:
        raise TypeError("fit_composite: no data: fit_composite(model, data, sampler=...)")
    if sampler is not None:
        f_hz = getattr(model, "f_hz", 60.0)
        check_run(f_hz=f_hz, draws=sampler.draws, burn=sampler.burn, thin=sampler.thin,
                  seed=sampler.seed)  # fmt: skip
    spec = spec if spec is not None else DataSpec()
    items = list(data) if isinstance(data, (list, tuple)) else [data]
    files = [str(x) for x in items if isinstance(x, str) or hasattr(x, "__fspath__")]
    _check_index_frequency(model, files)
    events = read(data, spec, f_hz=getattr(model, "f_hz", 60.0))
    columns = {"v": spec.v_col, "p": spec.p_col, "q": spec.q_col or "q"}
    # The units first, named by the data's own columns; then the warnings the fit keeps.
    check_units(events, accept_units=spec.accept_units, columns=columns, wording="python")
    warnings = check_units(events, accept_units=spec.accept_units, wording="python")
    extra = {**({"files": files} if files else {}), **(provenance or {})}
    return fit_events(model, events, sampler=sampler, progress=progress,
                      data_warnings=warnings, provenance=extra or None)  # fmt: skip


def _check_index_frequency(model: DynamicLoadModel, files: list[str]) -> None:
    """Refuse a model whose frequency is not the one the events' index records.

    Events cut by ``loadbayes events`` carry the record's nominal frequency in
    ``events.csv``; the CLI takes it when ``--f-hz`` is not given. A model is not changed
    behind the caller's back: the one that disagrees (60 Hz, the default, for a 50 Hz
    record) is refused with the model to build.
    """
    from loadbayes.io.errors import OptionError
    from loadbayes.measurements.events import index_f_hz

    f_model = getattr(model, "f_hz", None)
    found = index_f_hz(files) if files and f_model is not None else None
    if found is not None and found[0] != f_model:
        name = type(model).__name__
        raise OptionError(
            f"{found[1]} says the record's nominal frequency is {found[0]:g} Hz, but the "
            f"model's f_hz is {f_model:g}: build {name}(f_hz={found[0]:g}, ...)"
        )
