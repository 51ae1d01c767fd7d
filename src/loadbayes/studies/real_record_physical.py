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
- what the negative sequence adds: the motors' total rating with and without it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.studies.real_record import BAYS, SOURCE, events_of, find_record

__all__ = ["PhysicalStudy", "html_section", "run", "text_table"]

#: Iterations (burn-in) per chain, quick and full.
QUICK, FULL = (4000, 2000), (24000, 6000)


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


def run(*, quick: bool = True, seed: int = 0, record: str | None = None) -> PhysicalStudy:
    """Fit, compare and predict on both transformers (see the module docstring)."""
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.choice import compare_models
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.models.dynamic import dynamic_model
    from loadbayes.models.zip_motor import CompositeModel

    cfg = find_record(record)
    if cfg is None:
        return PhysicalStudy(pd.DataFrame(), record=None)
    draws, burn = QUICK if quick else FULL
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
            col[f"{name}: reclose in the 95% band (P, Q)"] = (
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
