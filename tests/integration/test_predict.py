"""``loadbayes predict``: a fit of parts played through a fault it has not shown.

The fast tests fit ``cmld-lite`` (few draws: the mechanics, not the numbers) to one
15 % sag from the tests' own SciPy feeder simulator (``tests/feeder_generator.py``) and
check that the command and ``loadbayes.predict`` give the same numbers, that a deep sag
is said to extrapolate (naming the priors that decide, citing their source) and a
shallow one is not, that a user's prior moves the answer, and that bad input is refused
in one line (exit 2) with nothing overwritten.

The GridDyn checks (issue 37; skipped without the GridDyn environment) fit cmld-lite to
GridDyn's shallow and medium CMLD faults (13 %, 25 %) and predict the deep one (46 %,
where GridDyn's motor D stalls) from its recorded voltage, then again from the shallow
fault alone.
"""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cases.griddyn import cases
from loadbayes.cli import main
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.fit.composite.predict import PRIOR_SOURCE, predict
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def fitted(cmld_lite_nc):
    """A cmld-lite fit of one 15 % sag (SciPy simulator), its NetCDF (tests/conftest.py)."""
    return cmld_lite_nc


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_cli_and_python_give_the_same_numbers(fitted, tmp_path):
    out = tmp_path / "p.json"
    r = _run("predict", fitted, "--sag", 0.45, "--duration", 0.1, "--draws", 30, "--json", out,
             "--plot", tmp_path / "p.png")  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "motor D stalls with probability" in r.output
    doc = json.loads(out.read_text())
    py = predict(fitted, sag=0.45, duration=0.1, draws=30).to_dict()
    assert doc["stall"] == py["stall"]
    assert doc["recovery"] == py["recovery"]
    assert doc["band"]["p_hi"] == py["band"]["p_hi"]
    assert (tmp_path / "p.png").stat().st_size > 0
    import loadbayes

    assert loadbayes.predict is predict


def test_a_deep_sag_is_said_to_extrapolate_and_names_the_priors(fitted):
    pred = predict(fitted, sag=0.45, duration=0.1, draws=30)
    ex = pred.extrapolation
    assert ex["extrapolated"]
    assert {"vstall", "tstall", "vd1", "vd2"} <= set(ex["decided_by_prior"])
    assert "deeper than any fitted event" in ex["message"]
    assert pred.thresholds["vstall"]["source"] == PRIOR_SOURCE
    assert "WECC" in PRIOR_SOURCE and "PNNL-17796" in PRIOR_SOURCE
    # Each interval is an interval: a probability in its Jeffreys interval.
    lo, hi = pred.stall["interval"]
    assert 0 <= lo <= pred.stall["probability"] <= hi <= 1
    # A sag inside what the fit saw (shallower, as short) is not flagged, and no
    # threshold decides it (0.9 p.u. is above every threshold's prior range).
    small = predict(fitted, sag=0.1, duration=0.1, draws=30)
    assert not small.extrapolation["extrapolated"]
    assert small.extrapolation["decided_by_prior"] == []
    assert small.stall["probability"] == 0.0


def test_every_fit_records_what_its_events_covered(fitted):
    # Issue 37: the fit itself keeps the voltage range and durations its events span.
    cover = Posterior.from_netcdf(fitted).settings["covered"]
    assert cover["depth_max"] == pytest.approx(0.15, abs=0.02)  # the 15 % sag fitted
    assert 0.1 <= cover["duration_max_s"] <= 0.16
    assert cover["events"][0]["event"] == "sag 0.15"


def test_a_users_prior_moves_the_stall_and_is_named(fitted):
    base = predict(fitted, sag=0.45, duration=0.1, draws=40)
    low = predict(fitted, sag=0.45, duration=0.1, draws=40, prior=["vstall=0.3,0.01"])
    assert base.stall["probability"] > 0.5  # the feeder end near 0.5 p.u., Vstall ~ 0.6
    assert low.stall["probability"] == 0.0  # a stall voltage of 0.3 p.u. is never reached
    assert low.thresholds["vstall"]["source"] == "given by the user (--prior)"


