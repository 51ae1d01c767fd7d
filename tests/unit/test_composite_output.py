"""What a user is handed after ``fit composite``: the table, the static part, the figure.

The draws are written in the test where it matters (no fit): the table's units and
meanings, and the static part's determined combinations, are checked against values
known by construction; one short fit checks what the result keeps for the report.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.fit.composite.identifiability import static_identifiability
from loadbayes.fit.composite.predictive import events_of, fault_times, predictive_band
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import THETA_NAMES
from loadbayes.plots.composite import plot_composite_fit
from loadbayes.posterior import Posterior
from loadbayes.report.composite_names import QUANTITIES, describe
from loadbayes.report.composite_table import (
    TABLE_WIDTH,
    composite_table,
    run_lines,
    static_lines,
)

#: Every name a composite fit draws (event 0 plain, event 1 suffixed, two steps each).
EVENT = ("p0", "q0", "v0", "a1", "a2", "a3", "a4", "a5", "a6", "f_m", "mva_m", "q_c")
MOTOR = ("rs", "xs", "xm", "rr", "xr", "h_s", "a", "b", "c", "t0", "x_prime", "x_open",
         "t_prime_s", "f_hz", "tau_p", "tau_q", "nu_p", "nu_q", *THETA_NAMES)  # fmt: skip
ALL = [*EVENT, *(f"{n}_e1" for n in EVENT), *MOTOR, "t_step0", "t_step1", "t_step0_e1"]


def _event(v_sag: float = 0.7, name: str = "sag.csv") -> EventRecord:
    t = np.arange(0.0, 2.0, 1 / 60)
    v = np.where((t >= 0.5) & (t < 0.7), v_sag, 1.0)
    return EventRecord(t, v, np.ones_like(t), 0.3 * np.ones_like(t), None, name)


def test_every_named_draw_has_a_unit_and_a_meaning():
    for name in ALL:
        unit, words = describe(name)
        assert unit and words, name
    assert describe("t_prime_s")[0] == "s"
    assert describe("x_prime")[0] == "p.u. motor base"
    assert describe("p0_e1") == (QUANTITIES["p0"][0], QUANTITIES["p0"][1] + ", event 2")
    assert describe("t_step1_e1")[1].startswith("instant of voltage step 2")
    assert describe("not_a_name") == ("", "")


def _posterior(rng, n_events=2) -> Posterior:
    names = [n for n in ALL if n.endswith("_e1") <= (n_events > 1)]
    draws = {n: rng.normal(1.0, 0.1, (2, 100)) for n in names}
    return Posterior(draws, model="composite", method="mwg-adaptive-metropolis")


def test_the_table_has_a_unit_on_every_row_and_fits_its_width():
    post = _posterior(np.random.default_rng(0))
    text = composite_table(post, post.summary(), n_events=2)
    lines = text.splitlines()
    assert lines[0].startswith("composite posterior, mwg-adaptive-metropolis, 2 event(s)")
    assert "95% low" in lines[1] and "R-hat" in lines[1]
    rows = {ln.split()[0]: ln for ln in lines[2:]}
    for name in ("p0", "f_m", "a1", "p0_e1", "f_m_e1", "t_step0", "t_step0_e1", "t_prime_s"):
        assert name in rows, name
    for name, line in rows.items():
        assert len(line) <= TABLE_WIDTH, line
        unit = describe(name)[0]
        assert line.endswith(f"[{unit}]"), line  # the unit is kept whole when cut
    assert rows["f_m_e1"].endswith("motor's share of p0, event 2 [-]")
    assert rows["t_prime_s"].endswith("transient time constant T' [s]")
    # The sampled log-parameters and the precisions are in the JSON, not the table.
    assert "log_rs" not in rows and "tau_p" not in rows


def _ridge_draws(rng, x, n=4000, sd=0.5):
    # Shares that trade off exactly along the line one sag to x v0 cannot resolve: the
    # static P at x is fixed (0.3 x^2 + 0.3 x + 0.4), the slope 2 a1 + a2 is not.
    s = rng.normal(0.0, sd, (2, n // 2))
    a1, a2 = 0.3 + s, 0.3 - (1 + x) * s
    return {"a1": a1, "a2": a2, "a3": 1 - a1 - a2,
            "a4": 0.4 + 0.01 * rng.standard_normal(s.shape),
            "a5": 0.3 + 0.01 * rng.standard_normal(s.shape),
            "a6": 0.3 + 0.01 * rng.standard_normal(s.shape),
            "p0": np.ones_like(s), "q0": 0.3 * np.ones_like(s),
            "f_m": 0.5 * np.ones_like(s)}  # fmt: skip


def test_undetermined_shares_are_said_with_what_the_sag_does_fix():
    x = 0.7
    out = static_identifiability(_ridge_draws(np.random.default_rng(1), x), [_event(x)])
    ev = out["events"][0]
    assert ev["v_sag_over_v0"] == pytest.approx(x)
    p, q = ev["p"], ev["q"]
    assert not p["determined"] and p["correlation"] < -0.99
    assert q["determined"]  # the Q shares were drawn tight and independent
    slope, level = p["combinations"]
    assert slope["name"] == "2 a1 + a2"
    # The level at the sag is exact by construction; the slope's sd is (1 - x) sd(s).
    assert level["mean"] == pytest.approx(0.3 * x * x + 0.3 * x + 0.4, abs=1e-12)
    assert level["high"] - level["low"] < 1e-9
    assert slope["sd"] == pytest.approx((1 - x) * 0.5, rel=0.05)
    assert slope["low"] < 0.9 < slope["high"]
    assert "not determined for P of sag.csv" in out["warning"]
    assert "Q of" not in out["warning"]
    lines = static_lines(out)
    assert lines[0].startswith("static P of event 1 (sag.csv): the shares a1, a2, a3 are not")
    assert lines[1].startswith("  2 a1 + a2 = ") and "dP/dV" in lines[1]
    assert "static P at the sag's voltage 0.700 v0" in lines[2]


def test_determined_shares_give_no_warning():
    rng = np.random.default_rng(2)
    d = _ridge_draws(rng, 0.7, sd=0.01)
    # Independent, tight shares: nothing to say.
    d["a1"] = 0.3 + 0.01 * rng.standard_normal(d["a1"].shape)
    d["a2"] = 0.3 + 0.01 * rng.standard_normal(d["a1"].shape)
    d["a3"] = 1 - d["a1"] - d["a2"]
    out = static_identifiability(d, [_event()])
    assert out["warning"] is None and static_lines(out) == []
    assert out["events"][0]["p"]["determined"] and out["events"][0]["q"]["determined"]


def test_fault_times_find_a_step_and_both_ends_of_a_ramp():
    # A step at 0.5 s (between samples), a hold, then a 0.2 s ramp back: three places
    # to zoom on, with no fitted steps to go by (noise on V does not add any).
    fs = 60
    t = np.arange(0.0, 2.0, 1 / fs)
    v = np.interp(t, [0, 0.5, 0.5 + 1e-9, 0.7, 0.9, 2.0], [1, 1, 0.7, 0.7, 1, 1])
    v = v + np.random.default_rng(0).normal(0, 5e-4, t.size)
    ev = EventRecord(t, v, np.ones_like(t), np.ones_like(t), None, "ramp")
    post = Posterior({"p0": np.ones((1, 4))}, model="composite", method="x")
    (found,) = fault_times(post, [ev])
    assert len(found) == 3, found
    for got, want in zip(found, (0.5, 0.7, 0.9), strict=True):
        assert abs(got - want) <= 1.5 / fs, (got, want)


def test_a_fit_keeps_its_recordings_and_the_figure_draws_them(tmp_path):
    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite import fit_composite
    from loadbayes.models.zip_motor import CompositeModel
    from loadbayes.plots.fit import pyplot

    ev = simulate_event("small_industrial", depth=0.3, t_end_s=1.5, fs=30, seed=0)[0]
    run = SamplerSettings(draws=120, burn=60, chains=1, seed=0)
    fit = fit_composite(CompositeModel(window_s=0), [ev], sampler=run)
    fit.posterior.to_netcdf(tmp_path / "c.nc")
    back = Posterior.from_netcdf(tmp_path / "c.nc")
    (kept,) = events_of(back)
    for ch in ("t", "v", "p", "q"):
        np.testing.assert_array_equal(getattr(kept, ch), getattr(ev, ch))
    assert kept.name == ev.name
    assert back.extra_json["identifiability"]["static_part"]["events"]
    (band,) = predictive_band(back, [kept])
    for ch in ("p", "q"):  # the predictive band holds the model's band and more
        assert np.all(band[f"{ch}_pred_lo"] <= band[f"{ch}_lo"] + 1e-12)
        assert np.all(band[f"{ch}_pred_hi"] >= band[f"{ch}_hi"] - 1e-12)
        assert np.mean(band[f"{ch}_pred_hi"] - band[f"{ch}_pred_lo"]) > np.mean(
            band[f"{ch}_hi"] - band[f"{ch}_lo"]
        )
    faults = fault_times(back, [kept])
    fig = plot_composite_fit(back, [kept], [band], faults, notes=run_lines(back))
    try:
        n_zoom = len(faults[0])
        assert n_zoom >= 2  # the sag's edge and its recovery
        assert len(fig.axes) == 3 * (1 + n_zoom) + 3
        labels = {ax.get_ylabel() for ax in fig.axes}
        assert {"V (p.u.)", "P (p.u. system base)", "Q (p.u. system base)"} <= labels
        assert all(ax.get_xlabel() for ax in fig.axes[-3:])
        zooms = [ax for ax in fig.axes if ax.get_title().startswith("zoom: fault at")]
        assert len(zooms) == n_zoom
        (notes,) = fig.texts  # the settings used, under the panels
        assert "seed 0" in notes.get_text() and "1 chains x 120 iterations" in notes.get_text()
    finally:
        pyplot().close(fig)


def test_the_settings_lines_show_the_bases_when_the_settings_hold_them():
    st = {"files": ["a.csv", "b.csv"], "v_base_kv": 11.0, "s_base_mva": 5.0, "f_hz": 50.0,
          "draws": 100, "burn": 50, "thin": 1, "seed": 3, "torque": [1.0, 0.0, 0.0]}  # fmt: skip
    post = Posterior({"p0": np.ones((2, 5))}, model="composite", method="m", settings=st)
    lines = run_lines(post)
    assert lines[0] == "data: a.csv, b.csv"
    assert lines[1] == "bases: v_base_kv = 11, s_base_mva = 5, f = 50 Hz"
    assert lines[2].startswith("run: 2 chains x 100 iterations (50 burn-in, thin 1); seed 3")
    # Without bases in the settings, no bases line but the frequency.
    del st["v_base_kv"], st["s_base_mva"]
    post = Posterior({"p0": np.ones((2, 5))}, model="composite", method="m", settings=st)
    assert run_lines(post)[1] == "bases: f = 50 Hz"
