"""Play a recorded voltage into an exported ANDES case and compare its P, Q with the record.

The load devices of the exported case (the ``PQ`` its ``ZIP`` replaces, the ``ZIP``,
``Motor3`` and ``Shunt`` on the load's bus) are copied into a two-bus ANDES system: the
load bus fed through a lossless tie of reactance ``X_TIE`` (1e-4 p.u.) from a ``Slack``,
an ideal source. (ANDES 2.0 does not solve a single bus carrying both the ``Slack`` and
the load: its power flow stops at iteration 0 with the ``Slack``'s P and Q at zero.)

The ``Slack``'s set points ``v0`` and ``a0`` follow the record through ANDES's
perturbation hook, ``TDS.callpert(t, system)``, which ``TDS.run`` calls at the top of
every step with the time being solved (``andes/routines/tds.py``; ``andes run --pert
FILE`` loads the same hook from a file). ANDES's implicit trapezoid so sees the record at
both ends of every step, linear between the samples; a step of the voltage inside a
sample interval (a fault, its clearing) is put where the fit put it, or at the
interval's middle (:mod:`loadbayes.models.composite_steps`). ANDES 2.0's ``TimeSeries``
device (``andes/models/timeseries.py``) applies values only at a file's exact times (its
interpolated mode raises ``NotImplementedError``): a staircase, hence the hook. ANDES
runs to each sample time in turn (``TDS.run`` with ``tf`` raised), so the samples are
among its points even where it shortened its step.

One idea needs these 545 lines: a record played through an exported ANDES case, from
reading the fit and the case's load devices to the run and its comparison with the
record.
The load's P, Q are the ``Slack``'s injection less the tie's ``X_TIE |I|^2`` (exact for a
lossless tie). The load bus misses the record by the tie's drop ``X_TIE |I|`` (about
1e-4), reported as ``max_v_error``. The power flow puts the bus at the first sample's
voltage, the fit's ``v0`` for the event that was fitted: there the ``ZIP`` shares refer
to ``v0`` as in loadbayes, and the motor starts at its steady state.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from loadbayes.export.andes.conventions import andes_quiet, solve_power_flow
from loadbayes.export.andes.run import TDS_TOL
from loadbayes.io.errors import DataError
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite_steps import EPS_FRACTION, step_intervals

__all__ = ["FitResult", "Playback", "load_devices", "playback", "read_fit", "step_for"]

#: Longest ANDES step (s): the harness's default for the IEEE motors (docs/andes.md).
MAX_STEP_S = 1.0 / 600.0

_COPIED = ("PQ", "ZIP", "Motor3", "Shunt")
#: Reactance of the tie from the ideal source to the load bus (system p.u.).
X_TIE = 1e-4


@dataclass(frozen=True)
class Playback:
    """A record played into an ANDES case: what was imposed, recorded and simulated.

    Arrays are at the record's sample times (system p.u., rad, s).
    """

    t_s: np.ndarray
    v: np.ndarray
    angle_rad: np.ndarray
    p_rec: np.ndarray
    q_rec: np.ndarray
    p_sim: np.ndarray
    q_sim: np.ndarray
    p0: float
    step_s: float
    s_base_mva: float
    angle_from: str
    v_load: np.ndarray
    devices: dict[str, int] = field(default_factory=dict)
    steps: dict[int, float] = field(default_factory=dict)

    @property
    def rms_p(self) -> float:
        """RMS of simulated minus recorded P, per unit of ``p0``."""
        return float(np.sqrt(np.mean((self.p_sim - self.p_rec) ** 2)) / self.p0)

    @property
    def rms_q(self) -> float:
        """RMS of simulated minus recorded Q, per unit of ``p0``."""
        return float(np.sqrt(np.mean((self.q_sim - self.q_rec) ** 2)) / self.p0)

    def to_dict(self) -> dict[str, Any]:
        """The numbers (no arrays): RMS, sample count, step, the devices played."""
        return {
            "n": int(self.t_s.size),
            "t_span_s": float(self.t_s[-1] - self.t_s[0]),
            "p0": self.p0,
            "rms_p": self.rms_p,
            "rms_q": self.rms_q,
            "max_abs_p": float(np.max(np.abs(self.p_sim - self.p_rec)) / self.p0),
            "max_abs_q": float(np.max(np.abs(self.q_sim - self.q_rec)) / self.p0),
            "step_s": self.step_s,
            "s_base_mva": self.s_base_mva,
            "max_v_error": float(np.max(np.abs(self.v_load - self.v))),
            "angle_from": self.angle_from or "none (magnitude only)",
            "devices": dict(self.devices),
            "steps": [{"interval": k, "t_s": s} for k, s in self.steps.items()],
        }


@dataclass(frozen=True)
class FitResult:
    """What playback takes from a composite fit's JSON.

    ``p0`` of event 0 (the operating point the export writes), the residual noise
    ``sigma_p``, ``sigma_q`` (``tau_p^-1/2``, ``tau_q^-1/2``, system p.u., shared by the
    events), the names of the fitted events, and per event its ``p0`` and the steps the
    fit placed (interval ``k`` to the posterior mean of its instant, s).
    """

    p0: float
    sigma_p: float | None
    sigma_q: float | None
    events: tuple[str, ...]
    steps: dict[str, dict[int, float]]
    p0_by_event: dict[str, float] = field(default_factory=dict)
    s_base_mva: float | None = None
    #: The fit's nominal frequency (Hz): the events are read against it, as the fit read them.
    f_hz: float = 60.0

    def fitted_event(self, name: str) -> str | None:
        """The fitted event whose file has the name of ``name``, or None (held out)."""
        for fitted in self.events:
            if Path(fitted).name == Path(name).name:
                return fitted
        return None

    def steps_for(self, name: str) -> dict[int, float] | None:
        """The fit's steps for the event file ``name`` (matched by file name), or None."""
        fitted = self.fitted_event(name)
        return None if fitted is None else self.steps.get(fitted, {})

    def p0_for(self, name: str) -> float:
        """The fitted ``p0`` of that event when it was fitted, else event 0's."""
        fitted = self.fitted_event(name)
        return self.p0_by_event.get(fitted, self.p0) if fitted is not None else self.p0


