"""Do the data look like per unit? The check every reader of V, P, Q runs before a fit.

A load model is fitted in per unit of its nominal point: ``x = V / V0`` near 1, and
``P / P0`` (``Q / Q0``) near 1 at ``V = V0`` when the nominal power is given. Data in kV,
MW or kvar without the matching base give a fit that runs, converges and means nothing
(the ZIP constraint ``a1 + a2 + a3 = 1`` then holds far from every sample). These
functions look at the arrays, say what they saw, and name the option that fixes it.

They take plain arrays and return a list of
:class:`~loadbayes.measurements.wording.UnitProblem` (empty when the data look right), so
a fleet (per bus) or a recording reader calls them the same way as ``fit zip``;
:func:`loadbayes.measurements.wording.refuse` turns the problems into one
:class:`DataError`, and the fixes are worded for the caller there.

One idea needs these 454 lines: whether V, P, Q are per unit of the nominal point, checked
alike from the rows (:func:`check_power_units`, with the motor's and the frequency's
checks) and from a fleet bus's Gram matrix (:func:`check_gram_units`), with the warnings
for a given P0 or Q0 that the data place off the power at V0.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from loadbayes.io.errors import DataError
from loadbayes.measurements.wording import UnitProblem, Wording, option, suggest_v_base

__all__ = [
    "check_frequency",
    "check_gram_units",
    "nominal_level_warnings",
    "nominal_level_warnings_gram",
    "check_motor_units",
    "check_power_units",
    "level_at_nominal",
    "require_power",
]

#: ``median(V / V0)`` outside this range is not per unit of V0.
V_RANGE = (0.7, 1.3)
#: ``P / P0`` at ``V = V0`` (from the data) outside this range: P0 is not the power at V0.
NOMINAL_RANGE = (1 / 1.5, 1.5)
#: With ``auto`` nominal power, powers above this are not per unit of any sensible base
#: (and the weak prior of P0, sd 1e4, would no longer be weak).
AUTO_MAX = 1e3


def _zip_design(x: np.ndarray) -> np.ndarray:
    """Columns ``1, x^2 - 1, x - 1``: the ZIP model's own form, its intercept the level at V0."""
    dx = x - 1.0
    return np.column_stack([np.ones_like(x), dx * (x + 1.0), dx])


def level_at_nominal(x: np.ndarray, y: np.ndarray) -> float:
    """``y`` at ``x = 1`` by least squares on (1, x^2 - 1, x - 1): the ZIP model's own form.

    Parameters
    ----------
    x : ndarray
        Voltage in per unit of V0.
    y : ndarray
        Power (any units).

    Returns
    -------
    float
        The fitted power at ``V = V0`` (the median of ``y`` when V has no spread).
    """
    with np.errstate(all="ignore"):
        a = _zip_design(x)
    with np.errstate(all="ignore"):  # an absurd value is refused elsewhere by name
        if not np.isfinite(a).all() or np.ptp(x) < 1e-9:
            return float(np.median(y))  # no usable spread: the level at the V there is
        coef, *_ = np.linalg.lstsq(a, y, rcond=1e-10)
    return float(coef[0])


