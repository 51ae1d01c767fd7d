"""``loadbayes.fit_composite``: the composite fit with the options and checks of the CLI.

``loadbayes fit composite FILES ...`` and :func:`fit_composite` take the same options
(files or tables, column names, bases, ``f_hz``, ``torque``, ``steps``, the likelihood,
priors by name, the sampler's settings) and refuse the same mistakes with the same
one-line :class:`~loadbayes.io.errors.DataError` / :class:`~loadbayes.io.errors.OptionError`
before any work: the checks live here (:func:`check_torque`, :func:`check_noise`,
:func:`prior_with`) and the command calls them. Events already read
(:class:`~loadbayes.measurements.record.EventRecord`) go straight to
:func:`loadbayes.fit.composite.driver.fit_composite`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from loadbayes.fit.composite.driver import CompositeFit
from loadbayes.fit.composite.driver import fit_composite as _fit_events
from loadbayes.io.errors import DataError, OptionError
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import THETA_NAMES
from loadbayes.models.composite_prior import CompositePrior

__all__ = ["PRIOR_NAMES", "check_noise", "check_torque", "fit_composite", "prior_with", "read"]

#: ``--prior`` / ``priors=`` names -> the sampled log-parameter they set.
PRIOR_NAMES = {
    "rs": "log_rs",
    "x_prime": "log_x_prime",
    "dx": "log_dx",
    "t_prime_s": "log_t_prime",
    "h_s": "log_h",
    "t0": "log_t0",
}


def check_torque(torque: Any) -> tuple[float, float, float] | str:
    """``"estimate"`` or a finite ``(A, B, C)`` summing to 1; else :class:`OptionError`."""
    if isinstance(torque, str):
        if torque.strip().lower() == "estimate":
            return "estimate"
        raise OptionError(f"torque {torque!r}: expected (A, B, C) or 'estimate'")
    try:
        a, b, c = (float(x) for x in torque)
    except (TypeError, ValueError):
        raise OptionError(f"torque {torque!r}: expected (A, B, C) or 'estimate'") from None
    if not all(math.isfinite(x) for x in (a, b, c)) or abs(a + b + c - 1) > 1e-9:
        raise OptionError(f"torque {torque!r}: A + B + C must be 1")
    return a, b, c


def check_noise(likelihood: str, nu: float | str) -> float | str:
    """The likelihood and its ``nu`` as the CLI accepts them; else :class:`OptionError`."""
    if likelihood not in ("normal", "student-t"):
        raise OptionError(f"likelihood must be 'normal' or 'student-t', got {likelihood!r}")
    auto = isinstance(nu, str) and nu.strip().lower() == "auto"
    if likelihood != "student-t" and not auto:
        raise OptionError("nu needs likelihood 'student-t' (the --nu of --likelihood student-t)")
    if auto:
        return "auto"
    try:
        value = float(nu)
    except (TypeError, ValueError):
        raise OptionError(f"nu {nu!r}: a positive number or 'auto'") from None
    if not (value > 0 and math.isfinite(value)):
        raise OptionError(f"nu {nu!r}: a positive number or 'auto'")
    return value


def prior_with(
    events: Sequence[EventRecord], priors: Mapping[str, tuple[float, float]] | None
) -> CompositePrior:
    """The default prior of ``events`` with log-normal priors set by name.

    Parameters
    ----------
    events : sequence of EventRecord
        The events (the default prior reads their levels).
    priors : mapping of str to (float, float), optional
        ``{name: (median, sd_log)}`` for names in :data:`PRIOR_NAMES` (``--prior
        NAME=MEDIAN,SD_LOG``).

    Raises
    ------
    OptionError
        An unknown name, or a median or sd_log that is not positive and finite.
    """
    prior = CompositePrior.default(events)
    if not priors:
        return prior
    mean, sd = prior.theta_mean.copy(), prior.theta_sd.copy()
    for name, value in priors.items():
        if name not in PRIOR_NAMES:
            raise OptionError(f"prior {name!r}: NAME must be one of {', '.join(PRIOR_NAMES)}")
        try:
            med, s = (float(x) for x in value)
        except (TypeError, ValueError):
            raise OptionError(f"prior {name}={value!r}: expected (MEDIAN, SD_LOG)") from None
        if not (med > 0 and math.isfinite(med) and s > 0 and math.isfinite(s)):
            raise OptionError(f"prior {name}: MEDIAN and SD_LOG must be positive and finite")
        i = THETA_NAMES.index(PRIOR_NAMES[name])
        mean[i], sd[i] = math.log(med), s
    return CompositePrior(mean, sd, prior.beta_sd, prior.tau_shape, prior.tau_rate)


def read(
    data: Any,
    *,
    t_col: str = "t_s",
    v_col: str = "v",
    p_col: str = "p",
    q_col: str = "q",
    f_col: str | None = None,
    angle_col: str | None = None,
    event_col: str = "event",
    v_base: float | None = None,
    s_base: float | None = None,
    f_hz: float = 60.0,
) -> list[EventRecord]:
    """Events from files, tables or events (the readers and checks of the CLI).

    ``data`` is a file name, a DataFrame (or mapping of columns), an
    :class:`EventRecord`, or a list of any of them.
    """
    from loadbayes.measurements.events import events_from_arrays, read_events, refuse_repeats
    from loadbayes.measurements.frame import is_path, read_frame

    items = list(data) if isinstance(data, (list, tuple)) else [data]
    if not items:
        raise OptionError("no events to fit: give one or more files, tables or events")
    for base, name in ((v_base, "v_base"), (s_base, "s_base")):
        if base is not None and not (base > 0 and math.isfinite(base)):
            raise OptionError(f"{name} {base}: must be a positive number")
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
            optional = [names["f"], names["angle"], event_col]
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


def fit_composite(
    data: Any,
    *,
    t_col: str = "t_s",
    v_col: str = "v",
    p_col: str = "p",
    q_col: str = "q",
    f_col: str | None = None,
    angle_col: str | None = None,
    event_col: str = "event",
    v_base: float | None = None,
    s_base: float | None = None,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] | str = (1.0, 0.0, 0.0),
    likelihood: str = "normal",
    nu: float | str = "auto",
    priors: Mapping[str, tuple[float, float]] | None = None,
    prior: CompositePrior | None = None,
    settings: dict[str, Any] | None = None,
    **options: Any,
) -> CompositeFit:
    """Fit the composite load (ZIP + induction motor) to one or more events of one load.

    The Python face of ``loadbayes fit composite``: the same options, the same checks,
    the same one-line errors; every event is fitted jointly (one motor, each event its
    own operating point and mix).

    Parameters
    ----------
    data : str, path, DataFrame, mapping, EventRecord, or a list of them
        Files (CSV or Parquet) or tables with columns ``t_col, v_col, p_col, q_col``
        (optionally a frequency ``f_col`` in Hz or an angle ``angle_col`` in rad, and an
        ``event_col``: one event per distinct value), or events already read.
    t_col, v_col, p_col, q_col, f_col, angle_col, event_col : str
        Column names (``--t-col`` ...); ``f_col``/``angle_col`` default to ``f`` and
        ``angle_rad`` when present.
    v_base, s_base : float, optional
        Data V / v_base and P, Q / s_base are per unit (``--v-base``, ``--s-base``). Data
        in kV without ``v_base`` are refused (``accept_units=True`` fits them anyway).
    f_hz : float
        Nominal frequency, 10-1000 Hz.
    torque : (A, B, C) or "estimate"
        Load torque ``A w^2 + B w + C`` with ``A + B + C = 1``, or estimated.
    likelihood : {"normal", "student-t"}
        The noise of P and Q; ``nu`` (a number or "auto") only with "student-t".
    priors : mapping of str to (float, float), optional
        Log-normal priors ``{name: (median, sd_log)}`` of ``rs, x_prime, dx, t_prime_s,
        h_s, t0`` (``--prior NAME=MEDIAN,SD_LOG``), and normal priors ``{name: (mean,
        sd)}`` of ``a1..a6, f_m, p0, q0`` (``--prior NAME=MEAN,SD``).
    prior : CompositePrior, optional
        A whole prior instead (not with ``priors``).
    settings : dict, optional
        Extra provenance; the files read are recorded under ``files``.
    **options
        Passed to :func:`loadbayes.fit.composite.driver.fit_composite`: ``sampler``,
        ``draws``, ``burn``, ``chains``, ``thin``, ``seed``, ``steps``, ``accept_units``,
        ``progress``, ``workers``, ``shares`` ("free" or "bounded"), ``noise`` ("white"
        or "ar1"), ``window_s``, ``max_seconds``, ``until_converged`` ...

    Returns
    -------
    CompositeFit
        ``.posterior`` (the JSON contract, :meth:`~loadbayes.posterior.Posterior.to_json`),
        ``.baseline`` (the NLS estimate's Gaussian approximation), the problem, the start
        and the timings.

    Raises
    ------
    loadbayes.io.errors.DataError
        Data the CLI refuses (file, column and row named): a missing column, time going
        backwards, a gap, no voltage change, V not per unit ...
    loadbayes.io.errors.OptionError
        Options the CLI refuses: torque shares not summing to 1, ``nu`` without the
        Student-t likelihood, an unknown prior name, ``f_hz`` outside 10-1000 Hz, too few
        draws, a negative seed.

    Examples
    --------
    >>> import loadbayes
    >>> fit = loadbayes.fit_composite(["sag1.csv", "sag2.csv"], draws=4000, burn=1000,
    ...                               seed=1)  # doctest: +SKIP
    >>> fit.posterior.to_json("composite.json")  # doctest: +SKIP
    """
    from loadbayes.fit.composite.checks import check_run
    from loadbayes.io.errors import LoadbayesError

    torque_abc = check_torque(torque)
    nu_value = check_noise(likelihood, nu)
    if prior is not None and priors:
        raise OptionError("give either prior (a whole CompositePrior) or priors (by name)")
    if not (isinstance(f_hz, (int, float)) and 10 <= f_hz <= 1000):
        raise OptionError(f"f_hz {f_hz}: the nominal frequency must be 10-1000 Hz")
    sampler = options.get("sampler")
    run = {k: options[k] for k in ("draws", "burn", "thin", "seed") if k in options}
    if sampler is not None or run:
        from loadbayes.core.settings import SamplerSettings
        from loadbayes.fit.composite.driver import COMPOSITE_DEFAULTS

        try:
            s = SamplerSettings.of(sampler or COMPOSITE_DEFAULTS, **run)
        except ValueError as exc:
            if isinstance(exc, LoadbayesError):
                raise
            raise OptionError(str(exc)) from None
        check_run(f_hz=f_hz, draws=s.draws, burn=s.burn, thin=s.thin, seed=s.seed,
                  max_seconds=options.get("max_seconds", 1.0))  # fmt: skip
    items = list(data) if isinstance(data, (list, tuple)) else [data]
    files = [str(x) for x in items if isinstance(x, str) or hasattr(x, "__fspath__")]
    events = read(data, t_col=t_col, v_col=v_col, p_col=p_col, q_col=q_col, f_col=f_col,
                  angle_col=angle_col, event_col=event_col, v_base=v_base, s_base=s_base,
                  f_hz=f_hz)  # fmt: skip
    # Priors by name: the motor's (log-normal) set the prior; a1..a6, f_m, p0, q0 (normal)
    # are the coefficients' factors (driver's coefficient_prior).
    from loadbayes.models.composite_prior import COEFFICIENT_PRIOR_NAMES

    priors = dict(priors or {})
    coef = {n: priors.pop(n) for n in list(priors) if n in COEFFICIENT_PRIOR_NAMES}
    if coef:
        options["coefficient_prior"] = {**coef, **(options.get("coefficient_prior") or {})}
    if prior is None:
        from loadbayes.measurements.record import check_units

        # The units first: the default prior reads the events' levels.
        check_units(events, accept_units=bool(options.get("accept_units", False)),
                    columns={"v": v_col, "p": p_col, "q": q_col},
                    wording=options.get("wording", "python"))  # fmt: skip
        prior = prior_with(events, priors)
    extra = {**({"files": files} if files else {}), **(settings or {})}
    return _fit_events(events, prior=prior, f_hz=f_hz, torque=torque_abc, likelihood=likelihood,
                       nu=nu_value, settings=extra or None, **options)  # fmt: skip