def read_fit(path: str | Path) -> FitResult:
    """Read a ``fit composite --json`` result for playback.

    Raises
    ------
    DataError
        Naming the file: not a loadbayes JSON, the result of another fit, no ``p0``.
    """
    import json

    where = str(path)
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        model, params = doc["model"], doc["parameters"]
    except (OSError, ValueError, KeyError, TypeError, UnicodeDecodeError, RecursionError):
        raise DataError("not a loadbayes posterior JSON (no 'model'/'parameters')", where) from None
    if model != "composite":
        raise DataError(
            f"a JSON of a {model} fit ({doc.get('method', '?')}): playback takes the result "
            "of fit composite",
            where,
        )
    if not isinstance(params, dict):
        raise DataError("'parameters' is not an object", where)

    def mean(name: str) -> float | None:
        row = params.get(name)
        val = row.get("mean") if isinstance(row, dict) else None
        if val is None:
            return None
        if not isinstance(val, int | float) or isinstance(val, bool) or not math.isfinite(val):
            raise DataError(f"parameters.{name}.mean is {val!r}, expected a finite number", where)
        return float(val)

    p0 = mean("p0")
    if p0 is None or p0 <= 0:
        raise DataError(f"parameters.p0 is {p0!r}: playback needs the fitted P0 > 0", where)
    taus = [mean(n) for n in ("tau_p", "tau_q")]
    sigma = [None if t is None or t <= 0 else t**-0.5 for t in taus]
    settings = doc.get("settings") if isinstance(doc.get("settings"), dict) else {}
    listed = settings.get("events") or []
    names = tuple(str(e.get("name", "")) for e in listed if isinstance(e, dict))
    steps: dict[str, dict[int, float]] = {n: {} for n in names}
    intervals = (settings.get("steps") or {}).get("intervals") or []
    count: dict[int, int] = {}
    for item in intervals:
        e, k = int(item["event"]), int(item["k"])
        j = count.get(e, 0)
        count[e] = j + 1
        instant = mean(f"t_step{j}{'' if e == 0 else f'_e{e}'}")
        if instant is not None and e < len(names):
            steps[names[e]][k] = instant
    p0s = {}
    for e, name in enumerate(names):
        val = mean(f"p0{'' if e == 0 else f'_e{e}'}")
        if val is not None and val > 0:
            p0s[name] = val
    s_base = settings.get("s_base_mva", settings.get("s_base"))
    if s_base is not None and not (
        isinstance(s_base, int | float) and not isinstance(s_base, bool) and s_base > 0
    ):
        raise DataError(f"settings.s_base_mva is {s_base!r}, expected MVA > 0", where)
    f_hz = settings.get("f_hz", 60.0)
    if not (isinstance(f_hz, int | float) and not isinstance(f_hz, bool) and 10 <= f_hz <= 1000):
        raise DataError(f"settings.f_hz is {f_hz!r}, expected 10-1000 Hz", where)
    return FitResult(
        p0, sigma[0], sigma[1], names, steps, p0s, None if s_base is None else float(s_base),
        float(f_hz),
    )  # fmt: skip


