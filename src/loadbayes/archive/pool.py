r"""``loadbayes.archive.pool``: each station's composition over the year, events pooled.

An archive's fits (:func:`loadbayes.archive.catalog.fits_frame`: one row per fitted event
and part share) are many shallow measurements of a few slowly changing loads. For each
part (``f_m``, the motor's share of ``zip+motor``; each share of a richer model, apart),
every unit ``u`` (a station's bay) gets a curve over the covariates, and the units'
curves are pooled:

.. math::

    y_e &= \operatorname{logit}(c_e) + (m_e - c_e) / q_e, \quad s_e = sd_e / q_e,
    \quad q_e = c_e (1 - c_e) \\
    y_e &\sim N(x_e^\top \beta_{u(e)} + \eta_e,\; s_e^2), \quad
    \eta_e \sim N(0, \tau_{u(e)}^2) \\
    \beta_u &\sim N(\mu_{g(u)}, \Sigma), \quad \mu_g \sim N(0, M_0), \quad
    \Sigma \sim IW(\nu_0, \Psi_0), \quad \tau_u \sim \text{HalfNormal}(1)

``m_e`` and ``sd_e`` are the event's posterior mean and sd of the share, ``c_e`` a rough
curve of its unit at the event (:func:`.pool_data.working`); ``x_e`` holds 1, the first
and second harmonics of the day of the year (``sin, cos`` of ``2 pi k d / 365.25``, k =
1, 2), those of the hour of the day when asked (``2 pi k h / 24``), and the temperature
(standardised) when a table of it is given. ``eta_e`` is the event-to-event spread around
the unit's curve. ``g(u)`` is the unit's population: one for all the part's units, or one
per bay name (``by_bay``: a transformer bay pooled with the other stations' of that
name), with ``Sigma`` shared. ``M_0 = diag(2.5^2, 1, ...)``; ``Psi_0`` makes the prior
mean of ``Sigma`` ``diag(0.5^2, 0.3^2, ...)`` with ``nu_0 = p + 4``: with three or five
stations the data hardly tell ``Sigma``, and this prior sets how far a station with few
events may stray from the population.

The approximation: an event's share posterior is taken as normal, and the logit is
linearised around the unit's rough curve (iteratively reweighted least squares' working
response; the delta method around the event's own mean gave a share measured low less
weight and biased low shares' curves up). It is poor where the posterior crowds 0 or 1
(its mean within two sd of a bound; counted in the result's notes) and where an event
lies far from its unit's curve (the logit's curvature over the event-to-event spread).
The curve ``logistic(x' beta_u)`` is the share of the unit's median event at ``x`` (the
mean over events is pulled toward 1/2 by ``tau``). Parts are pooled one by one (their sum
to one is not imposed).

Sampled by Gibbs (:mod:`.pool_gibbs`), chains from one seed. What the pool asks of an
event is asked of its share only (:func:`.pool_data.usable`, why these numbers): the
chains agree on it (R-hat under 1.05) and it has 100 effective draws or more, whatever
the motor's other coordinates did. Events whose fit failed, whose share is outside
[0, 1], or that miss either number are left out and counted by reason (``left_out``);
``events`` says how many were pooled.

Which units are alike (the rule, :mod:`.pool_words`), on a grid of the covariates (every
other week, every third hour when hours are modelled, the 10/50/90 % temperatures):
"alike" when the posterior probability that the two curves differ by less than
``tolerance`` (share, default 0.1) everywhere on the grid is 0.8 or more; "different"
when the simultaneous 95% band of their difference lies beyond ``+-tolerance`` at some
point (``prob_apart``, the largest simultaneous level at which it does, 0.95 or more);
"cannot tell" otherwise, which is what wide bands give whether or not the curves are
the same. Groups are the connected sets of alike pairs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.archive.pool_data import (
    ESS_EVENT,
    RHAT_EVENT,
    check_fits,
    event_temperatures,
    usable,
    working,
)
from loadbayes.archive.pool_gibbs import PoolData, PoolPrior, sample_pool
from loadbayes.io.errors import DataError, OptionError

__all__ = ["PartPool", "PoolResult", "design", "pool"]

COVARIATES = ("season", "hour")
MONTHS = ("Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec")
_MONTH_START = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30])
_MONTH_DAYS = np.diff(np.append(_MONTH_START, 365))


def design(day: np.ndarray, hour: np.ndarray | None = None,
           temperature: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:  # fmt: skip
    """The covariate rows ``x``: 1, the seasonal harmonics, the hour's, the temperature."""
    day = np.asarray(day, dtype=float)
    cols, names = [np.ones_like(day)], ["intercept"]
    for what, x, period in (("season", day, 365.25), ("hour", hour, 24.0)):
        if x is None:
            continue
        for k in (1, 2):
            a = 2 * np.pi * k * np.asarray(x, dtype=float) / period
            cols += [np.sin(a), np.cos(a)]
            names += [f"{what}_sin{k}", f"{what}_cos{k}"]
    if temperature is not None:
        cols.append(np.asarray(temperature, dtype=float))
        names.append("temperature")
    return np.stack(cols, axis=-1), names


