"""The motors' rating with and without the negative sequence, on a record the tests wrote.

Issue 36, Checks: "three-phase waveforms of a known mix under phase-to-ground faults,
with the motors' negative-sequence current; the motor rating is covered with the
negative sequence, and is not without it." The record is :mod:`sequence_generator`'s
(SciPy, no loadbayes): a static ZIP part (0.35 + j0.05 p.u.) and two third-order motors
whose parameters lie in ``cmld-lite``'s motor classes' priors (models/part_priors.py)
except their loading: motor A (constant torque, Rs 0.04, X' 0.118, X - X' 1.74, T' 0.10 s,
H 0.12 s, rating 0.5) and motor B (torque ~ speed squared, Rs 0.03, X' 0.194, X - X' 1.61,
T' 0.20 s, H 0.5 s, rating 0.3), both at T0 0.35, far below the prior's median 0.75, so
that a rating resting on the prior of T0 misses the truth (0.8). A phase-A-to-ground
fault (|V1| 0.87, |V2| 0.13) of 0.1017 s; 50 Hz waveforms at 3200 samples/s, written as
COMTRADE and read by the package's reader as a user would (``loadbayes read comtrade``
at its default one phasor a cycle, then ``loadbayes events``): 30 rows with V2 and I2.

What the checks found (each test says which):

- **A (fixed). Rows across a step were left out of the likelihood but not out of the
  motors' input**: their one-cycle means across the step became knots of a linear input
  voltage, and at the true parameters the kept rows beside each step missed P by up to
  0.033 p.u. (5% of P0). A model of parts now cuts those rows and steps the voltage
  across the gap at the instant the straddling rows' means give
  (models/parts.step_times, step_knots; in the compiled sums too): the kept rows match
  the record to 6e-4 at the truth (:func:`test_the_model_is_the_readers_rows_at_the_truth`).
  Besides (models/composite_steps.edge_runs, shared with zip+motor): at ``--per-cycle 4``
  a 13% sag moves at most 3.6% per row, under ``JUMP`` (5%), so no edge is found there;
  the reader's ``straddle`` flags (``EventRecord.straddle``) are used where given.
- **B (fixed). The motors' swing equation had no negative-sequence braking torque**
  (``|I_r2|^2 Rr / (2 - s)``, which the generator has). During the unbalanced fault the
  generator's motors slowed more than the model's, and at the true parameters the model's
  P was low by 0.012 p.u. (1.8% of P0) throughout the fault (0.0004 on the same sag
  balanced). The motors now brake with the load bus's ``|V2|``
  (``motor_kernel.brake_torque``, from their T-circuit at slip ``2 - s``): the mean
  residual during the unbalanced fault is 0.0004 p.u. (0.06% of P0, measured 3.9e-4),
  the balanced sag's (3.8e-4)
  (:func:`test_the_motors_positive_sequence_under_an_unbalanced_fault`).
- **C. The negative sequence does not see T0, the coordinate that sets the rating.** A
  motor of rating S with own-base impedances Z is, at its terminals, Z / S in both
  sequences: ``S / Z2`` is the same system-unit impedance the positive sequence sees.
  In ``PartsModel``'s coordinates, moving ``log_t0`` with the scale-free ones fixed
  changes the rating threefold and neither the P column nor the predicted I2 (to 1e-9).
  The rating then comes from the priors alone: where I2 pins ``X' T0``, from the prior
  of the own-base X' (sd of the log 0.3) beside T0's (0.25). parts_model.py's docstring
  says the negative sequence sees ``log T0``: it does not.

Measured on this record (4000 draws, 2000 burn-in, 2 chains, seed 0), total rating
(truth 0.8), 95% interval (R-hat of the total rating where measured):

====================================================== ====================== ======================
events                                                 with I2 ("auto")       without ("off")
====================================================== ====================== ======================
the reader's rows, before A was fixed                  [0.107, 0.273]         [0.142, 0.256]
the reader's rows, A fixed, before the share steps     [0.476, 0.984] (1.05)  [0.239, 0.681] (1.09)
the same, with the share steps, before B was fixed     [0.457, 1.040] (1.20)  [0.230, 0.885] (1.22)
the same, B fixed: the motors brake (this test)        [0.495, 1.064] (1.69)  [0.299, 0.796] (1.13)
====================================================== ====================== ======================

(The share steps: ``fit/composite/shares.py``.) With the braking torque the interval
without I2 misses the truth at this seed by 0.004, but a miss by 0.004 at one seed of
unconverged chains, which the other seeds and the long run below cover, is no evidence
that the positive sequence alone misses the rating: that claim (the issue's "and is not
without it") is not asserted, here or as an xfail; finding C says why it cannot be
expected to hold. Every run is unconverged. At sampler seeds 1 and
2 (braking) with I2 [0.463, 0.756] (R-hat 1.58, missed) and [0.510, 0.967] (1.21),
without [0.307, 0.848] (1.17, covered) and [0.210, 0.691] (1.33, missed); before the
braking seeds 1 and 2 gave [0.315, 0.932] and [0.486, 1.144] with, [0.276, 0.880] and
[0.232, 0.955] without, all covering. At 4 chains of 12000 (6000 burn-in), seed 0: with
the braking [0.400, 1.115] with I2 and [0.259, 0.867] without (R-hat 1.14 both), both
covering; before it [0.242, 1.161] with I2 (R-hat 1.27) and [0.269, 0.940] without
(1.07).

With A fixed the rating is covered with I2 (asserted, at this seed) and, without it,
missed or covered by seed (the prior of T0, median 0.75 where the truth is 0.35,
decides it then); it is not narrower with I2 (0.57 wide against 0.50). ``f_motors``
(0.455) was read high with I2 before B was fixed ([0.546, 0.760]; [0.489, 0.711] and
[0.543, 0.695] at seeds 1, 2), which the missing braking was thought to cause: with the
braking it is [0.492, 0.723] at this seed, still high, [0.491, 0.664] and [0.363, 0.533]
at seeds 1, 2, and [0.410, 0.691] in the long run; without I2 it is covered at each
([0.380, 0.694]). So the braking is not the whole of it. At the true parameters the I2
rows miss by up to 5.5e-3 (0.8% of ``|I2|``; the reader leaves up to 4e-3 at one phasor
a cycle; the model's I2 takes each motor's admittance at slip 2, the generator's at
``2 - s``), not traced further; on the reader's rows the model's P at the truth misses
the unbalanced fault by up to 3.0e-3 with the braking (1.4e-2 without), against 5.6e-4
on the balanced sag, not traced further either.

False-alarm rates: the residual checks are deterministic (fixed noise seed;
thresholds of 15 to 25 times the noise of P); the rating test, with
calibrated intervals, fails 5% of the time, and runs under ``make validate`` only, at
the long run's length: at 2 chains of 4000 its chains are not converged (the table) and
another machine's arithmetic gave [0.34, 0.76] at seed 0, a miss, where this table's
seed 0 covered.
The fits without I2 in the table were measured, not run by the suite.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.measurements.events import read_events
from loadbayes.measurements.record import EventRecord
from loadbayes.models.parts_model import PartsModel
from sequence_generator import Fault, Motor, generate, write_record

pytestmark = pytest.mark.statistical

F_HZ, V_BASE, S_BASE = 50.0, 110.0, 40.0
WB = 2 * math.pi * F_HZ
FAULT_S = 0.1017
#: The rating's fit: 4 chains of 12000 (6000 burn-in) under ``make validate``, where the
#: table's long run covered the truth at R-hat 1.14; the suite's 2 chains of 4000 were
#: never converged (R-hat 1.2-1.7) and their coverage was a coin another machine's
#: arithmetic turned ([0.34, 0.76] there, [0.495, 1.064] here): not run by ``make test``.
FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"
DRAWS, BURN, CHAINS, SEED = (12000, 6000, 4, 0) if FULL else (4000, 2000, 2, 0)
# Slips at which each motor carries T0 = 0.35 (found by the generator's steady state).
MOTOR_A = Motor(rating=0.5, rs=0.04, xs=0.06, xm=1.8, xr=0.06, rr=1.86 / (WB * 0.10),
                h_s=0.12, s0=0.02283, torque_exp=0)  # fmt: skip
MOTOR_B = Motor(rating=0.3, rs=0.03, xs=0.10, xm=1.7, xr=0.10, rr=1.8 / (WB * 0.20),
                h_s=0.5, s0=0.01156, torque_exp=2)  # fmt: skip
BALANCED = {"v2": 0j, "v0": 0j}
# What the checks found (the module docstring's A, B and C).
WHY_B = (
    "B: without the negative sequence's braking torque the model's P was low by 0.012 p.u. "
    "(1.8% of P0) through the unbalanced fault at the true parameters; with it 3.9e-4"
)


def _model(negative_sequence: str, window_s: float = 1 / F_HZ, cls=PartsModel, **extra):
    return cls(motors=("a", "b"), feeder=False, f_hz=F_HZ, negative_sequence=negative_sequence,
               window_s=window_s, **extra)  # fmt: skip


def _read(tmp_path, **fault) -> tuple[EventRecord, dict, float]:
    """The record through `read comtrade` and `events`: the event, the truth, its t0."""
    cfg, rec = write_record(tmp_path / "gen", f_hz=F_HZ, rate_hz=3200.0, t_end_s=0.6,
                            v_base_kv=V_BASE, s_base_mva=S_BASE, motors=(MOTOR_A, MOTOR_B),
                            fault=Fault(duration_s=FAULT_S, **fault), seed=0)  # fmt: skip
    runner = CliRunner()
    res = runner.invoke(main, ["read", "comtrade", str(cfg), "--v-base", str(V_BASE),
                               "--s-base", str(S_BASE), "--out", str(tmp_path / "rec.csv"),
                               "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    res = runner.invoke(main, ["events", str(tmp_path / "rec.csv"), "--out",
                               str(tmp_path / "ev"), "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    (ev,) = read_events([str(tmp_path / "ev" / "event_001.csv")], f_hz=F_HZ)
    t0 = float(pd.read_csv(tmp_path / "rec.csv", nrows=1)["t_s"].iloc[0])
    return ev, rec.truth, t0


def _true_theta(model: PartsModel, truth: dict) -> np.ndarray:
    """The generator's mix in the model's sampled coordinates (motors as the model's closure)."""
    p0 = truth["p0"]
    phys = []
    for m, mt in zip((MOTOR_A, MOTOR_B), truth["motors"], strict=True):
        phys.append(np.log([m.rs, m.x1, m.x - m.x1, m.t0p(WB), m.h_s, mt["load_torque"]]))
    f = [m.rating * mt["p_pre_motor_base"] / p0 for m, mt in
         zip((MOTOR_A, MOTOR_B), truth["motors"], strict=True)]  # fmt: skip
    f_s = truth["zip"]["p"] / p0
    a1, a2, a3 = truth["zip"]["shares"][:3]
    # The model's coordinates from the physical logs: (Rs T0, X' T0, (X - X') T0, T',
    # H / T0, T0), as models/parts_model._SCALE_FREE maps them.
    coords = []
    for rs, xp, dx, tp, h, t0 in phys:
        coords += [rs + t0, xp + t0, dx + t0, tp, h - t0, t0]
    theta = np.array([*coords, math.log(f[0] / f_s), math.log(f[1] / f_s),
                      math.log(a1 / a3), math.log(a2 / a3)])  # fmt: skip
    phys_back = model.physical(theta)
    assert phys_back["t0_a"] == pytest.approx(0.35, rel=1e-3)
    assert phys_back["x_prime_b"] == pytest.approx(MOTOR_B.x1)
    assert phys_back["f_motors"] == pytest.approx(sum(f))
    return theta


def _p_residual(model: PartsModel, event: EventRecord, theta: np.ndarray, p0: float):
    (z, y), *_ = model.channels(event, theta)
    return y - z[:, 0] * p0


def test_the_generators_mix_has_the_rating_the_prior_of_t0_misses():
    # The premise: lightly loaded motors, whose rating a T0 at the prior's median reads
    # at less than half the truth.
    *_, truth = generate(f_hz=F_HZ, rate_hz=400.0, t_end_s=0.3, motors=(MOTOR_A, MOTOR_B))
    assert truth["motor_rating_total"] == pytest.approx(0.8)
    p_motors = sum(m["rating"] * m["p_pre_motor_base"] for m in truth["motors"])
    for m in truth["motors"]:
        assert m["load_torque"] == pytest.approx(0.35, abs=1e-3)
    assert p_motors / 0.75 < 0.5 * truth["motor_rating_total"]


def test_the_motor_kernel_is_the_generators_on_a_balanced_sag():
    # Point samples of the generator's own phasors (3200/s, no reader): at the true
    # parameters the model's P during the fault is the generator's on average to 0.3% of
    # P0 (measured 0.0004 p.u.). The check beside B's, which differs in V2 only.
    t, sv, si, _, truth = generate(f_hz=F_HZ, rate_hz=3200.0, t_end_s=0.6,
                                   motors=(MOTOR_A, MOTOR_B),
                                   fault=Fault(duration_s=FAULT_S, **BALANCED))  # fmt: skip
    s = sv[1] * np.conj(si[1])
    ev = EventRecord(t, np.abs(sv[1]), s.real, s.imag, np.angle(sv[1]), "points")
    model = _model("off", window_s=0.0)
    r = _p_residual(model, ev, _true_theta(model, truth), truth["p0"])
    during = (t > truth["fault"]["t_on_s"] + 0.001) & (t < truth["fault"]["t_off_s"])
    assert abs(r[during].mean()) < 0.003 * truth["p0"], r[during].mean()


def test_the_motors_positive_sequence_under_an_unbalanced_fault():
    # B: the same check on the unbalanced fault, the generator's V2 and I2 given (the I2
    # channel off: the braking is the motors' physics, not the I2 data). Measured 3.9e-4
    # p.u. with the braking torque; without V2 the model's mean is 0.012 (1.8% of P0),
    # which the second assert keeps as the check that the braking is what closes it.
    t, sv, si, _, truth = generate(f_hz=F_HZ, rate_hz=3200.0, t_end_s=0.6,
                                   motors=(MOTOR_A, MOTOR_B),
                                   fault=Fault(duration_s=FAULT_S))  # fmt: skip
    s = sv[1] * np.conj(si[1])
    balanced = EventRecord(t, np.abs(sv[1]), s.real, s.imag, np.angle(sv[1]), "points")
    ev = replace(balanced, v2=sv[2], i2=si[2])
    model = _model("off", window_s=0.0)
    theta = _true_theta(model, truth)
    during = (t > truth["fault"]["t_on_s"] + 0.001) & (t < truth["fault"]["t_off_s"])
    r = _p_residual(model, ev, theta, truth["p0"])
    assert abs(r[during].mean()) < 0.003 * truth["p0"], (WHY_B, r[during].mean())
    r_none = _p_residual(model, balanced, theta, truth["p0"])
    assert r_none[during].mean() > 0.01 * truth["p0"], r_none[during].mean()


def test_the_model_is_the_readers_rows_at_the_truth(tmp_path):
    # A balanced sag through the reader: the rows across the two steps left out, the
    # steps placed by the straddling rows' means; at the true parameters the model's P is
    # the record's to 2.5e-3 p.u. (measured 5.6e-4; it was 0.033 with those rows as
    # knots of a ramp).
    ev, truth, _ = _read(tmp_path, **BALANCED)
    model = _model("off")
    r = _p_residual(model, ev, _true_theta(model, truth), truth["p0"])
    assert r.size < ev.n  # the rows across the two steps are left out
    assert np.abs(r).max() < 2.5e-3, np.abs(r).max()


def test_the_negative_sequence_is_blind_to_the_coordinate_of_the_rating(tmp_path):
    # C: along log_t0 (the scale-free coordinates held) the rating moves threefold, the
    # P column and the predicted I2 do not: the rating is the priors'.
    ev, truth, _ = _read(tmp_path)
    model = _model("on")
    theta = _true_theta(model, truth)
    i_t0 = model.theta_names.index("log_t0_a")
    out = []
    for t0 in (0.35, 1.05):
        th = theta.copy()
        th[i_t0] = math.log(t0)
        (zp, _), _, (zi, _) = model.channels(ev, th)
        out.append((zp, zi, model.ratings(ev, th, np.array([truth["p0"]]))["mva_a"][0]))
    (zp0, zi0, mva0), (zp1, zi1, mva1) = out
    assert mva0 / mva1 == pytest.approx(3.0, rel=0.02)
    assert np.allclose(zi0, zi1, rtol=1e-9, atol=1e-12)
    assert np.allclose(zp0, zp1, rtol=1e-9, atol=1e-12)


@pytest.fixture(scope="module")
def ratings(tmp_path_factory):
    """The total rating's 95% interval with I2 ("auto"), and the truth."""
    ev, truth, _ = _read(tmp_path_factory.mktemp("ratings"))
    assert ev.unbalanced and _model("auto").uses_negative_sequence(ev)
    sampler = SamplerSettings(draws=DRAWS, burn=BURN, chains=CHAINS, seed=SEED)
    d = fit_composite(_model("auto"), [ev], sampler=sampler).posterior.draws
    total = np.asarray(d["mva_a"]) + np.asarray(d["mva_b"])
    return tuple(np.quantile(total, [0.025, 0.975])), truth["motor_rating_total"]


@pytest.mark.skipif(not FULL, reason="unconverged at the suite's length: make validate "
                    "(LOADBAYES_VALIDATE=1) runs the long fit")  # fmt: skip
def test_the_rating_is_covered_with_the_negative_sequence(ratings):
    # With A and B fixed: [0.495, 1.064] for 0.8, R-hat 1.69 (before the braking, with
    # the shares' own steps [0.457, 1.040], R-hat 1.20; before them [0.476, 0.984],
    # R-hat 1.05). At seed 1 it misses ([0.463, 0.756], R-hat 1.58): unconverged. Not
    # asserted: a narrower interval with I2; by C the negative sequence measures S / X',
    # which the positive sequence sees through X' T0 too, so what it adds is a second,
    # sharper look at that one combination.
    (lo, hi), true = ratings
    assert lo <= true <= hi, (lo, hi)