def load_devices(case: str | Path) -> dict[str, list[dict[str, Any]]]:
    """The load's devices in an ANDES case: the bus of its first ``ZIP`` (or ``Motor3``).

    Parameters
    ----------
    case : str or Path
        An ANDES case file (``.xlsx``, ``.json``), such as ``export --to andes`` writes.

    Returns
    -------
    dict
        ``"Bus"`` (the load bus's row) and, per model of ``PQ, ZIP, Motor3, Shunt``, the
        input parameters of each device on that bus (``ZIP`` rows those of its ``PQ``);
        ``"mva"``: the case's system base (MVA).

    Raises
    ------
    DataError
        If ANDES cannot read the file or it holds no ``ZIP`` or ``Motor3``.
    """
    import andes

    path = str(case)
    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp, andes_quiet():
        try:
            ss = andes.load(path, setup=False, no_output=True, default_config=True, output_path=tmp)
        except Exception as exc:  # ANDES raises many types for a file it cannot parse
            raise DataError(f"ANDES cannot read this case ({type(exc).__name__})", path) from None
        if ss is None:
            raise DataError("ANDES cannot read this case", path)
        rows = {name: _rows(ss, name) for name in ("Bus", *_COPIED)}
        mva = float(ss.config.mva)
    pq_bus = {r["idx"]: r["bus"] for r in rows["PQ"]}
    # A load exported into another case (--case) has named devices: only those are
    # the load; the case's own devices on that bus are not.
    ours = {name: [r for r in rows[name] if str(r["idx"]).startswith("loadbayes_")]
            for name in _COPIED}  # fmt: skip
    if any(ours.values()):
        rows.update(ours)
    if rows["ZIP"]:
        bus = pq_bus.get(rows["ZIP"][0]["pq"])
    elif rows["Motor3"]:
        bus = rows["Motor3"][0]["bus"]
    else:
        raise DataError("no ZIP or Motor3 device: not a load exported by loadbayes", path)
    out: dict[str, list[dict[str, Any]]] = {
        "Bus": [r for r in rows["Bus"] if r["idx"] == bus],
        "PQ": [r for r in rows["PQ"] if r["bus"] == bus],
    }
    pqs = {r["idx"] for r in out["PQ"]}
    out["ZIP"] = [r for r in rows["ZIP"] if r["pq"] in pqs]
    out["Motor3"] = [r for r in rows["Motor3"] if r["bus"] == bus]
    out["Shunt"] = [r for r in rows["Shunt"] if r["bus"] == bus]
    if not out["Bus"]:
        raise DataError(f"the load's bus {bus!r} is not in the case", path)
    out["mva"] = mva  # type: ignore[assignment]
    return out


def _rows(ss: Any, name: str) -> list[dict[str, Any]]:
    model = ss.models.get(name) if hasattr(ss, "models") else None
    if model is None or model.n == 0:
        return []
    data = model.as_dict(vin=True)
    keys = list(data)
    return [{k: data[k][i] for k in keys} for i in range(model.n)]


