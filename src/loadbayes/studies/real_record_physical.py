"""The real record with loads built from parts: physical, compared, and the negative sequence.

For each main transformer of the shared State Grid record (``studies/real_record.py``
reads it), three models are fitted to each of the two faults and asked to predict the
other from its recorded voltage alone (``fit/composite/choice.compare_models``):
``zip+motor`` (today's, free shares), ``slm`` (ZIP + one motor behind Rd + jXd) and
``cmld-lite`` (feeder, motors A and B, motor D, electronics, static part), the last two
with their shares on the simplex and published priors (``models/part_priors.py``). The
section shows, per transformer:

- the physical models' fit of the first fault: every share, each motor's Rs and H on its
  own base, the feeder, and what the fit said in words (outside the physical region,
  left to the prior), beside today's ``zip+motor``;
- the reclose (second fault) predicted from the first fault's fit: RMS of P and Q in %
  of P0 and the share of samples inside the 95 % band;
- the model the record supports (held-out ELPD, its standard error) in words;
- what the negative sequence adds: the motors' total rating with and without it;
- where the reclose is missed (:func:`reclose_miss`: the rows before the fault, the first
  cycles after clearing, the level after them), and two things no load model fitted on
  the first fault can know, measured on the record itself: how far the two faults'
  own responses differ (:func:`faults_apart`) and the even harmonic of the current that
  a transformer's magnetising inrush draws after a fault (:func:`second_harmonic`);
- how much of the reclose's miss is model form (``fit/composite/model_error.py``, worded
  by ``studies/reclose_form.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.fit.composite.model_error import held_out_error
from loadbayes.studies.real_record import BAYS, SOURCE, events_of, find_record
from loadbayes.studies.reclose_form import form_rows, form_words

__all__ = [
    "PhysicalStudy",
    "faults_apart",
    "html_section",
    "reclose_miss",
    "run",
    "second_harmonic",
    "text_table",
]

#: Iterations (burn-in) per chain, quick and full.
QUICK, FULL = (4000, 2000), (24000, 6000)

#: Cycles after a fault's clearing read as its first ones (the motors re-accelerating).
FIRST_CYCLES = 3

#: A current's 2nd harmonic after a fault said to be an inrush's when it is above this
#: share of the fundamental and twice what it was before the fault.
INRUSH_H2 = 0.02


@dataclass
class PhysicalStudy:
    """What :func:`run` returns: one column per transformer, and the words."""

    table: pd.DataFrame
    choice: dict[str, dict[str, Any]] = field(default_factory=dict)
    words: dict[str, list[str]] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    record: str | None = None


def _ci(x: np.ndarray) -> str:
    x = np.asarray(x, dtype=float).ravel()
    lo, hi = np.percentile(x, [2.5, 97.5])
    return f"{np.median(x):.3g} [{lo:.3g}, {hi:.3g}]"


def _rating(post) -> np.ndarray:
    names = [n for n in post.draws if n.startswith("mva") and "_e" not in n]
    return sum(np.asarray(post.draws[n], dtype=float).ravel() for n in names)


def _steps(straddle: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """The first and last straddling row's times: the fault's inception and clearing."""
    k = np.flatnonzero(np.asarray(straddle, bool))
    return (float(t[k[0]]), float(t[k[-1]])) if k.size else (float("nan"), float("nan"))


def reclose_miss(v, t_fault: float, t_clear: float, f_hz: float,
                 reach: float = np.inf) -> dict[str, float]:  # fmt: skip
    """Where a held-out prediction misses, in % of the fitted P0.

    ``v``: an ``EventValidation``; ``t_fault``, ``t_clear``: the event's first and last
    row whose window straddles a step. ``before_p``: the RMS of P over the scored rows
    before the fault, where the prediction is the operating point (their mean): the
    load's own movement with the voltage steady, which no model driven by the voltage
    predicts. ``first_p``, ``first_q``: the RMS over the :data:`FIRST_CYCLES` cycles after
    clearing. ``later_p``, ``later_q``: the mean of recorded minus predicted after them
    (a level the prediction misses), ``later_cover_q`` the share of those rows in Q's band.
    ``reach``: how long after its clearing the fitted event's record runs (s); ``beyond_p``,
    ``beyond_q`` are the mean over the rows further after clearing than that, which the
    fit never saw (``beyond_rows`` of them), ``within_q`` over the later rows before them.
    """
    t, sc, b = v.event.t, np.asarray(v.scored, bool), v.band
    rp = (v.event.p - b["p_mean"]) / v.scale * 100
    rq = (v.event.q - b["q_mean"]) / v.scale * 100
    inq = (v.event.q >= b["q_lo"]) & (v.event.q <= b["q_hi"])
    end = t_clear + FIRST_CYCLES / f_hz
    parts = {"before": sc & (t < t_fault), "first": sc & (t > t_clear) & (t <= end),
             "later": sc & (t > end), "beyond": sc & (t > max(end, t_clear + reach))}  # fmt: skip
    parts["within"] = parts["later"] & ~parts["beyond"]

    def rms(x, m):
        return float(np.sqrt(np.mean(x[m] ** 2))) if m.any() else float("nan")

    def mean(x, m):
        return float(np.mean(x[m])) if m.any() else float("nan")

    return {"before_p": rms(rp, parts["before"]), "first_p": rms(rp, parts["first"]),
            "first_q": rms(rq, parts["first"]), "later_p": mean(rp, parts["later"]),
            "later_q": mean(rq, parts["later"]),
            "later_cover_q": mean(inq.astype(float), parts["later"]),
            "within_q": mean(rq, parts["within"]), "beyond_p": mean(rp, parts["beyond"]),
            "beyond_q": mean(rq, parts["beyond"]),
            "beyond_rows": int(parts["beyond"].sum())}  # fmt: skip


def faults_apart(events, straddles, f_hz: float) -> dict[str, float]:
    """How far two faults' own responses differ, in % of the second's P0: no model needed.

    Each event's P and Q from its mean before the fault, the two aligned at their last
    straddling row (the clearing) and compared on the rows from :data:`FIRST_CYCLES`
    cycles after it on (where the two faults' lengths, which differ, matter less) that
    straddle no step in either: the RMS and mean of second minus first, and the RMS of
    their voltages' difference (each from its first row) in % of nominal. Where the
    voltages agree and the powers do not, the load answered alike sags differently: a
    model fitted to one fault cannot predict the other much closer than this.
    ``steady_p``: the RMS of the second event's P about its mean over the rows before its
    fault, the voltage steady: the load's own movement, which no prediction from the
    voltage follows.
    """
    (e0, e1), (s0, s1) = events[:2], [np.asarray(s, bool) for s in straddles[:2]]
    k0, k1 = np.flatnonzero(s0), np.flatnonzero(s1)
    if not (k0.size and k1.size):
        return {}
    a0, a1 = k0[-1], k1[-1]
    k = np.arange(min(e0.n - a0, e1.n - a1))
    ok = ~s0[a0 + k] & ~s1[a1 + k] & (e1.t[a1 + k] - e1.t[a1] > FIRST_CYCLES / f_hz)
    if not ok.any():
        return {}
    p00, q00 = e0.p[: k0[0]].mean(), e0.q[: k0[0]].mean()
    p01, q01 = e1.p[: k1[0]].mean(), e1.q[: k1[0]].mean()
    dp = ((e1.p[a1 + k] - p01) - (e0.p[a0 + k] - p00))[ok] / p01 * 100
    dq = ((e1.q[a1 + k] - q01) - (e0.q[a0 + k] - q00))[ok] / p01 * 100
    dv = ((e1.v[a1 + k] - e1.v[0]) - (e0.v[a0 + k] - e0.v[0]))[ok] * 100
    return {"rms_p": float(np.sqrt(np.mean(dp**2))), "mean_p": float(dp.mean()),
            "rms_q": float(np.sqrt(np.mean(dq**2))), "mean_q": float(dq.mean()),
            "rms_v": float(np.sqrt(np.mean(dv**2))), "rows": int(ok.sum()),
            "steady_p": float(np.std(e1.p[: k1[0]]) / p01 * 100)}  # fmt: skip


def second_harmonic(v: np.ndarray, i: np.ndarray, n: int, *, skip: int = FIRST_CYCLES,
                    sag: float = 0.95) -> tuple[float, float]:  # fmt: skip
    """The currents' 2nd harmonic over their fundamental before a fault and after it.

    ``v``, ``i``: one waveform segment's phase voltages and currents, shape (3, m);
    ``n`` samples a cycle. Whole cycles, one DFT each; the fault's cycles are those where
    a phase voltage's fundamental falls under ``sag`` of its median; returns the median
    over the cycles before the first of them and over those from ``skip`` cycles after
    the last (mean over phases). A transformer whose core a fault's voltage recovery
    left saturating draws an inrush: even harmonics, and a fundamental that is reactive.
    """
    c = v.shape[1] // n
    k = np.arange(n)
    e1, e2 = np.exp(-2j * np.pi * k / n), np.exp(-4j * np.pi * k / n)
    vw = v[:, : c * n].reshape(3, c, n)
    iw = i[:, : c * n].reshape(3, c, n)
    v1 = np.abs(vw @ e1)
    ratio = (np.abs(iw @ e2) / np.maximum(np.abs(iw @ e1), 1e-12)).mean(0)
    low = np.flatnonzero((v1 < sag * np.median(v1, axis=1, keepdims=True)).any(0))
    if not low.size:
        return float("nan"), float("nan")
    before, after = ratio[: low[0]], ratio[low[-1] + 1 + skip :]
    med = [float(np.median(x)) if x.size else float("nan") for x in (before, after)]
    return med[0], med[1]


def _replay(models, name: str, post, event, straddle, seed: int):
    """The fitted event played back through its own fit (the held-out scoring's path)."""
    from loadbayes.fit.composite.validate import validate_event
    from loadbayes.fit.composite.validate_parts import validate_parts_event

    model = next(m for m in models if m.name == name)
    if getattr(model, "parts", None) is not None:
        return validate_parts_event(post, model, event, exclude=straddle, seed=seed)
    return validate_event(post, event, exclude=straddle, seed=seed)


def _harmonics(cfg, bay: str, f_hz: float) -> list[tuple[float, float]]:
    """:func:`second_harmonic` of each waveform segment of one bay, in time order."""
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.phasors import samples_per_cycle

    w = read_comtrade(cfg, bay=bay)
    out = []
    for s in w.segments:
        if s.kind == "waveform":
            n = samples_per_cycle(s.rate_hz, f_hz)
            out.append(second_harmonic(w.v[:, s.start : s.stop], w.i[:, s.start : s.stop], n))
    return out


def _miss_words(miss: dict, own: dict, apart: dict, h2: list) -> list[str]:
    """What the reclose's miss is made of, in words, from the measured numbers."""
    out = []
    for name, m in miss.items():
        o = own.get(name)
        for ch in ("p", "q"):
            x, y = m[f"later_{ch}"], (o or {}).get(f"later_{ch}", float("nan"))
            if abs(x) >= 1.0 and np.sign(y) == np.sign(x) and abs(y) >= 0.5 * abs(x):
                out.append(f"{name} misses the reclose's {ch.upper()} after its first "
                           f"{FIRST_CYCLES} cycles by {x:+.1f} % of P0 on average, and its fit "
                           f"of the first fault misses that fault's own by {y:+.1f}: the "
                           "model's form, not the reclose")  # fmt: skip
    far = [(n, m) for n, m in miss.items() if m.get("beyond_rows")
           and abs(m["beyond_q"]) >= abs(m["within_q"]) + 1.0]  # fmt: skip
    if far:
        n, m = far[0]
        out.append(f"{m['beyond_rows']} of the reclose's rows lie further after its clearing "
                   "than the first fault's record reaches, a stretch no fit of the first "
                   f"fault saw: there {n} misses Q by {m['beyond_q']:+.1f} % of P0 on average, "
                   f"against {m['within_q']:+.1f} on the later rows before it")  # fmt: skip
    if apart and apart["steady_p"] >= 0.5:
        out.append(f"before the reclose, with the voltage steady, P moves by "
                   f"{apart['steady_p']:.1f} % of P0 (RMS about its mean): no load model "
                   "driven by the voltage predicts that, and the reclose's RMS of P cannot "
                   "fall far under it")  # fmt: skip
        out.append(f"the two faults' own responses (each from its pre-fault level, aligned at "
                   f"the clearing, {apart['rows']} rows from the {FIRST_CYCLES + 1}th cycle "
                   f"after it on) differ by {apart['rms_p']:.1f} % of "
                   f"P0 in P (mean {apart['mean_p']:+.1f}) and {apart['rms_q']:.1f} % in Q "
                   f"(mean {apart['mean_q']:+.1f}), while their voltages differ by "
                   f"{apart['rms_v']:.2f} % there: a difference a model fitted on the first "
                   "fault cannot know")  # fmt: skip
    if len(h2) >= 2:
        (b0, a0), (b1, a1) = h2[:2]
        if a1 > INRUSH_H2 and a1 > 2 * b1:
            out.append(f"after the reclose the current holds a 2nd harmonic of {a1:.1%} of its "
                       f"fundamental ({b1:.1%} before it; {a0:.1%} after the first fault): a "
                       "transformer's magnetising inrush, whose fundamental is reactive and "
                       "which no load model describes")  # fmt: skip
    return out


def run(
    *, quick: bool = True, seed: int = 0, record: str | None = None, smoke: bool = False
) -> PhysicalStudy:
    """Fit, compare and predict on both transformers (see the module docstring)."""
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.choice import compare_models
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.models.dynamic import dynamic_model
    from loadbayes.models.zip_motor import CompositeModel

    cfg = find_record(record)
    if cfg is None:
        return PhysicalStudy(pd.DataFrame(), record=None)
    draws, burn = (1000, 500) if smoke else QUICK if quick else FULL  # smoke: a pipeline check
    sampler = SamplerSettings(draws=draws, burn=burn, chains=2, seed=seed)
    cols, choice, words, seconds = {}, {}, {}, {}
    for bay, short in BAYS:
        t0 = time.perf_counter()
        events, flags, info = events_of(cfg, bay)
        f = info["f_hz"]
        parts = dict(f_hz=f, window_s=1.0 / f)
        models = [CompositeModel(f_hz=f), dynamic_model("slm", **parts),
                  dynamic_model("cmld-lite", **parts)]  # fmt: skip
        straddle = [fl["straddle"] for fl in flags[:2]]
        ch = compare_models(models, events[:2], sampler=sampler, exclude=straddle)
        col: dict[str, str] = {}
        for name in ("zip+motor", "slm", "cmld-lite"):
            post = ch.fits[name][1].posterior  # fitted on the first fault (the second left out)
            pred = ch.held_out[name][1]  # the reclose, predicted
            d = post.draws
            if name == "zip+motor":
                col[f"{name}: f_m"] = _ci(d["f_m"])
                col[f"{name}: static P shares a1, a2, a3"] = ", ".join(
                    f"{np.median(d[a]):.2f}" for a in ("a1", "a2", "a3"))  # fmt: skip
                col[f"{name}: Rs, H (motor base)"] = f"{_ci(d['rs'])}; {_ci(d['h_s'])}"
            else:
                col[f"{name}: three-phase motors' share"] = _ci(d["f_motors"])
                col[f"{name}: static share"] = _ci(d["f_s"])
                for extra in ("f_d", "f_el"):
                    if extra in d:
                        col[f"{name}: {extra}"] = _ci(d[extra])
                tags = [t for t in ("_a", "_b", "") if f"rs{t}" in d]
                for t in tags:
                    both = f"{_ci(d['rs' + t])}; {_ci(d['h_s' + t])}"
                    col[f"{name}: Rs{t}, H{t} (motor base)"] = both
                col[f"{name}: feeder X (load base)"] = _ci(d["x_fd"])
                words[f"{short} {name}"] = list(post.warnings)
            col[f"{name}: reclose RMS P, Q (% of P0)"] = (
                f"{100 * pred.rms_p:.1f}, {100 * pred.rms_q:.1f}")  # fmt: skip
            col[f"{name}: reclose in the 95% band of a new observation (P, Q)"] = (
                f"{pred.coverage_p:.0%}, {pred.coverage_q:.0%}")  # fmt: skip
        choice[short] = ch.to_dict()
        # What the negative sequence adds: the physical model's motors' total rating with it
        # (the fit above) and without it, on the first fault.
        best = next(r["model"] for r in ch.table if r["model"] in ("slm", "cmld-lite"))
        with_ns = ch.fits[best][1].posterior
        model = next(m for m in models if m.name == best)
        off = dynamic_model(best, negative_sequence="off", **parts)
        first = replace(events[0], straddle=np.asarray(straddle[0], bool))  # as compare_models
        without = fit_composite(off, [first], sampler=sampler).posterior
        used = with_ns.extra_json["parts"]["negative_sequence"]["summary"]
        col[f"{best}: motors' rating, with V2 and I2"] = _ci(_rating(with_ns))
        col[f"{best}: motors' rating, without"] = _ci(_rating(without))
        words[f"{short} negative sequence"] = [used, f"model {model.name}"]
        # Where the reclose is missed, and what the record says no model could know.
        t_fault, t_clear = _steps(flags[1]["straddle"], events[1].t)
        reach = float(events[0].t[-1]) - _steps(straddle[0], events[0].t)[1]
        best_first = [r["model"] for r in ch.table]
        miss = {n: reclose_miss(ch.held_out[n][1], t_fault, t_clear, f, reach) for n in best_first}
        replays = {n: _replay(models, n, ch.fits[n][1].posterior, events[0], straddle[0], seed)
                   for n in ch.held_out}  # fmt: skip
        own = {n: reclose_miss(r, *_steps(straddle[0], events[0].t), f)
               for n, r in replays.items()}  # fmt: skip
        form = {n: held_out_error(r, ch.held_out[n][1], _steps(straddle[0], events[0].t)[0])
                for n, r in replays.items()}  # fmt: skip
        for n, m in miss.items():
            col[f"{n}: reclose miss (% of P0)"] = (
                f"before the fault P {m['before_p']:.1f}; first {FIRST_CYCLES} cycles after "
                f"P {m['first_p']:.1f}, Q {m['first_q']:.1f}; later, mean P "
                f"{m['later_p']:+.1f}, Q {m['later_q']:+.1f} "
                f"(Q band {m['later_cover_q']:.0%})")  # fmt: skip
            if m["beyond_rows"]:
                col[f"{n}: reclose later, within the first fault's reach and past it, mean Q"] = (
                    f"{m['within_q']:+.1f}; {m['beyond_q']:+.1f} ({m['beyond_rows']} rows past "
                    f"{reach:.2f} s)")  # fmt: skip
            col.update(form_rows(n, form[n], ch.held_out[n][1].scale))
            o = own[n]
            col[f"{n}: first fault, its own fit: later, mean P, Q (% of P0)"] = (
                f"{o['later_p']:+.1f}, {o['later_q']:+.1f}")  # fmt: skip
        apart = faults_apart(events, straddle, f)
        if apart:
            col["the two faults apart, RMS P, Q (% of P0)"] = (
                f"{apart['rms_p']:.1f}, {apart['rms_q']:.1f}")  # fmt: skip
        h2 = _harmonics(cfg, bay, f)
        col["current's 2nd harmonic before, after (first fault; reclose)"] = "; ".join(
            f"{b:.1%}, {a:.1%}" for b, a in h2[:2])  # fmt: skip
        words[f"{short} reclose"] = _miss_words(miss, own, apart, h2) + form_words(form)
        seconds[short] = time.perf_counter() - t0
        cols[short] = col
    table = pd.DataFrame(cols)
    settings = {"draws": draws, "burn": burn, "chains": 2, "seed": seed, "seconds": seconds}
    return PhysicalStudy(table, choice, words, settings, str(cfg))


def text_table(study: PhysicalStudy) -> str:
    """The table as aligned text."""
    if study.record is None:
        return "real record (physical models): not found"
    return study.table.to_string()


def html_section(study: PhysicalStudy) -> str:
    """The section of the report (an HTML ``<section>``)."""
    from loadbayes.studies.report import escape, table_html

    head = ['<section id="real-record-physical">',
            "<h2>The real record with loads built from parts: physical, compared, the "
            "negative sequence</h2>"]  # fmt: skip
    if study.record is None:
        return "\n".join(head + ["<p>The record was not found: this section is empty.</p>",
                                 "</section>"])  # fmt: skip
    st = study.settings
    secs = ", ".join(f"{k} {v:.0f} s" for k, v in st["seconds"].items())
    out = head + [
        f"<p>Source: {escape(SOURCE)}. Each transformer's two faults; each model fitted to "
        f"one and predicting the other from its recorded voltage alone ({st['chains']} "
        f"chains x {st['draws']} iterations, {st['burn']} burn-in, seed {st['seed']}; "
        f"{secs}). <code>slm</code> and <code>cmld-lite</code> hold every share in [0, 1] "
        "and their motors in published ranges by their priors; where the data push a motor "
        "outside the physical region (Rs above 0.1 or H below 0.05 s on its own base), the "
        "fit says so below, and such a fit is not a load to hand a planner as it is.</p>",
        table_html(study.table, caption="The first fault fitted, the reclose predicted."),
        f"<p>Where the reclose is missed (% of P0): the RMS over the rows before the fault, "
        "where every prediction is the operating point (what is left there is the load's "
        f"own movement), over the first {FIRST_CYCLES} cycles after clearing, and the mean "
        "of recorded minus predicted after them, beside the same for the first fault's own "
        "fit. Measured on the record with no model: the two faults' own responses, each "
        "from its pre-fault level and aligned at the clearing, and the currents' 2nd "
        "harmonic before and after each fault, which a transformer's magnetising inrush "
        "raises. The model error: AR(1) beside the recorder's white noise, fitted on the "
        "first fault; the reclose's band with it and its mean square split. What these say "
        "is listed below.</p>",
    ]
    for short, ch in study.choice.items():
        out.append(f"<p><b>Transformer {escape(short)}</b>: {escape(ch['words'])}.</p>")
        rows = pd.DataFrame(ch["table"]).set_index("model")
        out.append(table_html(rows.round(4), caption=f"{short}: leave-one-fault-out scores"))
    out.append("<ul>")
    for key, lines in study.words.items():
        for line in lines:
            out.append(f"<li>{escape(key)}: {escape(line)}</li>")
    out.append("</ul></section>")
    return "\n".join(out)