@dataclass
class PartPool:
    """One part's pooled fit: its units, draws, monthly table and alike pairs."""

    part: str
    units: list[tuple[str, str]]
    events: np.ndarray
    coefs: list[str]
    draws: dict[str, np.ndarray]
    observed: dict[str, np.ndarray]
    monthly: pd.DataFrame
    alike: pd.DataFrame
    groups: list[list[str]]
    diagnostics: dict[str, Any]
    grid: dict[str, Any] = field(repr=False)

    def inference_data(self):
        """The draws as ArviZ ``InferenceData`` (posterior, observed and constant data)."""
        from loadbayes.posterior import import_arviz

        names = [f"{s} / {b}" for s, b in self.units]
        return import_arviz().from_dict(
            posterior={"beta": self.draws["beta"], "mu": self.draws["mu"],
                       "Sigma": self.draws["sigma"], "tau": self.draws["tau"]},
            sample_stats={"accept_tau": self.draws["accept_tau"]},
            observed_data={"y_logit": self.observed["y"]},
            constant_data={"s_logit": self.observed["s"], "unit_index": self.observed["unit"]},
            coords={"unit": names, "coef": self.coefs, "coef_b": self.coefs,
                    "group": self.grid["groups"]},
            dims={"beta": ["unit", "coef"], "mu": ["group", "coef"], "Sigma": ["coef", "coef_b"],
                  "tau": ["unit"], "y_logit": ["event"], "s_logit": ["event"],
                  "unit_index": ["event"]},
            attrs={"part": self.part, "model": "loadbayes.archive.pool"},
        )  # fmt: skip

    def curve(
        self,
        station: str,
        bay: str,
        day: np.ndarray,
        hour: np.ndarray | None = None,
        temperature: np.ndarray | None = None,
        prob: float = 0.95,
    ) -> pd.DataFrame:
        """The unit's share at the covariates given: mean and equal-tailed band per row.

        ``temperature`` in degrees (standardised here as the fit was; the events' mean
        when the fit has a temperature term and none is given). ``hour`` is needed when
        the fit has the hour's harmonics.
        """
        u = self.units.index((station, bay))
        day = np.asarray(day, dtype=float)
        if self.grid["hour"] and hour is None:
            raise OptionError("this pool has the hour of day: give hour= with day=")
        t = None
        if "temperature" in self.coefs:
            given = self.grid["t_mean"] if temperature is None else temperature
            t = (np.broadcast_to(np.asarray(given, float), day.shape) - self.grid["t_mean"]) / (
                self.grid["t_sd"]
            )
        x, _ = design(day, hour if self.grid["hour"] else None, t)
        sh = _shares(self.draws["beta"][:, :, u], x).reshape(-1, x.shape[0])
        lo, hi = np.quantile(sh, [(1 - prob) / 2, (1 + prob) / 2], axis=0)
        return pd.DataFrame({"day": day, "mean": sh.mean(axis=0), "low": lo, "high": hi})