def step_for(devices: dict[str, list[dict[str, Any]]]) -> float:
    """ANDES's step (s): ``1/(600 k)``, at most a sixteenth of the fastest motor mode.

    The mode is the short-circuit transient ``T'0 x' / x0`` of each ``Motor3`` (docs/andes.md,
    "Tolerances"); without a motor, 1/600 s.
    """
    fastest = math.inf
    for m in devices.get("Motor3", []):
        xr1, xm, xs, rr1 = (float(m[k]) for k in ("xr1", "xm", "xs", "rr1"))
        t10 = (xr1 + xm) / (2 * math.pi * float(m["fn"]) * rr1)
        x1, x0 = xs + xr1 * xm / (xr1 + xm), xs + xm
        fastest = min(fastest, t10 * x1 / x0)
    k = 1 if not math.isfinite(fastest) else max(1, math.ceil(16 * MAX_STEP_S / fastest))
    return MAX_STEP_S / k


def playback(
    case: str | Path,
    event: EventRecord,
    *,
    p0: float,
    steps: dict[int, float] | None = None,
    s_base_mva: float | None = None,
    step_s: float | None = None,
) -> Playback:
    """Run an exported ANDES case with the event's voltage imposed at the load bus.

    Parameters
    ----------
    case : str or Path
        The ANDES case (``export --to andes``; any case whose load bus carries a ``ZIP``
        or a ``Motor3``).
    event : EventRecord
        The record (system p.u.): ``t, v, p, q`` and, when present, the angle ``delta``;
        without it the angle is held at 0 (the magnitude alone is played).
    p0 : float
        The P the RMS is expressed in (the fitted ``p0``), system p.u.
    steps : dict of int to float, optional
        Voltage steps inside sample intervals: interval ``k`` (``t_k`` to ``t_k+1``) to
        the step's instant (s, the record's clock). The voltage holds ``V_k`` until the
        instant, then ``V_k+1`` (as the fit reads a step: ``models/composite_steps.py``).
        Default: the intervals :func:`~loadbayes.models.composite_steps.step_intervals`
        finds, each stepped at its middle.
    s_base_mva : float, optional
        MVA per p.u. of the event's (and ``p0``'s) powers. ANDES's P, Q (p.u. of the
        case's system base) are rescaled to it. Default: the case's base (the event is
        per unit of the same base).
    step_s : float, optional
        ANDES's fixed step; default :func:`step_for`.

    Returns
    -------
    Playback
        The imposed voltage, the recorded and the simulated P, Q at the record's times.

    Raises
    ------
    DataError
        If the case cannot be read or holds no load.
    RuntimeError
        If ANDES's power flow or time-domain run fails.
    """
    if not (math.isfinite(p0) and p0 > 0):
        raise ValueError(f"p0 must be a positive number, got {p0!r}")
    devices = load_devices(case)
    h = float(step_s) if step_s is not None else step_for(devices)
    t = np.asarray(event.t, dtype=float)
    v = np.asarray(event.v, dtype=float)
    angle = np.zeros_like(v) if event.delta is None else np.asarray(event.delta, dtype=float)
    if steps is None:
        steps = {int(k): 0.5 * (t[k] + t[k + 1]) for k in step_intervals(v)}
    knots_t, knots_v, knots_a = _knots(t, v, angle, steps)
    with tempfile.TemporaryDirectory(prefix="loadbayes-andes-") as tmp:
        p_k, q_k, v_k = _run(devices, knots_t - t[0], knots_v, knots_a, h, tmp)
    # The record's own samples (the knots add the steps' instants).
    at = np.searchsorted(knots_t, t)
    scale = 1.0 if s_base_mva is None else float(devices["mva"]) / float(s_base_mva)
    p_sim, q_sim, v_load = p_k[at] * scale, q_k[at] * scale, v_k[at]
    _check_bases(case, event, p_sim[0], float(devices["mva"]), s_base_mva)
    counts = {name: len(devices[name]) for name in _COPIED if devices[name]}
    return Playback(
        t_s=t,
        v=v,
        angle_rad=angle,
        p_rec=np.asarray(event.p, dtype=float),
        q_rec=np.asarray(event.q, dtype=float),
        p_sim=p_sim,
        q_sim=q_sim,
        p0=float(p0),
        step_s=h,
        s_base_mva=float(devices["mva"]) if s_base_mva is None else float(s_base_mva),
        angle_from=event.angle_from if event.delta is not None else "",
        v_load=v_load,
        devices=counts,
        steps={int(k): float(s) for k, s in sorted(steps.items())},
    )