def check_power_units(
    v: np.ndarray,
    p: np.ndarray | None = None,
    q: np.ndarray | None = None,
    *,
    v0: float = 1.0,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    v_base: float | None = None,
    s_base: float | None = None,
    wording: Wording = "cli",
) -> list[UnitProblem]:
    """Problems with the units of V, P, Q as a ZIP or exponential model sees them.

    Parameters
    ----------
    v, p, q : ndarray
        Voltage and powers after the bases (``V / v_base``, ``P / s_base``); ``p`` or
        ``q`` may be None.
    v0, p0, q0 : float or "auto"
        The nominal point the model uses, in the same units.
    v_base, s_base : float, optional
        The bases already applied (to suggest a better one in the data's own units).
    wording : {"cli", "python"}
        Name the fixes as the command line's options (``--v-base 13.8``) or as Python's
        keywords (``v_base=13.8``): each user reads the names they type.

    Returns
    -------
    list of UnitProblem
        Empty when the data look like per unit of the nominal point.

    Notes
    -----
    Three checks, each a factor of about 1.5 wide so that a genuine sag record or a
    load off its rating passes: the median of ``V / V0`` lies in ``[0.7, 1.3]``; with a
    given P0, the power at ``V = V0`` (the intercept of the model's own least-squares
    form ``y = c + d1 (x^2 - 1) + d2 (x - 1)``) is within ``[1/1.5, 1.5]`` of P0; with
    ``auto``, ``|P|`` has a median below 1e3 (beyond, the data are in W or kW).
    """
    v = np.asarray(v, dtype=float)
    ok = np.isfinite(v)
    out: list[UnitProblem] = []
    if not ok.any():
        return out
    x = v[ok] / v0
    med = float(np.median(x))

    def opt(name: str, value: object = None) -> str:
        return option(name, value, wording=wording)

    if not V_RANGE[0] <= med <= V_RANGE[1]:
        raw = med * v0 * (v_base or 1.0)
        given = f" with {opt('v-base', f'{v_base:g}')}" if v_base else ""
        v0_txt = f" and {opt('v0', f'{v0:g}')}" if v0 != 1.0 else ""
        out.append(
            UnitProblem(
                "v",
                f"V / V0 has median {med:.4g}{given}{v0_txt}, not about 1: the voltage is "
                "not per unit",
                f"give the system's nominal voltage in the data's units with "
                f"{opt('v-base').removesuffix('=...')} (V's median is {raw:.4g}: "
                f"{suggest_v_base(raw, wording)} if that is near nominal)",
                wording,
            )
        )
        return out  # the power checks need a per-unit x
    for ch, y, nom in (("p", p, p0), ("q", q, q0)):
        if y is None:
            continue
        y = np.asarray(y, dtype=float)[ok]
        fin = np.isfinite(y)
        if fin.sum() < 3:
            continue
        if nom == "auto":
            big = float(np.median(np.abs(y[fin])))
            if big > AUTO_MAX:
                out.append(
                    UnitProblem(
                        ch,
                        f"{ch.upper()} has median magnitude {big:.4g}: not per unit of any "
                        "sensible power base",
                        f"give the power base in the data's units with "
                        f"{opt('s-base').removesuffix('=...')} (e.g. "
                        f"{opt('s-base', f'{10 ** np.floor(np.log10(big)):g}')})",
                        wording,
                    )
                )
            continue
        level = level_at_nominal(x[fin], y[fin] / float(nom))
        if not NOMINAL_RANGE[0] <= level <= NOMINAL_RANGE[1]:
            raw = level * float(nom) * (s_base or 1.0)
            out.append(
                UnitProblem(
                    ch,
                    f"{ch.upper()} / {ch.upper()}0 is about {level:.4g} at V = V0 (from the "
                    f"data), not 1: {opt(f'{ch}0', f'{nom:g}')} is not the load's "
                    f"{ch.upper()} at V0 (the data say about {raw:.4g} in their own units)",
                    f"let loadbayes estimate it with {opt(f'{ch}0', 'auto')}, or give the "
                    f"right {opt(f'{ch}0').removesuffix('=...')} (with "
                    f"{opt('s-base').removesuffix('=...')} for data in MW, kW or kvar)",
                    wording,
                )
            )
    return out


#: A given P0 (Q0) that the data put more than this far from the power at V0, and by
#: more than LEVEL_SDS standard errors, is said in a warning: inside NOMINAL_RANGE the
#: fit runs, but with a3 = 1 - a1 - a2 the model holds P(V0) = P0 and the shares take up
#: the difference (the red-team's bus: P0 given 1.0 for a true 0.714 gave a1 30).
LEVEL_WARN = 0.05
LEVEL_SDS = 4.0


def _level_and_se(a: np.ndarray, xy: np.ndarray, yy: float, n: int) -> tuple[float, float]:
    """Least-squares intercept (the level at V0) and its standard error, from X'X, X'y, y'y."""
    try:
        coef = np.linalg.solve(a, xy)
        cov = np.linalg.inv(a)
    except np.linalg.LinAlgError:
        return float("nan"), float("inf")
    rss = max(float(yy - coef @ xy), 0.0)
    dof = n - a.shape[0]
    if dof < 1:
        return float(coef[0]), float("inf")
    return float(coef[0]), float(np.sqrt(max(cov[0, 0], 0.0) * rss / dof))


def _level_note(ch: str, level: float, se: float, opt) -> str | None:
    off = abs(level - 1.0)
    if not (np.isfinite(level) and off > LEVEL_WARN and off > LEVEL_SDS * se):
        return None
    big = ch.upper()
    return (
        f"{big} / {big}0 is about {level:.3g} at V = V0 (from the data, +/- {se:.2g}), not 1: "
        f"with {ch}0 given the model holds {big} = {big}0 at V0 (the shares add up to 1), so "
        f"the shares take up the difference and are not the load's; let loadbayes estimate "
        f"it with {opt(f'{ch}0', 'auto')}, or give the right {ch}0"
    )