@dataclass
class PoolResult:
    """What :func:`pool` returns: per part a :class:`PartPool`, the events left out, words."""

    parts: dict[str, PartPool]
    left_out: dict[str, int]
    warnings: list[str]
    notes: list[str]
    settings: dict[str, Any]
    #: ``rows``: the fitted shares given (one per event and part); ``pooled``: those read.
    events: dict[str, int] = field(default_factory=dict)

    def events_line(self) -> str:
        """How many event shares were pooled, and why the others were left out."""
        left = ", ".join(f"{k} {v}" for k, v in self.left_out.items() if v)
        n, m = self.events.get("pooled", 0), self.events.get("rows", 0)
        return f"{n} of {m} fitted event shares pooled" + (f"; left out: {left}" if left else "")

    def monthly(self) -> pd.DataFrame:
        """Every part's monthly table (the population's rows have station ``(all)``)."""
        return pd.concat([p.monthly for p in self.parts.values()], ignore_index=True)

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``archive pool --out``."""
        return {
            "settings": self.settings,
            "events": self.events,
            "left_out": self.left_out,
            "warnings": self.warnings,
            "notes": self.notes,
            "parts": {
                name: {
                    "units": [
                        {"station": s, "bay": b, "events": int(n)}
                        for (s, b), n in zip(p.units, p.events, strict=True)
                    ],
                    "monthly": p.monthly.to_dict(orient="records"),
                    "alike": p.alike.to_dict(orient="records"),
                    "groups": p.groups,
                    "diagnostics": p.diagnostics,
                }  # fmt: skip
                for name, p in self.parts.items()
            },
        }


def _shares(beta: np.ndarray, x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-(beta @ x.T)))


def pool(
    frame: pd.DataFrame,
    *,
    covariates: tuple[str, ...] = ("season",),
    temperature: pd.DataFrame | None = None,
    draws: int = 1000,
    burn: int | None = None,
    chains: int = 4,
    seed: int = 0,
    tolerance: float = 0.1,
    by_bay: bool = False,
    source: str | None = None,
    temperature_source: str = "temperature table",
) -> PoolResult:
    """Pool the archive's fitted shares per part: each unit's curve over the covariates.

    Parameters
    ----------
    frame : DataFrame
        ``catalog.fits_frame``: station, bay, event_id, time, part, mean, sd, rhat, status.
    covariates : tuple of str
        ``"season"`` (always) and ``"hour"``.
    temperature : DataFrame, optional
        station, time, temperature (C): each event takes its station's nearest reading
        within 3 h (events with none are left out and counted).
    draws, burn, chains, seed : int
        Kept draws per chain, burn-in (default ``draws // 2``), chains, the seed.
    tolerance : float
        The share difference under which two units are alike (see the module's rule).
    by_bay : bool
        A population per bay name (bays named alike at every station: a transformer's
        with the transformers') instead of one for all the part's units.
    source, temperature_source : str
        Names for the errors (the catalog's and the temperature file's).
    """
    unknown = set(covariates) - set(COVARIATES)
    if unknown or "season" not in covariates:
        raise OptionError(f"covariates must include 'season' and may add 'hour'; got {covariates}")
    if draws < 50 or chains < 1 or not 0 < tolerance < 1:
        raise OptionError("draws must be at least 50, chains at least 1, tolerance in (0, 1)")
    burn = draws // 2 if burn is None else burn
    f = check_fits(frame, source)
    fitted = len(f)
    f, left = usable(f)
    temp, table, t_mean, t_sd = None, None, 0.0, 1.0
    if temperature is not None:
        raw, table = event_temperatures(f, temperature, temperature_source)
        left["no temperature within 3 h"] = int(np.isnan(raw).sum())
        f, raw = f[~np.isnan(raw)].reset_index(drop=True), raw[~np.isnan(raw)]
        t_mean, t_sd = (float(raw.mean()), float(raw.std()) or 1.0) if raw.size else (0.0, 1.0)
        temp = (raw - t_mean) / t_sd
    if f.empty:
        raise DataError("no usable event: " + ", ".join(f"{k} {v}" for k, v in left.items()),
                        source)  # fmt: skip
    hour = "hour" in covariates
    settings = {"covariates": list(covariates), "temperature": temperature is not None,
                "draws": draws, "burn": burn, "chains": chains, "seed": seed,
                "tolerance": tolerance, "by_bay": by_bay,
                "rhat_event": RHAT_EVENT, "ess_event": ESS_EVENT}  # fmt: skip
    res = PoolResult({}, left, [], [], settings, {"rows": fitted, "pooled": len(f)})
    seeds = np.random.SeedSequence(seed).spawn(f["part"].nunique())
    for part, sq in zip(sorted(f["part"].astype(str).unique()), seeds, strict=True):
        rows = np.flatnonzero(f["part"].astype(str).to_numpy() == part)
        grid = {"hour": hour, "t_mean": t_mean, "t_sd": t_sd, "table": table, "by_bay": by_bay}
        res.parts[part] = _fit_part(f.iloc[rows], None if temp is None else temp[rows], grid,
                                    draws, burn, chains, sq, tolerance)  # fmt: skip
        res.warnings += res.parts[part].diagnostics.pop("warnings")
        res.notes += res.parts[part].diagnostics.pop("notes")
    return res


def _fit_part(f, temp, grid, draws, burn, chains, seed, tolerance) -> PartPool:
    from loadbayes.archive.pool_words import alike_pairs, convergence_words, groups_of

    part = str(f["part"].iloc[0])
    keys = list(zip(f["station"].astype(str), f["bay"].astype(str), strict=True))
    units = sorted(set(keys))
    unit = np.array([units.index(k) for k in keys])
    m = f["mean"].to_numpy(float).clip(1e-4, 1 - 1e-4)
    sd = f["sd"].to_numpy(float)
    t = pd.DatetimeIndex(f["time"])
    day = (t.dayofyear - 1 + (t.hour + t.minute / 60) / 24).to_numpy(float)
    hours = (t.hour + t.minute / 60).to_numpy(float) if grid["hour"] else None
    x, coefs = design(day, hours, temp)
    p = len(coefs)
    prior = PoolPrior(mu_sd=np.r_[2.5, np.ones(p - 1)], sigma_sd=np.r_[0.5, np.full(p - 1, 0.3)])
    start, y, s = working(x, unit, len(units), m, sd, prior.sigma_sd)
    data = PoolData.of(unit, x, y, s**2, len(units))
    labels = sorted({b for _, b in units}) if grid["by_bay"] else ["(all)"]
    group = np.array([labels.index(b) if grid["by_bay"] else 0 for _, b in units])
    grid = {**grid, "groups": labels, "group": group}
    out = sample_pool(data, prior, draws=draws, burn=burn, chains=chains, seed=seed,
                      start_beta=start, group=group)  # fmt: skip
    crowded = int(np.sum((m < 2 * sd) | (1 - m < 2 * sd)))
    notes = []
    if crowded:
        notes.append(
            f"{part}: {crowded} event share(s) within two sd of 0 or 1, where the "
            "normal approximation on the logit scale is poor"
        )
    names = [f"{a} / {b}" for a, b in units]
    grid = {**grid, "month_temps": _month_temps(units, grid, temp, f)}
    monthly, month_draws = _monthly(part, units, out, grid, np.bincount(unit, minlength=len(units)))
    table = alike_pairs(names, out["beta"], _alike_grid(grid, temp), tolerance)
    diag = convergence_words(part, names, labels, coefs, out, month_draws)
    if temp is not None:
        diag["warnings"] += _confounded(part, x)
    return PartPool(part, units, np.bincount(unit, minlength=len(units)), coefs, out,
                    {"y": y, "s": s, "unit": unit}, monthly, table,
                    groups_of(names, table), {**diag, "notes": notes}, grid)  # fmt: skip


def _month_temps(units, grid, temp, f) -> np.ndarray | None:
    """Each unit's mean temperature per month (standardised), from the table given."""
    if temp is None:
        return None
    tab = grid["table"]
    out = np.zeros((len(units), 12))
    for i, (station, _) in enumerate(units):
        rows = tab[tab["station"] == station]
        std = (rows["temperature"].to_numpy() - grid["t_mean"]) / grid["t_sd"]
        by = pd.Series(std).groupby(rows["time"].dt.month.to_numpy()).mean()
        out[i] = [by.get(mo, std.mean()) for mo in range(1, 13)]
    return out


def _monthly(part, units, out, grid, counts):
    """The monthly table: each month's mean share over its days (and hours), with bands."""
    k = 3 if grid["hour"] else 6
    pieces = []
    for mo in range(12):
        d = _MONTH_START[mo] + _MONTH_DAYS[mo] * (np.arange(k) + 0.5) / k
        h = np.arange(0, 24, 3) + 1.5 if grid["hour"] else None
        dd, hh = (np.repeat(d, h.size), np.tile(h, d.size)) if h is not None else (d, None)
        pieces.append((dd, hh))
    rows, mdraws = [], []
    populations = [("(all)", g, out["mu"][:, :, [i]], None, grid["group"] == i)
                   for i, g in enumerate(grid["groups"])]  # fmt: skip
    for who in [(s, b, out["beta"][:, :, [u]], u, None) for u, (s, b) in enumerate(units)] + (
        populations
    ):
        station, bay, beta, u, members = who
        for mo, (dd, hh) in enumerate(pieces):
            t = None
            if grid["month_temps"] is not None:
                t = np.full(dd.size, grid["month_temps"][u, mo] if u is not None else 0.0)
            x, _ = design(dd, hh, t)
            v = _shares(beta, x).mean(axis=-1)[:, :, 0]
            lo, hi = np.quantile(v, [0.025, 0.975])
            n = int(counts[u]) if u is not None else int(counts[members].sum())
            rows.append({"part": part, "station": station, "bay": bay, "month": mo + 1,
                         "name": MONTHS[mo], "mean": float(v.mean()), "low": float(lo),
                         "high": float(hi), "events": n})  # fmt: skip
            mdraws.append(v)
    return pd.DataFrame(rows), np.stack(mdraws)


def _confounded(part: str, x: np.ndarray) -> list[str]:
    """Words when the temperature follows the season (and hour): R^2 of it on them."""
    fit, *_ = np.linalg.lstsq(x[:, :-1], x[:, -1], rcond=None)
    r2 = 1 - np.var(x[:, -1] - x[:, :-1] @ fit) / max(np.var(x[:, -1]), 1e-12)
    if r2 < 0.9:
        return []
    return [f"{part}: the events' temperature follows the season (R^2 {r2:.2f} on the "
            "harmonics): the data cannot tell the temperature's effect from the season's; "
            "the curve over the year stands, its split between them does not"]  # fmt: skip


def _alike_grid(grid, temp) -> np.ndarray:
    days = np.arange(7.0, 365, 14.0)
    hours = np.arange(0, 24, 3) + 1.5 if grid["hour"] else None
    temps = [None] if temp is None else list(np.quantile(temp, [0.1, 0.5, 0.9]))
    xs = []
    for t in temps:
        if hours is None:
            dd, hh = days, None
        else:
            dd, hh = np.repeat(days, hours.size), np.tile(hours, days.size)
        xs.append(design(dd, hh, None if t is None else np.full(dd.size, t))[0])
    return np.concatenate(xs)