#: The case's load at the event's first sample, over the event's: outside this range
#: the two are not on the same base (a factor 20 for a 5 MVA fit on a 100 MVA case).
BASE_RATIO = (0.5, 2.0)


def _check_bases(case, event: EventRecord, p_first: float, mva: float, s_base) -> None:
    """Refuse a playback whose case and event disagree on the power base."""
    p_rec = float(event.p[0])
    ratio = p_first / p_rec if p_rec > 0 else math.inf
    if BASE_RATIO[0] <= ratio <= BASE_RATIO[1]:
        return
    used = f"{mva:g} MVA, the case's" if s_base is None else f"{float(s_base):g} MVA"
    raise DataError(
        f"its load draws {p_first * (s_base or mva):.4g} MW at the event's first voltage, "
        f"the event {p_rec * (s_base or mva):.4g} MW (p.u. x {used}): the power bases "
        "disagree; give playback --s-base as the export used it (or export with the "
        "fit's --s-base)",
        str(case),
    )


def _knots(t, v, angle, steps: dict[int, float]):
    """The imposed voltage's knots: the samples, and two more at each step's instant."""
    kt, kv, ka = [t], [v], [angle]
    for k, instant in steps.items():
        if not 0 <= k < t.size - 1:
            raise ValueError(f"step interval {k} is outside the record's {t.size - 1} intervals")
        dt = t[k + 1] - t[k]
        eps = EPS_FRACTION * dt
        s = min(max(float(instant), t[k] + eps), t[k + 1] - 2 * eps)
        kt.append(np.array([s, s + eps]))
        kv.append(np.array([v[k], v[k + 1]]))
        ka.append(np.array([angle[k], angle[k + 1]]))
    order = np.argsort(np.concatenate(kt), kind="stable")
    return tuple(np.concatenate(x)[order] for x in (kt, kv, ka))


def _run(devices, t_rel, v, angle, h, tmp) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import andes
    from andes.linsolvers.solverbase import Solver

    bus = devices["Bus"][0]
    with andes_quiet():
        ss = andes.System(no_output=True, default_config=True, output_path=tmp)
        source = "playback-source"
        for idx in (bus["idx"], source):
            ss.add("Bus", {"idx": idx, "Vn": bus["Vn"], "v0": v[0], "a0": angle[0]})
        ss.add(
            "Slack",
            {"idx": "playback", "bus": source, "Vn": bus["Vn"], "v0": v[0], "a0": angle[0],
             "Sn": float(ss.config.mva)},
        )  # fmt: skip
        ss.add(
            "Line",
            {"idx": "playback-tie", "bus1": source, "bus2": bus["idx"], "r": 0.0, "x": X_TIE,
             "b": 0.0, "Vn1": bus["Vn"], "Vn2": bus["Vn"]},
        )  # fmt: skip
        for name in _COPIED:
            for row in devices[name]:
                ss.add(name, {k: val for k, val in row.items() if k not in ("uid", "name")})
        ss.setup()
    solve_power_flow(ss)
    slack = ss.Slack

    def follow(t_now: float, system: Any) -> None:
        # ANDES calls this before solving the step that ends at t_now: both ends of the
        # trapezoid then see the record, linear between its samples.
        tt = float(t_now)
        slack.set("v0", "playback", "v", float(np.interp(tt, t_rel, v)))
        slack.set("a0", "playback", "v", float(np.interp(tt, t_rel, angle)))

    cfg = ss.TDS.config
    cfg.tf, cfg.fixt, cfg.tstep, cfg.no_tqdm, cfg.criteria = float(t_rel[-1]), 1, h, 1, 0
    cfg.tol = TDS_TOL
    ss.TDS.solver = Solver(sparselib="spsolve")  # raise, never segfault, on a NaN
    ss.TDS.callpert = follow
    ok = True
    with andes_quiet():
        # One run per sample interval: ANDES ends each run exactly at its tf, so the
        # record's times are among ANDES's points even where it shortened its steps.
        for t_next in t_rel[1:]:
            cfg.tf = float(t_next)
            ok = ss.TDS.run() and not ss.TDS.busted
            if not ok:
                break
    ts = ss.dae.ts
    if not ok or ts.t[-1] < t_rel[-1] - 1e-9:
        raise RuntimeError(f"ANDES time-domain playback failed at t = {float(ts.t[-1]):.4g} s")
    ts_t = np.asarray(ts.t, dtype=float)
    y = np.asarray(ts.y)
    keep = np.append(np.diff(ts_t) > 0, True)  # a time recorded twice keeps its later record
    p = y[keep, int(slack.p.a[0])]
    q_src = y[keep, int(slack.q.a[0])]
    v_src = y[keep, int(ss.Bus.v.a[ss.Bus.idx2uid(source)])]
    q = q_src - X_TIE * (p**2 + q_src**2) / v_src**2  # the tie's own Q
    v_bus = y[keep, int(ss.Bus.v.a[ss.Bus.idx2uid(bus["idx"])])]
    tk = ts_t[keep]
    return np.interp(t_rel, tk, p), np.interp(t_rel, tk, q), np.interp(t_rel, tk, v_bus)