def test_a_sweep_gives_one_answer_per_depth(fitted, tmp_path):
    out = tmp_path / "s.json"
    r = _run("predict", fitted, "--sweep", "0.1:0.5:0.2", "--duration", 0.1, "--draws", 20,
             "--json", out, "--plot", tmp_path / "s.png")  # fmt: skip
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    sweep = doc["sweep"]
    assert [s["depth"] for s in sweep] == [0.1, 0.3, 0.5]
    stall = [s["stall"]["probability"] for s in sweep]
    assert stall[0] == 0.0 and stall[-1] > stall[0]
    # The planner's summary: the crossings of 0.025, 0.5, 0.975 (stall_depth's own
    # numbers are tested by hand in tests/unit/test_stall_depth.py), in words on stdout.
    sd = doc["stall_depth"]
    assert set(sd) == {"depth", "interval", "levels", "message"}
    assert sd["levels"] == pytest.approx([0.025, 0.5, 0.975])
    assert sd["interval"][0] is None or 0.1 < sd["interval"][0] <= 0.5
    assert sd["message"] in r.output


@pytest.mark.parametrize(
    "args, words",
    [
        ((), "give the fault as one of"),
        (("--sag", 0.4), "--sag needs --duration"),
        (("--sag", 0.4, "--duration", 0.1, "--sweep", "0.1:0.2:0.1"), "given: --sag, --sweep"),
        (("--sag", 1.4, "--duration", 0.1), "--sag 1.4: a depth between 0 and 1"),
        (("--sag", 0.4, "--duration", 0.1, "--prior", "vstal=0.5,0.1"), "one of vstall"),
        (("--sweep", "0.1-0.5", "--duration", 0.1), "START:STOP:STEP"),
    ],
)
def test_bad_requests_are_one_line_exit_2(fitted, args, words):
    r = _run("predict", fitted, *args)
    assert r.exit_code == 2, r.output
    assert words in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_a_bad_profile_names_the_file_column_and_row(fitted, tmp_path):
    bad = tmp_path / "v.csv"
    pd.DataFrame({"t_s": np.arange(20) / 60, "v": [1.0] * 7 + ["x"] + [0.5] * 12}).to_csv(
        bad, index=False
    )
    r = _run("predict", fitted, "--voltage", bad)
    assert r.exit_code == 2
    assert "v.csv" in r.output and "'v'" in r.output and "row 9" in r.output


def test_a_profile_with_v2_brakes_the_motors(fitted, tmp_path):
    # A 20 % sag with |V2| 0.15 (a phase-to-ground fault's negative sequence): the same
    # draws play it with the motors braked (models/motor_kernel.brake_torque), so the
    # band's P during the fault moves from the same profile without V2's; v2_re alone is
    # refused in one line naming the file and the column.
    t = np.arange(0.0, 0.8, 1 / 120)
    on = (t >= 0.1) & (t < 0.25)
    frame = pd.DataFrame({"t_s": t, "v": np.where(on, 0.8, 1.0)})
    plain, neg, half = tmp_path / "plain.csv", tmp_path / "neg.csv", tmp_path / "half.csv"
    frame.to_csv(plain, index=False)
    frame.assign(v2_re=np.where(on, -0.15, 0.0), v2_im=0.0).to_csv(neg, index=False)
    frame.assign(v2_re=0.0).to_csv(half, index=False)
    a = predict(fitted, voltage=plain, draws=30).to_dict()
    b = predict(fitted, voltage=neg, draws=30).to_dict()
    assert "v2_max" not in a["fault"] and b["fault"]["v2_max"] == pytest.approx(0.15)
    gap = np.abs(np.asarray(a["band"]["p_mid"]) - np.asarray(b["band"]["p_mid"]))
    assert gap[on].max() > 1e-3 and gap[t < 0.1].max() < 1e-9, gap.max()
    r = _run("predict", fitted, "--voltage", half)
    assert r.exit_code == 2 and "half.csv" in r.output and "'v2_re' without 'v2_im'" in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_nothing_is_overwritten_without_force(fitted, tmp_path):
    out = tmp_path / "p.json"
    out.write_text("keep")
    r = _run("predict", fitted, "--sag", 0.3, "--duration", 0.1, "--json", out)
    assert r.exit_code == 2 and "--force" in r.output
    assert out.read_text() == "keep"


