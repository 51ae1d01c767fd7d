"""The composite fit's guards: units, run settings, steady start, frequency, corrupt cells.

Every check refuses (or warns) before any sampling, in one line naming the file and the
column (and the row where there is one), from Python as from the CLI.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

from loadbayes.core.parallel import ChainsStopped, check_stop, clear_stop, request_stop
from loadbayes.core.parallel import run_chains as run_chains_
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite import fit_composite
from loadbayes.fit.composite.checks import check_run, start_warnings
from loadbayes.io.errors import DataError, OptionError
from loadbayes.measurements.events import events_from_arrays
from loadbayes.measurements.record import EventRecord, check_units
from loadbayes.models.zip_motor import CompositeModel

NAMES = {"t": "t_s", "v": "v", "p": "p", "q": "q", "f": "f", "angle": "angle_rad", "event": "e"}


def _sag(fs: float = 60.0, t_end: float = 3.0, depth: float = 0.3, seed: int = 0) -> dict:
    # A static load through a 0.2 s sag (written here, not the package's simulator): the
    # guards look at levels and timing, not at the motor.
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, t_end, 1.0 / fs)
    v = np.where((t >= 0.5) & (t < 0.7), 1.0 - depth, 1.0) + rng.normal(0, 1e-4, t.size)
    p = 0.6 * v**2 + 0.4 + rng.normal(0, 1e-3, t.size)
    q = 0.3 * v**2 + rng.normal(0, 1e-3, t.size)
    return {"t": t, "v": v, "p": p, "q": q}


def _events(cols, **kw):
    rows = np.arange(1, cols["t"].size + 1)
    return events_from_arrays(cols, rows, path="sag.csv", names=NAMES, **kw)


def _record(cols, name="sag.csv"):
    return EventRecord(cols["t"], cols["v"], cols["p"], cols["q"], None, name)


def test_kv_and_mw_are_refused_with_the_option_that_fixes_them(monkeypatch):
    cols = _sag()
    ev = _record({**cols, "v": 11 * cols["v"], "p": 5 * cols["p"], "q": 5 * cols["q"]})
    with pytest.raises(DataError, match=r"sag.csv: column 'v': V / V0 has median 11.*--v-base"):
        check_units([ev])
    assert "--accept-units" in check_units([ev], accept_units=True)[0]
    # MW alone is the base symmetry of the estimated p0, q0: accepted.
    assert check_units([_record({**cols, "p": 5 * cols["p"], "q": 5 * cols["q"]})]) == []
    # Python refuses before any work, as the CLI does (issue 21: it was a traceback): the
    # NLS start and the sampler are never entered (pinned by what ran, not by a time).
    from loadbayes.fit.composite import driver

    def work(*args, **kwargs):
        raise AssertionError("the fit began its work before refusing the units")

    monkeypatch.setattr(driver, "nls", work)
    monkeypatch.setattr(driver, "sample", work)
    with pytest.raises(DataError, match="not per unit"):
        fit_composite(CompositeModel(window_s=0), [ev],
                      sampler=SamplerSettings(draws=200, burn=100, chains=2))  # fmt: skip


def test_a_load_that_exports_power_is_refused():
    cols = _sag()
    with pytest.raises(DataError, match=r"column 'p': P has median -0\.\d+ < 0"):
        check_units([_record({**cols, "p": -cols["p"]})])


def test_run_settings_refused_up_front():
    ok = {"f_hz": 60.0, "draws": 600, "burn": 300, "thin": 1, "seed": 0}
    check_run(**ok)
    for bad, text in (
        ({"f_hz": 1e6}, "between 10 and 1000 Hz"),
        ({"f_hz": 1e-300}, "between 10 and 1000 Hz"),
        ({"draws": 10, "burn": 9}, "keep 1 draw"),
        ({"draws": 3000, "burn": 1000, "thin": 100000}, "keep 1 draw"),
        ({"seed": -1}, "--seed -1"),
    ):
        with pytest.raises(OptionError, match=text):
            check_run(**{**ok, **bad})


def test_an_event_cut_inside_the_sag_is_said_to_start_off_steady_state():
    cols = _sag()
    assert start_warnings(_events(cols)) == []
    mid = {k: v[33:] for k, v in cols.items()}  # 0.55 s: inside the sag
    mid["t"] = mid["t"] - mid["t"][0]
    (w,) = start_warnings(_events(mid))
    assert "does not start in a steady state" in w and "inside the sag" in w


def test_a_50_hz_record_at_the_default_60_hz_is_refused():
    cols = _sag()
    with pytest.raises(DataError, match=r"column 'f'.*about 50 Hz.*--f-hz 50"):
        _events({**cols, "f": np.full(cols["t"].size, 50.0)})
    # An angle turning at 50 Hz in a frame turning at 60 Hz drifts by -2 pi 10 rad/s.
    angle = np.angle(np.exp(-2j * math.pi * 10.0 * cols["t"]))
    with pytest.raises(DataError, match=r"column 'angle_rad'.*about 50 Hz"):
        _events({**cols, "angle": angle})
    # An angle in the record's own frame (flat, with the fault's phase jumps) passes.
    jumps = np.where((cols["t"] >= 0.5) & (cols["t"] < 0.7), -0.16, 0.0)
    assert len(_events({**cols, "angle": jumps})) == 1
    # A genuine swing of the frequency (0.5 Hz) passes.
    assert len(_events({**cols, "f": 60.0 + 0.5 * np.sin(cols["t"])})) == 1


def test_a_corrupt_cell_is_located():
    cols = _sag()
    cols["p"][30] = 1e300
    with pytest.raises(DataError, match=r"sag.csv: column 'p', row 31: value 1e\+300"):
        _events(cols)


def test_the_stop_flag_ends_every_chain_at_its_next_check():
    # One chain fails at once; the other would make 3,000 checks (30 s) without the flag.
    # Pinned by how the second chain ended, not by a time: stopped at a check, and
    # ended by the time run_chains raises.
    stop, how = threading.Event(), []

    def chain(i, rng):
        if i == 0:
            raise ValueError("boom")
        try:
            for _ in range(3000):
                check_stop(stop)
                time.sleep(0.01)
            how.append("ran all its iterations")
        except ChainsStopped:
            how.append("stopped")
            raise

    gens = [np.random.default_rng(i) for i in range(2)]
    with pytest.raises(ValueError, match="boom"):
        run_chains_(chain, gens, workers=2, stop=stop)
    assert how == ["stopped"]
    # request_stop (what the CLI's signal handler calls) reaches a chain without its flag.
    request_stop()
    try:
        with pytest.raises(ChainsStopped):
            check_stop(None)
    finally:
        clear_stop()
    check_stop(None)


def test_progress_gets_the_estimate_then_every_iteration():
    class Seen:
        def __init__(self):
            self.begun, self.done, self.lock = None, 0, threading.Lock()

        def begin(self, total, seconds):
            self.begun = (total, seconds)

        def __call__(self, n):
            with self.lock:
                self.done += n

    seen = Seen()
    from loadbayes.cases.composite_sim import simulate_event

    ev, _ = simulate_event("small_industrial", depth=0.3, seed=1, t_end_s=2.0)
    model, run = CompositeModel(window_s=0), SamplerSettings(draws=120, burn=60, chains=2, seed=4)
    a = fit_composite(model, [ev], sampler=run, progress=seen)
    total, seconds = seen.begun
    assert total == 240 and 0 < seconds < 600
    assert seen.done == 240
    # Same seed, same draws: the JSON differs only in the wall times, kept under timing_s.
    b = fit_composite(model, [ev], sampler=run)
    da, db = a.posterior.to_dict(), b.posterior.to_dict()
    assert set(da["settings"].pop("timing_s")) == {"nls", "sampler"}
    db["settings"].pop("timing_s")
    assert da == db


def test_the_sampling_bar_says_the_cost_and_draws_on_a_terminal(monkeypatch, capsys):
    from loadbayes.commands import output

    monkeypatch.setattr(output, "_isatty", lambda stream: True)
    bar = output.SamplingBar(quiet=False)
    bar.begin(400, 125.0)
    drawn = bar.bar  # click's bar (it renders only on a real terminal)
    assert drawn is not None and drawn.show_eta
    for _ in range(4):
        bar(100)
    assert drawn.pos == 400
    bar.close()
    err = capsys.readouterr().err
    assert "sampling 400 iterations (all chains): about 2 min 05 s" in err
    quiet = output.SamplingBar(quiet=True)
    quiet.begin(400, 125.0)
    quiet(400)
    quiet.close()
    assert capsys.readouterr().err == ""