#: Playback RMS up to this multiple of the fit's residual noise reads as "reproduced":
#: a perfect reproduction's RMS is the noise's, within 1/sqrt(2 n) (5% at n = 200).
WITHIN = 1.2


def compare(pb: Playback, fit: FitResult, *, event: str | None = None) -> dict[str, Any]:
    """The playback's numbers against the fit's residual noise, with a verdict in words.

    ``event`` (the event file's name) adds what the verdict must know: an event the fit
    held its own operating point and static mix for is played into event 0's (the one
    the export writes); a held-out event's steps sit at the intervals' middles.

    Returns
    -------
    dict
        :meth:`Playback.to_dict` plus ``fit_residual_p``, ``fit_residual_q`` (the fit's
        noise per unit of ``p0``), ``ratio_p``, ``ratio_q`` (playback RMS over them),
        ``reproduces`` (both ratios at most :data:`WITHIN`; None without the noise) and
        ``verdict`` (one sentence).
    """
    out = pb.to_dict()
    caveat = ""
    if event is not None and fit.events:
        fitted = fit.fitted_event(event)
        if fitted is None:
            caveat = (
                "; a held-out event: its voltage steps are put at the middles of their "
                "sample intervals, which alone can raise Q's RMS several-fold (docs/andes.md)"
            )
        elif fitted != fit.events[0]:
            caveat = (
                f"; the case holds the operating point and static mix of {fit.events[0]} "
                "(the export writes event 0's), this event was fitted with its own"
            )
    if fit.sigma_p is None or fit.sigma_q is None:
        out.update(fit_residual_p=None, fit_residual_q=None, ratio_p=None, ratio_q=None)
        out["reproduces"] = None
        out["verdict"] = (
            f"played back: RMS {pb.rms_p:.4f} on P, {pb.rms_q:.4f} on Q (per unit of P0); "
            "the result holds no residual noise (tau_p, tau_q) to compare them with" + caveat
        )
        return out
    res_p, res_q = fit.sigma_p / pb.p0, fit.sigma_q / pb.p0
    ratio_p, ratio_q = pb.rms_p / res_p, pb.rms_q / res_q
    ok = ratio_p <= WITHIN and ratio_q <= WITHIN
    out.update(fit_residual_p=res_p, fit_residual_q=res_q, ratio_p=ratio_p, ratio_q=ratio_q)
    out["reproduces"] = bool(ok)
    numbers = (
        f"RMS {pb.rms_p:.4f} on P, {pb.rms_q:.4f} on Q per unit of P0, {ratio_p:.2f} and "
        f"{ratio_q:.2f} times the fit's residual noise"
    )
    if ok:
        out["verdict"] = f"the exported case reproduces the record: {numbers}{caveat}"
    else:
        worse = "P" if ratio_p >= ratio_q else "Q"
        out["verdict"] = (
            f"the exported case does NOT reproduce the record ({numbers}): its {worse} "
            "misses by more than the noise the fit found. The exported values are one "
            "point of the posterior (its mean, by default), which can sit off the "
            "posterior's ridge; export a draw (export --draws) or a median, or check the "
            "fit (R-hat, the warnings in its JSON)" + caveat
        )
    return out