def test_a_fit_predict_cannot_play_is_refused_in_one_line():
    # A zip+motor fit is played (tests/integration/test_predict_zm.py); one without the
    # recordings of its events has no operating point, and another model is refused.
    post = Posterior({"p0": np.ones((1, 5))}, model="composite", method="gibbs",
                     settings={"model": "zip+motor"})  # fmt: skip
    with pytest.raises(ValueError, match="keeps no recordings of its events"):
        predict(post, sag=0.4, duration=0.1)
    post.settings["model"] = "exp"
    with pytest.raises(ValueError, match="a exp fit: predict plays zip\\+motor, slm, cmld-lite"):
        predict(post, sag=0.4, duration=0.1)


# -- GridDyn: fit shallow + medium, predict the deep fault -----------------------------

_REASON = cases.skip_reason()


@pytest.fixture(scope="module")
def griddyn(tmp_path_factory):
    if _REASON is not None:
        pytest.skip(_REASON)
    from loadbayes.cases.griddyn.events import griddyn_events

    frames, _ = griddyn_events(depths=(0.13, 0.25, 0.46), seed_noise=0)
    evs = [EventRecord(f.t_s.to_numpy(), f.v.to_numpy(), f.p.to_numpy(), f.q.to_numpy(),
                       f.angle_rad.to_numpy(), f"griddyn {k}")
           for k, f in enumerate(frames)]  # fmt: skip
    model = dynamic_model("cmld-lite", f_hz=60.0)
    sampler = SamplerSettings(draws=2000, burn=1000, chains=2, seed=7)
    both = fit_composite(model, evs[:2], sampler=sampler).posterior
    shallow = fit_composite(model, evs[:1], sampler=sampler).posterior
    deep = tmp_path_factory.mktemp("griddyn") / "deep.csv"
    frames[2][["t_s", "v", "angle_rad"]].to_csv(deep, index=False)
    return both, shallow, deep, frames[2]


@pytest.fixture(scope="module")
def griddyn_deep(griddyn):
    """The deep fault played by each fit, 300 draws, seed 0: computed once, read by the
    three tests below (each asked the same ``predict`` calls of its own before)."""
    both, shallow, deep, _ = griddyn
    return {"both": predict(both, voltage=deep, draws=300),
            "shallow": predict(shallow, voltage=deep, draws=300)}  # fmt: skip


def _inside(pred, frame):
    b = pred.band
    x = {ch: frame[ch].to_numpy() for ch in ("p", "q")}
    return {ch: float(np.mean((x[ch] >= b[f"{ch}_pred_lo"]) & (x[ch] <= b[f"{ch}_pred_hi"])))
            for ch in ("p", "q")}  # fmt: skip


@pytest.mark.statistical
def test_griddyn_deep_fault_predicted_from_shallow_and_medium(griddyn, griddyn_deep):
    """Fixed seeds (fit 7, prediction 0): deterministic; the numbers are reported."""
    frame = griddyn[3]
    pred = griddyn_deep["both"]
    inside = _inside(pred, frame)
    print("inside the 95% band:", inside, "stall:", pred.stall)
    assert pred.extrapolation["extrapolated"]  # 46 % against the deepest fitted 25 %
    assert pred.stall["probability"] > 0.5
    assert inside["p"] >= 0.8 and inside["q"] >= 0.8, inside
    # After the stall the answer rests on motor D's restart constants, not the data.
    assert pred.extrapolation["after_stall"]["assumed"] == {"frst": 0.2, "vrst": 0.95,
                                                            "trst": 0.3}  # fmt: skip
    assert "rest on an assumption" in pred.extrapolation["message"]