def nominal_level_warnings(
    v: np.ndarray,
    p: np.ndarray | None = None,
    q: np.ndarray | None = None,
    *,
    v0: float = 1.0,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    wording: Wording = "cli",
    **_: object,
) -> list[str]:
    """Warnings for a given P0 (Q0) that the data place clearly away from the power at V0.

    Within :data:`NOMINAL_RANGE` (outside it :func:`check_power_units` refuses) but more
    than :data:`LEVEL_WARN` off and by more than :data:`LEVEL_SDS` standard errors of the
    least-squares level (the model's own form, :func:`level_at_nominal`).
    """
    v = np.asarray(v, dtype=float)
    out = []
    for ch, y, nom in (("p", p, p0), ("q", q, q0)):
        if y is None or nom == "auto" or not float(nom):
            continue
        y = np.asarray(y, dtype=float) / float(nom)
        ok = np.isfinite(v) & np.isfinite(y)
        x = v[ok] / v0
        if ok.sum() < 4 or np.ptp(x) < 1e-9:
            continue
        a = _zip_design(x)
        level, se = _level_and_se(a.T @ a, a.T @ y[ok], float(y[ok] @ y[ok]), int(ok.sum()))
        note = _level_note(ch, level, se, lambda n, val: option(n, val, wording=wording))
        if note:
            out.append(note)
    return out


def nominal_level_warnings_gram(gram, *, nominal: Mapping[str, object]) -> list[str]:
    """:func:`nominal_level_warnings` of one bus from its ZIP Gram matrix (fleets)."""
    names = list(gram.names)
    n = int(gram.n)
    idx = [names.index(c) for c in ("1", "z1", "z2")]
    a = gram.matrix[np.ix_(idx, idx)]
    out = []
    for ch, nom in nominal.items():
        col = f"r{ch}"
        if nom == "auto" or col not in names:
            continue
        j = names.index(col)
        # r = P / P0 - 1: its level at V0 is 1 + the intercept
        level, se = _level_and_se(a, gram.matrix[idx, j], float(gram.matrix[j, j]), n)
        note = _level_note(ch, 1.0 + level, se, lambda k, val: option(k, val, wording="cli"))
        if note:
            out.append(note)
    return out


#: Plausible per-unit magnitudes of the motor's states: (column(s), low, high, what).
_MOTOR = (
    (("ud", "uq"), 0.3, 1.5, "terminal voltage |u|"),
    (("w",), 0.5, 1.5, "rotor speed w"),
    (("id", "iq"), 0.0, 10.0, "stator current |i|"),
    (("ed", "eq"), 0.0, 3.0, "internal voltage |e|"),
)


def check_motor_units(
    cols: Mapping[str, np.ndarray], *, wording: Wording = "cli"
) -> list[UnitProblem]:
    """Problems with the units of an induction motor's states (``fit im``'s columns).

    Parameters
    ----------
    cols : mapping
        Arrays ``ud, uq, w, id, iq, ed, eq`` (those present are checked).
    wording : {"cli", "python"}
        The option that accepts them anyway, as ``--accept-units`` or ``accept_units=True``.

    Returns
    -------
    list of UnitProblem
        Empty when the medians look like per unit: ``|u|`` in [0.3, 1.5], ``w`` in
        [0.5, 1.5], ``|i|`` below 10, ``|e|`` below 3.
    """
    out = []
    for names, lo, hi, what in _MOTOR:
        if not all(n in cols for n in names):
            continue
        mag = np.sqrt(sum(np.asarray(cols[n], dtype=float) ** 2 for n in names))
        mag = mag[np.isfinite(mag)]
        if mag.size == 0:
            continue
        med = float(np.median(mag))
        if not lo <= med <= hi:
            hint = (
                " (rad/s or rpm?)"
                if names == ("w",) and med > hi
                else " (V, kV or A?)"
                if med > hi
                else ""
            )
            out.append(
                UnitProblem(
                    "/".join(names),
                    f"{what} has median {med:.4g}{hint}: not per unit",
                    "convert the recording to per unit of the motor's base (fit im reads "
                    "per-unit states and derivatives per second)",
                    wording,
                )
            )
    return out


#: A record's median frequency this far from the nominal is another system's (50 Hz data
#: read against 60 Hz is 17% off), or not in Hz: the composite's events use the same
#: bound (measurements/events.py).
F_OFF = 0.03


