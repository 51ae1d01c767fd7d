"""GridDyn's WECC composite load (CMLDBLU1) as an independent simulator (issue 36, Checks).

The cases (loadbayes.cases.griddyn) run GridDyn 0.13.0 in its own Python >= 3.13 environment,
one child process per case, cached on disk; each takes about a second. These checks
hold the harness to what GridDyn did: the pre-fault P, Q of the frames against the
power flow GridDyn initialised (and against the .raw's P), the sag depths asked for,
motor D's stall in the deep case and not in the shallow one, the same numbers on a
rerun, and the files `loadbayes fit composite` reads. No loadbayes code makes the data.
"""

import numpy as np
import pandas as pd
import pytest

from loadbayes.cases.griddyn import cases
from loadbayes.cases.griddyn.events import griddyn_events, write_events_csv

pytestmark = pytest.mark.integration

_REASON = cases.skip_reason()
needs_griddyn = pytest.mark.skipif(_REASON is not None, reason=_REASON or "")


@pytest.fixture(scope="module")
def runs():
    return {name: cases.run_case(depth=depth) for name, depth in cases.DEPTHS.items()}


def _pre(frame, truth):
    return frame[frame.t_s < truth["event"]["t_fault_s"] - 0.02]


@needs_griddyn
def test_frames_have_the_recorder_layout_and_the_depths_asked_for(runs):
    for name, (frame, truth) in runs.items():
        assert list(frame.columns) == ["t_s", "v", "angle_rad", "p", "q"]
        assert np.allclose(np.diff(frame.t_s), 1 / 60)
        asked = cases.DEPTHS[name]
        assert abs(truth["event"]["depth_measured"] - asked) < 0.005, name
        # The frame's own sag (one-cycle means, fault edges left out) agrees within 1 pt.
        t = frame.t_s
        ev = truth["event"]
        during = frame.v[(t > ev["t_fault_s"] + 0.02) & (t < ev["t_clear_s"] - 0.01)]
        sag = 1 - np.median(during) / _pre(frame, truth).v.mean()
        assert abs(sag - asked) < 0.01, (name, sag)


@needs_griddyn
def test_pre_fault_p_q_equal_the_truth(runs):
    for name, (frame, truth) in runs.items():
        pre = _pre(frame, truth)
        ev = truth["event"]
        # Steady before the fault, and equal to GridDyn's initial power flow (read
        # from its link objects, not from the time series) within 0.5%.
        assert pre.p.std() < 1e-6 and pre.q.std() < 1e-6
        assert pre.p.mean() == pytest.approx(ev["p0"], rel=0.005), name
        assert pre.q.mean() == pytest.approx(ev["q0"], rel=0.005), name
        # The CMLD's one-pass initialisation keeps P within 3% of the .raw's load.
        p_raw = truth["load_mw_raw"] / truth["s_base_mva"]
        assert pre.p.mean() == pytest.approx(p_raw, rel=0.03), name
        # The composite's own P at the feeder end plus the series losses is the bus P.
        start = ev["initial_state"]
        p_end = start["loads"][cases.CMLD_LOAD][0]
        losses = sum(
            start["links"][k][0] + start["links"][k][2]
            for k in start["links"]
            if k.startswith("cmpldw")
        )
        assert p_end + losses == pytest.approx(ev["p0"], rel=1e-3), name


@needs_griddyn
def test_deep_fault_stalls_motor_d_and_the_shallow_one_does_not(runs):
    shallow, s_truth = runs["shallow"]
    deep, d_truth = runs["deep"]
    for frame, truth, stalled in ((shallow, s_truth, False), (deep, d_truth, True)):
        pre = _pre(frame, truth)
        late = frame[frame.t_s > truth["event"]["t_clear_s"] + 1.0]
        q_rise = late.q.mean() / pre.q.mean() - 1
        p_rise = late.p.mean() / pre.p.mean() - 1
        v_drop = 1 - late.v.mean() / pre.v.mean()
        if stalled:
            # Stalled compressors draw rated-current-times-several reactive power for
            # the rest of the window (the thermal relay acts after 15 s): Q stays high,
            # P does not come back to its pre-fault value, the bus voltage stays low.
            assert q_rise > 0.5 and p_rise > 0.1 and v_drop > 0.02, (q_rise, p_rise, v_drop)
        else:
            assert abs(q_rise) < 0.01 and abs(p_rise) < 0.01 and v_drop < 0.002


@needs_griddyn
def test_runs_are_deterministic(runs, tmp_path, monkeypatch):
    # A fresh cache: GridDyn runs again, and gives the same numbers.
    monkeypatch.setenv("LOADBAYES_GRIDDYN_CACHE", str(tmp_path / "cache"))
    again, truth = cases.run_case(depth=cases.DEPTHS["shallow"])
    assert truth["event"]["cache_file"] != runs["shallow"][1]["event"]["cache_file"]
    pd.testing.assert_frame_equal(again, runs["shallow"][0], rtol=1e-10, atol=1e-12)


@needs_griddyn
def test_events_files_for_fit_composite(runs, tmp_path):
    frames, truth = griddyn_events(seed_noise=3, noise=0.01)
    again, _ = griddyn_events(seed_noise=3, noise=0.01)
    assert len(frames) == 2 and all(f.equals(g) for f, g in zip(frames, again, strict=True))
    clean = runs["shallow"][0]
    resid = frames[0].p - clean.p
    sd = 0.01 * np.hypot(truth["events"][0]["p0"], truth["events"][0]["q0"])
    assert 0.8 * sd < resid.std() < 1.2 * sd  # 120 rows: outside this band p < 1e-3
    assert truth["fractions"]["static"] == pytest.approx(1 - 0.15 - 0.10 - 0.15 - 0.15)
    paths = write_events_csv(frames, tmp_path)
    back = pd.read_csv(paths[1])
    assert list(back.columns) == ["t_s", "v", "p", "q", "angle_rad"]
    assert np.allclose(back.p, frames[1].p)
    with pytest.raises(FileExistsError):
        write_events_csv(frames, tmp_path)