@pytest.mark.statistical
def test_griddyn_from_the_shallow_fault_alone_is_flagged(griddyn, griddyn_deep):
    frame = griddyn[3]
    b = griddyn_deep["shallow"]
    print("from the shallow fault alone: inside", _inside(b, frame), "stall:", b.stall)
    assert b.extrapolation["extrapolated"]
    assert "deepest 13%" in b.extrapolation["message"]
    assert {"vstall", "tstall"} <= set(b.extrapolation["decided_by_prior"])


@pytest.mark.statistical
@pytest.mark.xfail(strict=True, reason="measured (seeds 7, 0; thresholds sampled; with the shares' "
                   "own steps): the band from the shallow fault alone is narrower (mean width "
                   "of P's 95% band 0.97 p.u. against 1.18 from shallow + medium; without those "
                   "steps 0.64 against 1.09) and covers as much of GridDyn's deep fault (P 99% "
                   "against 98%). The width during the stall scales with motor D's share: "
                   "GridDyn's is 0.15; the shallow fault alone gives 0.125 [0.010, 0.376], "
                   "shallow + medium 0.281 [0.026, 0.464], both covering it, and the stall "
                   "probability 0.76 against 0.97. A wider band from less data holds on average "
                   "over data sets (the law of total variance), not in each: here the medium "
                   "fault moved motor D's share up within its interval, and the band with it. "
                   "The extrapolation is flagged all the same")  # fmt: skip
def test_griddyn_band_from_the_shallow_fault_alone_is_wider(griddyn_deep):
    widths = []
    for key in ("both", "shallow"):
        b = griddyn_deep[key].band
        widths.append(float(np.mean(b["p_pred_hi"] - b["p_pred_lo"])))
    print("mean width of P's band, shallow+medium then shallow:", widths)
    assert widths[1] > widths[0]


def _real():
    for folder in Path(__file__).resolve().parents:
        if (folder / "shared" / "real" / "xtz.cfg").is_file():
            return folder / "shared" / "real" / "xtz.cfg"
    return None


@pytest.mark.statistical
@pytest.mark.skipif(_real() is None, reason="shared/real is not beside the repository")
@pytest.mark.skipif(__import__("os").environ.get("LOADBAYES_VALIDATE") != "1",
                    reason="an slm fit of the real record (10-20 s): make validate")  # fmt: skip
def test_the_real_record_at_a_50_percent_sag_says_it_extrapolates_from_13():
    from loadbayes.measurements.events import events_from_arrays
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.record import phasor_rows, record_table

    w = read_comtrade(_real(), bay="1号主变")
    rows = phasor_rows(record_table(w, per_cycle=4).columns)
    m = rows["segment"] == 0
    cols = {"t": rows["t_s"][m] - rows["t_s"][m][0], "v": rows["v"][m], "p": rows["p"][m],
            "q": rows["q"][m], "angle": rows["angle_rad"][m]}  # fmt: skip
    names = {k: k for k in ("t", "v", "p", "q", "f", "angle", "event")}
    (ev,) = events_from_arrays(cols, np.arange(1, m.sum() + 1), path="real", names=names,
                               f_hz=w.f_nominal)  # fmt: skip
    run = SamplerSettings(draws=2000, burn=1000, chains=2, seed=0)
    post = fit_composite(dynamic_model("slm", f_hz=w.f_nominal), [ev], sampler=run).posterior
    pred = predict(post, sag=0.5, duration=0.1, draws=200)
    msg = pred.extrapolation["message"]
    print(msg)
    assert pred.extrapolation["extrapolated"]
    assert "deepest 13%" in msg or "deepest 12%" in msg
    assert "has no motor D" in msg  # slm: what a stall would do cannot appear