def check_frequency(f: np.ndarray, f0: float, *, wording: Wording = "cli") -> list[UnitProblem]:
    """A frequency column against the nominal frequency ``f0`` (Hz).

    ``df = (f - f0) / f0`` is the regressor of ``kpf``: a 50 Hz record at ``f0 = 60``
    makes every sample a 17% frequency excursion, a column in per unit one of -98%.
    """
    f = np.asarray(f, dtype=float)
    f = f[np.isfinite(f)]
    if not f.size:
        return []
    med = float(np.median(f))
    if abs(med / f0 - 1) <= F_OFF:
        return []
    if 0.5 <= med <= 2.0:
        fix = "give the frequency in Hz (the column looks per unit)"
    else:
        near = min((50.0, 60.0), key=lambda x: abs(x - med))
        fix = f"give {option('f0', f'{near:g}', wording=wording)} if the system runs at {near:g} Hz"
    seen = f"the frequency has median {med:.4g}, not about the nominal {f0:g} Hz"
    return [UnitProblem("f", seen, fix, wording)]


def require_power(
    p: np.ndarray | None,
    q: np.ndarray | None,
    *,
    path: str | None = None,
    names: Mapping[str, str | None] | None = None,
    wording: Wording = "cli",
) -> None:
    """Refuse a power column that is 0 in every row (``--accept-units`` does not help).

    A load model's shares are fractions of the power at V0: with P (or Q) 0 throughout
    they are 0 / 0, and the fit, which "fits exactly", reports any numbers at all. An
    open breaker, a current channel that was not recorded (a PMU's zero current), or
    the wrong column gives such data.

    Raises
    ------
    DataError
        Naming the file and the column.
    """
    for ch, y in (("p", p), ("q", q)):
        if y is None:
            continue
        y = np.asarray(y, dtype=float)
        fin = y[np.isfinite(y)]
        if fin.size and not np.any(fin):
            fix = (
                f"name the column that holds it with {option('p-col', wording=wording)}"
                if ch == "p"
                else "fit P alone with " + ("--q-col none" if wording == "cli" else "q_col=None")
            )
            raise DataError(
                f"{ch.upper()} is 0 in all {fin.size} rows: there is no load to fit (an open "
                f"breaker, a current that was not recorded, or the wrong column?); {fix}",
                path=path,
                column=(names or {}).get(ch) or ch,
            )


def check_gram_units(gram, *, v0: float, nominal: Mapping[str, object]) -> list[str]:
    """The unit check of one bus from its ZIP Gram matrix alone (fleets keep no rows).

    Parameters
    ----------
    gram : loadbayes.core.stats.Gram
        Columns of :class:`~loadbayes.models.zip.ZIPModel`: ``z1, z2, 1`` and ``rp``/``p``
        (``rq``/``q``).
    v0 : float
        Nominal voltage of the model.
    nominal : mapping
        ``{"p": P0 or "auto", "q": ...}`` for the channels present.

    Returns
    -------
    list of str
        Plain-words problems (empty when the bus looks per unit). The mean stands in for
        the median of :func:`check_power_units`.
    """
    names = list(gram.names)
    n = max(int(gram.n), 1)
    one = names.index("1")
    x_mean = 1.0 + float(gram.matrix[names.index("z2"), one]) / n
    out = []
    if not (V_RANGE[0] <= x_mean <= V_RANGE[1]):
        out.append(
            f"voltage averages {x_mean:.4g} times v0 ({x_mean * v0:.4g}): not per unit "
            f"({suggest_v_base(x_mean * v0)})"
        )
        return out
    idx = [names.index(c) for c in ("1", "z1", "z2")]
    a = gram.matrix[np.ix_(idx, idx)]
    for ch, nom in nominal.items():
        col = ch if nom == "auto" else f"r{ch}"
        if col not in names:
            continue
        if ch in names and float(gram.matrix[names.index(ch), names.index(ch)]) == 0.0:
            out.append(
                f"{ch.upper()} is 0 in every row: no load to fit (an open breaker, or the "
                "wrong column?)"
            )
            continue
        coef = np.linalg.lstsq(a, gram.matrix[idx, names.index(col)], rcond=None)[0]
        level = float(coef[0])
        if nom == "auto" and abs(level) > AUTO_MAX:
            out.append(
                f"{ch.upper()} at V0 is about {level:.4g}: not per unit of any sensible base "
                "(give --s-base)"
            )
        elif nom != "auto" and not (NOMINAL_RANGE[0] <= 1.0 + level <= NOMINAL_RANGE[1]):
            out.append(
                f"{ch.upper()} at V0 is {1.0 + level:.3g} times the given {ch}0: "
                f"not the power at V0 (give --{ch}0 auto, or --s-base)"
            )
    return out
