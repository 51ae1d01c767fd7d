"""Issue 37: is the band from the shallow fault alone wider *on average* over data sets?

``tests/integration/test_predict.py`` fits ``cmld-lite`` to GridDyn's shallow (13 %) and
medium (25 %) CMLD faults, and to the shallow one alone, and predicts the deep one (46 %)
from its recorded voltage. On its one data set (noise seed 0) the band from the shallow
fault alone is the narrower (a strict xfail there). Less data widens the predictive
spread on average over data sets drawn from the prior (the law of total variance), not in
each. This module measures the averaged form on GridDyn's data (no loadbayes code makes
them), the same fits and prediction as there (2000 draws, 1000 burn-in, 2 chains, sampler
seed 7; 300 draws predicted, seed 0; 1 % noise on P and Q), over K independent data sets
each of two kinds:

* ``noise``: the harness's default load (``Cmld()``), noise seeds 0 .. K-1 (seed 0 is
  ``test_predict.py``'s data set);
* ``truth``: motor D's share and stall voltage drawn anew for each data set (the static
  part takes what the share leaves), noise seed 100 + k. Vstall is uniform on 0.5-0.7
  p.u., the range of the air conditioners tested in PNNL-17796 (Lu, Xie and Huang 2008)
  that the fit's prior spans (``predict.PRIOR_SOURCE``); motor D's share is uniform on
  0.05-0.25 around the harness's 0.15 (our choice: the width during a stall scales with
  it). GridDyn runs three cases per data set (a few CPU seconds; cached).

For each data set: the mean width over the deep fault's samples of the 95 % band (with
the fit's noise) of P and of Q, from the shallow fault alone and from both, and the share
of the deep fault's recorded P and Q inside each band (its coverage).

**The test.** One-sided Wilcoxon signed-rank test over the K pairs (shallow alone minus
both), alternative "shallow alone wider", for P and for Q. It passes where both reject
"not wider" at 1 %: a pass by chance when the band is not wider on average has
probability at most 1 % for each channel. How often it fails when the claim holds depends
on how much wider the band is, which is what is measured; the sign test's p is printed
beside it. A data set where no draw plays the deep fault (no band) would be reported and
left out of the pairs.

Full counts (K = 20 of each kind) run in ``make validate`` (LOADBAYES_VALIDATE=1); a data
set costs 12-20 CPU s (two fits and two predictions; median 14), so nothing of it fits in
``make test``'s few seconds: there the one data set of ``test_predict.py`` stands. Each
data set runs in a child process with a CPU limit (:data:`CPU_LIMIT_S`): two of them
(noise seeds 4 and 13) hung before the motor kernel's MAX_SUBSTEPS.

**Measured (2026-11-29; the averaged claim is false here too: both kinds are strict
xfails).** Mean width of the band over the deep fault, shallow alone against both:

====== ====== ================= ================= ============= ============= ===========
kind   played P wider (Wilc. p) Q wider (Wilc. p) mean P width  mean Q width  mean cov. Q
====== ====== ================= ================= ============= ============= ===========
noise  18     6/18 (0.827)      8/18 (0.633)      1.120 / 1.188 1.377 / 1.396 0.93 / 0.99
truth  16     4/16 (0.986)      8/16 (0.647)      1.169 / 1.338 1.499 / 1.578 0.95 / 0.69
====== ====== ================= ================= ============= ============= ===========

(Wilcoxon p: one-sided, "shallow alone wider"; the other side, "narrower", 0.19 (P) and
0.38 (Q) for the noise kind and 0.017 (P), 0.37 (Q) for the drawn truths.) So the band
from the shallow fault alone is, if anything, narrower on average. What the law of total variance
needs does not hold: ``cmld-lite`` is not GridDyn's model (no tap, a different motor D),
the truths are not drawn from the fit's prior (uniform shares), and a 95 % band's width is
not a variance. The picture of ``test_predict.py`` repeats: from the shallow fault alone
motor D stalls in fewer draws (stall probability 0.47-0.95 against 0.93-1.00 from both),
and the width during the stall goes with that.

Coverage of the deep fault (the share of its samples inside the band): from both faults
P 0.91-1.00 in every data set; Q 0.93-1.00 on the default load, but on the drawn truths
0.14-0.99 (mean 0.69; below 0.8 in 9 of 16: seeds 105 0.14, 109 0.26, 114 0.40, 112
0.45, ...), so there the Q band from shallow + medium misses most of the deep fault. From
the shallow fault alone P and Q 0.92-1.00, except noise seed 16: a narrow band (P 0.45,
against 0.83 from both; stall probability 0.47) holding 9 % of P's samples and 8 % of
Q's. Every prediction, from either fit, is flagged as extrapolation.

**Why seed 16's band is narrow: the sampler, not the prior (traced 2026-11-29).** The
shallow fit's two chains sat on the feeder's X at 0.207 [0.191, 0.223] and 0.150 [0.136,
0.163] (R-hat of ``log_x_fd`` 1.85, bulk ESS 2.9; shallow + medium put it at 0.08, and
no chain of the shallow fit came near it). At the deep fault 144 of chain 1's 146 picked
draws collapsed or failed numerically while chain 2's played (114 of 154), so the band
was chain 2's playing draws alone: 39 % of the 300 played, 0.42 p.u. wide in P, topping
at 1.20 where GridDyn's stalled load draws 1.33. Sampler seeds 8 and 9 gave per-chain X
of 0.120 / 0.196 and 0.184 / 0.167 and coverage of P 0.28 and 0.08; 2 x 8000 draws, X
0.134 / 0.143, still R-hat 1.92, P 0.10; six chains (seed 11), X 0.12-0.22 by chain,
band 0.58 p.u., P 0.78, Q 0.90. The thresholds (Vstall, Tstall) are sampled from their
prior and agree between chains (R-hat 1.00); the recorded and predicted samples are the
same (the profile's time re-based to 0, sample for sample). So ``predict`` now says
where the chains disagree about the fault (``fit/composite/predict_chains.py``), which
:func:`test_a_band_that_misses_the_deep_fault_says_its_chains_disagree` checks. Re-run
on 29 Nov 2026 with it (the bands unchanged: the same numbers as above, wider in 8/20 and
10/20): the shallow fit's prediction says its chains disagree on seeds 8, 13, 14, 15, 16
(5 of 20), the fit of both faults on none; every one of the 40 says its chains have not
converged (R-hat of the played coordinates at least 1.01); seed 16's is the only band
under 50 % of the deep fault's P or Q. On the drawn truths (bands unchanged, wider in
2/16 and 4/16) the shallow fit's prediction says its chains disagree on 100, 105, 109 and
the fit of both's on 105 alone: the Q bands from both that miss the drawn truths (0.14-0.27)
miss for GridDyn's motor D restart (below), not for the chains, and are not checked so.

**Why the Q band from both misses the drawn truths: after the clearing, not in the sag.**
On seeds 105 and 109 (measured 2026-11-29, the band tabulated sample by sample) the band
holds the recorded Q through the sag; of the 102 samples it misses, 100 come after the
clearing (0.317 s to the record's end): the fit's draws stall (probability 0.99, 1.00,
rightly: GridDyn's feeder end sits at 0.43-0.50 p.u. for 0.1 s) and ``cmld-lite`` keeps
80 % of a stalled motor D stalled (Frst 0.2, the WECC rule; its current through the
feeder holds the load bus below Vrst 0.95, so even Frst = 1 restarts none), drawing Q
0.54-2.68 where GridDyn's load is back at 0.34 within 0.15 s. The fit is not what is
wrong: on 105 motor D's share 0.37 [0.07, 0.55] holds the truth's 0.243 and Vstall
0.60 [0.51, 0.68] sits just under its 0.684 (the medium fault's feeder end, 0.697 at its
lowest, did not stall). GridDyn 0.13.0's motor D is what departs from the rule: at the
46 % sag with f_d 0.15 it stays stalled at Vstall 0.58 and 0.60 and comes back at
0.545, 0.62 and 0.684 (a higher Vstall cannot stall less under the WECC rule), and
stays stalled on only 6 of the 20 drawn loads (106, 107, 108, 115, 117, 118; two of
them GridDyn cannot run) against all of the default load's. The reason shows in
:func:`test_griddyn_brings_motor_d_back_where_the_wecc_model_keeps_it_stalled`; each
row says which (``stays_stalled``) and the report splits Q's coverage by it (measured
2026-11-29 on the 16 played: where GridDyn's motor D stays stalled, 107, 108, 115, 117,
Q's coverage from both is 0.99-1.00; where it comes back, the other 12, 0.14-0.96, mean
0.48, under 0.8 in 9: the three above, 100, 110, 119, are those where 5-6 % of the draws
do not stall, so the band's 2.5 % edge reaches the running load). No fit of
faults without a stall can tell the two apart: ``predict`` says that after a stall P
and Q rest on the restart constants, not on the data (``extrapolation['after_stall']``).

Not played at first: ``predict`` from the shallow fit did not return on noise seeds 4
and 13 (killed at 240 CPU s, where the others take 0.3-4 s): the threads sat in
``models/parts_play._play_block`` (``motor_kernel._rk4``). With the motor kernel's
``MAX_SUBSTEPS`` (and the parts' log T0 coordinates, which moved every fit) all 20 noise
data sets play (re-run on 29 Nov 2026: shallow alone wider in 8/20 for P, 10/20 for Q;
Wilcoxon p 0.982, 0.835; mean coverage of the deep fault 0.94 / 0.93 from the shallow
fault alone, 0.99 / 0.99 from both; on the drawn truths, wider in 2/16 and 4/16, the
shallow-alone band significantly narrower: Wilcoxon p 0.0004 for P, 0.008 for Q). GridDyn
itself fails at the medium (25 %) fault on 4 of the 20 drawn loads (seeds 104, 106, 111,
118; f_d 0.16-0.18, "GridDyn failed four times around Y"): left out and reported.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from loadbayes.cases.griddyn import cases

pytestmark = pytest.mark.statistical

FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"
K = 20
DEPTHS = (0.13, 0.25, 0.46)
ALPHA = 0.01
#: A guard against a data set that never returns (about 12 times a normal one's CPU):
#: each data set runs in a child process with this CPU limit, so a hang is a row that
#: says so, not a validate run that never ends.
CPU_LIMIT_S = 240
_REASON = cases.skip_reason()


def _truths(kind: str, k_sets: int) -> list[tuple[int, object]]:
    """(noise seed, Cmld) for each data set of ``kind``."""
    from loadbayes.cases.griddyn.cmld import Cmld, MotorD

    if kind == "noise":
        return [(k, Cmld()) for k in range(k_sets)]
    rng = np.random.default_rng(2026)
    out = []
    for k in range(k_sets):
        f_d, vstall = rng.uniform(0.05, 0.25), rng.uniform(0.5, 0.7)
        out.append((100 + k, Cmld(f_d=float(f_d), motor_d=MotorD(vstall=float(vstall)))))
    return out


def _band_numbers(pred, frame) -> dict:
    """Mean width of the band and the share of the recorded P, Q inside it."""
    b = pred.band
    if b is None:
        return {f"{w}_{ch}": float("nan") for w in ("width", "cover") for ch in "pq"}
    out = {}
    for ch in "pq":
        lo, hi = np.asarray(b[f"{ch}_pred_lo"]), np.asarray(b[f"{ch}_pred_hi"])
        x = frame[ch].to_numpy()
        out[f"width_{ch}"] = float(np.mean(hi - lo))
        out[f"cover_{ch}"] = float(np.mean((x >= lo) & (x <= hi)))
    return out


def _stays_stalled(frame) -> bool:
    """GridDyn's load still stalled at the deep record's end: its P over the last 0.5 s
    above the pre-fault P (the first 0.15 s) by more than 0.1 p.u. A stalled motor D
    draws about five times its rating at 1 p.u. (Rstall = Xstall = 0.1), so even a 5 %
    share stalled adds 0.25; a load come back sits within its 1 % noise."""
    t, p = frame.t_s.to_numpy(), frame.p.to_numpy()
    return bool(np.mean(p[t > t[-1] - 0.5]) - np.mean(p[t < 0.15]) > 0.1)


def _one_data_set(seed_noise: int, cmld, folder) -> dict:
    from loadbayes.cases.griddyn.events import griddyn_events
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.fit.composite.predict import predict
    from loadbayes.measurements.record import EventRecord
    from loadbayes.models.dynamic import dynamic_model

    frames, truth = griddyn_events(depths=DEPTHS, seed_noise=seed_noise, cmld=cmld)
    cpu = time.process_time()
    evs = [EventRecord(f.t_s.to_numpy(), f.v.to_numpy(), f.p.to_numpy(), f.q.to_numpy(),
                       f.angle_rad.to_numpy(), f"griddyn {k}")
           for k, f in enumerate(frames)]  # fmt: skip
    model = dynamic_model("cmld-lite", f_hz=60.0)
    sampler = SamplerSettings(draws=2000, burn=1000, chains=2, seed=7)
    deep = folder / f"deep{seed_noise}.csv"
    frames[2][["t_s", "v", "angle_rad"]].to_csv(deep, index=False)
    row = {"seed_noise": seed_noise, "f_d": cmld.f_d, "vstall": cmld.motor_d.vstall,
           "depth_deep": truth["events"][2]["depth_measured"],
           "stays_stalled": _stays_stalled(frames[2])}  # fmt: skip
    for name, used in (("both", evs[:2]), ("shallow", evs[:1])):
        post = fit_composite(model, used, sampler=sampler).posterior
        pred = predict(post, voltage=deep, draws=300)
        chains = pred.chains or {}
        row[name] = _band_numbers(pred, frames[2]) | {
            "stall": pred.stall["probability"],
            "flagged": bool(pred.extrapolation["extrapolated"]),
            "chains_disagree": bool(chains.get("disagree", False)),
            "converged": bool(chains.get("converged", True)),
        }
    row["cpu_s"] = time.process_time() - cpu
    return row


def _paired(rows: list[dict], ch: str) -> dict:
    d = np.array([r["shallow"][f"width_{ch}"] - r["both"][f"width_{ch}"] for r in rows])
    d = d[np.isfinite(d)]
    wider = int(np.sum(d > 0))
    return {
        "pairs": len(d),
        "wider": wider,
        "mean_difference": float(np.mean(d)),
        "wilcoxon_p": float(stats.wilcoxon(d, alternative="greater").pvalue),
        "sign_p": float(stats.binomtest(wider, int(np.sum(d != 0)), alternative="greater").pvalue),
        "wilcoxon_p_narrower": float(stats.wilcoxon(d, alternative="less").pvalue),
    }


def _report(kind: str, rows: list[dict], tests: dict) -> None:
    print(f"\n{kind}: per data set, mean width of the 95% band (shallow alone / both) and "
          "coverage of the deep fault")  # fmt: skip
    print(" seed   f_d  vstall | wP sh  wP both | wQ sh  wQ both | cov P sh/both | "
          "cov Q sh/both | stall sh/both | cpu s")  # fmt: skip
    for r in rows:
        s, b = r["shallow"], r["both"]
        print(f" {r['seed_noise']:4d} {r['f_d']:.3f} {r['vstall']:.3f} | {s['width_p']:.3f} "
              f"{b['width_p']:.3f} | {s['width_q']:.3f} {b['width_q']:.3f} | {s['cover_p']:.2f} "
              f"{b['cover_p']:.2f} | {s['cover_q']:.2f} {b['cover_q']:.2f} | {s['stall']:.2f} "
              f"{b['stall']:.2f} | {r['cpu_s']:.1f}")  # fmt: skip
    for stays in (True, False):
        sub = [r for r in rows if r.get("stays_stalled") is stays]
        if sub:
            print(f" GridDyn's motor D {'stays stalled' if stays else 'comes back'} in "
                  f"{len(sub)}: coverage of Q from both " + ", ".join(
                      f"{r['seed_noise']} {r['both']['cover_q']:.2f}" for r in sub))  # fmt: skip
    for name in ("shallow", "both"):
        said = [r["seed_noise"] for r in rows if r[name].get("chains_disagree")]
        print(f" {name}: the prediction says the chains disagree about the deep fault in "
              f"{len(said)}/{len(rows)} {said}; not converged in "
              f"{sum(not r[name].get('converged', True) for r in rows)}")  # fmt: skip
    for name in ("shallow", "both"):
        cov = {ch: np.nanmean([r[name][f"cover_{ch}"] for r in rows]) for ch in "pq"}
        flagged = sum(r[name]["flagged"] for r in rows)
        print(f" {name}: mean coverage P {cov['p']:.3f}, Q {cov['q']:.3f}; flagged "
              f"{flagged}/{len(rows)}")  # fmt: skip
    for ch, t in tests.items():
        print(f" {ch.upper()}: shallow alone wider in {t['wider']}/{t['pairs']}, mean difference "
              f"{t['mean_difference']:+.3f}; one-sided p (wider): Wilcoxon "
              f"{t['wilcoxon_p']:.3g}, sign {t['sign_p']:.3g}; Wilcoxon p (narrower) "
              f"{t['wilcoxon_p_narrower']:.3g}")  # fmt: skip


def _in_child(kind: str, index: int, folder: Path) -> dict:
    """One data set in a fresh interpreter under :data:`CPU_LIMIT_S`; failures as rows."""
    code = (f"import json, sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
            "import test_predict_band_average as m; from pathlib import Path; "
            f"seed, cmld = m._truths({kind!r}, m.K)[{index}]; "
            f"print(json.dumps(m._one_data_set(seed, cmld, Path({str(folder)!r}))))")  # fmt: skip

    def limit():
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_LIMIT_S, CPU_LIMIT_S))

    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          preexec_fn=limit)  # fmt: skip
    if done.returncode == 0:
        return json.loads(done.stdout.strip().splitlines()[-1])
    seed, _ = _truths(kind, K)[index]
    if done.returncode < 0:  # RLIMIT_CPU: SIGXCPU, then SIGKILL
        last = f"killed by signal {-done.returncode} (at most {CPU_LIMIT_S} CPU s a data set)"
    else:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
    if "GridDyn" in last:  # GridDyn could not run this drawn load: not the package's
        return {"seed_noise": seed, "griddyn_failed": last}
    return {"seed_noise": seed, "failed": last, "returncode": done.returncode}


_ROWS: dict[str, list[dict]] = {}


def _rows(kind: str, folder: Path) -> list[dict]:
    if kind not in _ROWS:
        _ROWS[kind] = [_in_child(kind, i, folder) for i in range(K)]
    return _ROWS[kind]


@pytest.mark.skipif(_REASON is not None, reason=str(_REASON))
@pytest.mark.skipif(not FULL, reason="2 x 20 data sets, 4 fits each: make validate")
@pytest.mark.parametrize("kind", [
    pytest.param("noise", marks=pytest.mark.xfail(strict=True, reason="measured: shallow "
                 "alone wider in 8/20 (P), 10/20 (Q); one-sided Wilcoxon p 0.982, 0.835")),
    pytest.param("truth", marks=pytest.mark.xfail(strict=True, reason="measured: shallow "
                 "alone wider in 2/16 (P), 4/16 (Q); one-sided Wilcoxon p 1.000, 0.993")),
])  # fmt: skip
def test_the_band_from_the_shallow_fault_alone_is_wider_on_average(kind, tmp_path):
    rows = [r for r in _rows(kind, tmp_path) if "both" in r]
    tests = {ch: _paired(rows, ch) for ch in "pq"}
    _report(kind, rows, tests)
    assert tests["p"]["wilcoxon_p"] < ALPHA and tests["q"]["wilcoxon_p"] < ALPHA, tests


@pytest.mark.skipif(_REASON is not None, reason=str(_REASON))
@pytest.mark.skipif(not FULL, reason="2 x 20 data sets, 4 fits each: make validate")
# Predict from the shallow fit did not return on noise seeds 4 and 13 (240 CPU s) until the
# motor kernel refused inputs asking for more than MAX_SUBSTEPS sub-steps (and the parts'
# log T0 coordinates changed the fits); since, both play (40 and 18 CPU s).
@pytest.mark.parametrize("kind", ["noise", "truth"])
def test_every_data_set_is_played(kind, tmp_path):
    rows = _rows(kind, tmp_path)
    skipped = [r for r in rows if "griddyn_failed" in r]
    failed = [r for r in rows if "failed" in r]
    print(f"\n{kind}: GridDyn could not run {len(skipped)} drawn loads: {skipped}")
    assert not failed, failed


@pytest.mark.skipif(_REASON is not None, reason=str(_REASON))
def test_griddyn_brings_motor_d_back_where_the_wecc_model_keeps_it_stalled():
    """Why the Q band from shallow + medium misses most drawn truths: the reference.

    At the 46 % sag the feeder end sits near 0.43-0.50 p.u. for 0.1 s, three times
    Tstall (0.033 s) below any Vstall of 0.5-0.7: the WECC model (and ``cmld-lite``)
    stalls motor D and keeps 1 - Frst = 80 % of it stalled after the clearing (Trst 0.4 s,
    no thermal trip within 2 s), and a higher Vstall can only stall it sooner. GridDyn
    0.13.0 keeps it stalled at Vstall 0.60 (the default load: P 1.33, Q 0.93 at the
    record's end against 0.99, 0.35 before) but brings it back within 0.15 s at 0.684
    (measured, f_d 0.15: also stalled at 0.58, back at 0.545 and 0.62; f_d 0.20 stalled,
    0.243 back, at Vstall 0.60). So GridDyn's deep fault on such a load is not what the
    model the fit assumes does after a stall, and no fit of 13 % and 25 % faults (no stall
    in them) can tell which: ``predict`` says the post-stall answer is an assumption
    (``extrapolation['after_stall']``). Deterministic GridDyn runs (cached); fails when
    GridDyn's motor D starts to follow the WECC rule here, and then the drawn truths'
    coverage must be measured again.
    """
    from loadbayes.cases.griddyn.cmld import Cmld, MotorD
    from loadbayes.cases.griddyn.events import griddyn_events

    stays = {}
    for vstall in (0.60, 0.684):
        frames, _ = griddyn_events(depths=(0.46,), seed_noise=None,
                                   cmld=Cmld(motor_d=MotorD(vstall=vstall)))  # fmt: skip
        f = frames[0]
        during = f.v.to_numpy()[(f.t_s > 0.22) & (f.t_s < 0.3)]
        assert np.all(during < 0.6), during  # the recorded bus; the feeder end is lower
        stays[vstall] = _stays_stalled(f)
    assert stays == {0.60: True, 0.684: False}, stays


#: A band holding less than this share of the deep fault's P or Q is falsely narrow.
NARROW_COVER = 0.5


@pytest.mark.skipif(_REASON is not None, reason=str(_REASON))
@pytest.mark.skipif(not FULL, reason="2 x 20 data sets, 4 fits each: make validate")
def test_a_band_that_misses_the_deep_fault_says_its_chains_disagree(tmp_path):
    """Noise seed 16's band from the shallow fault alone (8 % of P, 7 % of Q) was one
    chain's: the other chain's draws, on a feeder's X 0.207 against 0.150, collapsed or
    failed at the deep fault (``fit/composite/predict_chains.py``). Every band of the
    default load's data sets that holds under half of the deep fault's P or Q must say
    that its chains disagree about the fault, and seed 16's shallow one must be among
    them. Deterministic given the seeds (no false alarm); it fails where a band misses
    the deep fault for another reason, which would then need its own trace."""
    rows = [r for r in _rows("noise", tmp_path) if "both" in r]
    fits = [(r["seed_noise"], name, r[name]) for r in rows for name in ("shallow", "both")]
    narrow = [(s, n) for s, n, f in fits if min(f["cover_p"], f["cover_q"]) < NARROW_COVER]
    silent = [(s, n) for s, n, f in fits if (s, n) in narrow and not f["chains_disagree"]]
    print(f"\nbands under {NARROW_COVER:.0%} of the deep fault: {narrow}; silent: {silent}")
    assert (16, "shallow") in narrow, narrow
    assert not silent, silent
