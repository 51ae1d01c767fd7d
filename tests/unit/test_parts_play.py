"""The compiled play of many draws equals ``predict_parts``, draw for draw.

``models/parts_play.play_draws`` solves each draw's feeder loop in one compiled call;
``models/parts_predict.play_reference`` is the NumPy reference (``predict_parts`` draw
by draw, then the stall and the trip read as ``fit/composite/predict.py`` read them
before). On random draws around the models' priors (``slm`` and ``cmld-lite``) and
faults built here (a shallow sag, a deep one that stalls motor D and trips the
electronics, one with a phase jump and a recovery ramp, a profile without an angle,
window means, two with a negative sequence that brakes the motors), every draw's P, Q
at the recorded bus, the load bus's |V_L|, the sweeps
the loop took, whether it converged, whether motor D stalled (its trajectory against one
that never stalls) and the share of the electronics tripped must agree with the
reference, P, Q and |V_L| to 1e-8 p.u. Deterministic (fixed seeds); each case also
asserts it saw what it is about (stalls, trips, a draw with no steady state planted), so
a vacuous pass fails.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.parts_loop import pv_root
from loadbayes.models.parts_play import COLLAPSES, play_draws
from loadbayes.models.parts_predict import _pv_root, play_reference

P0, Q0 = 0.9, 0.3


def _fault(depth, *, angle_deg=0.0, recovery=0.0, rate=120.0, end=0.8, with_angle=True,
           v2=0.0):  # fmt: skip
    # A sag at 0.1 s for 0.1 s, written here (not predict_scope.sag_profile); v2: |V2|
    # during it (a phase-to-ground fault's negative sequence), None outside.
    t = np.arange(0.0, end, 1.0 / rate)
    share = np.where((t >= 0.1) & (t < 0.2), 1.0, 0.0)
    if recovery > 0:
        ramp = (t >= 0.2) & (t < 0.2 + recovery)
        share[ramp] = 1.0 - (t[ramp] - 0.2) / recovery
    zeros = np.zeros(t.size)
    delta = np.radians(angle_deg) * share if with_angle else None
    neg = v2 * np.exp(2.5j) * share if v2 else None
    return EventRecord(t, 1.0 - depth * share, zeros, zeros, delta, f"sag {depth}", v2=neg)


def _draws(model, n, seed):
    # Draws around the model's prior (its scale-free Gaussian, shrunk), shares included.
    t = np.linspace(0, 0.5, 31)
    ev = EventRecord(t, np.ones(t.size), np.full(t.size, P0), np.full(t.size, Q0))
    mean, cov, _, _ = model.default_prior([ev]).scale_free()
    rng = np.random.default_rng(seed)
    theta = rng.multivariate_normal(mean, 0.1 * cov, size=n)
    q_sh = rng.dirichlet([2.0, 2.0, 2.0], size=n) * rng.choice([1.0, -0.5], size=(n, 1))
    q_sh /= q_sh.sum(-1, keepdims=True)
    th = {"vstall": rng.uniform(0.45, 0.75, n), "tstall": rng.uniform(0.0, 0.2, n),
          "vd1": rng.uniform(0.6, 0.85, n)}  # fmt: skip
    th["vd2"] = th["vd1"] - rng.uniform(0.05, 0.4, n)
    return theta, q_sh, th


CASES = [  # model, window, fault, draws, seed
    ("slm", 0.0, dict(depth=0.45), 12, 1),
    ("slm", 0.0, dict(depth=0.6, angle_deg=-25.0, recovery=0.15), 12, 2),
    ("slm", 1 / 60, dict(depth=0.3, with_angle=False), 8, 3),
    ("cmld-lite", 0.0, dict(depth=0.15), 12, 4),
    ("cmld-lite", 0.0, dict(depth=0.4), 16, 5),
    ("cmld-lite", 0.0, dict(depth=0.4, angle_deg=20.0, recovery=0.1), 16, 6),
    ("cmld-lite", 1 / 60, dict(depth=0.3, with_angle=False), 12, 7),
    ("slm", 0.0, dict(depth=0.2, v2=0.15, recovery=0.1), 12, 9),
    ("cmld-lite", 1 / 60, dict(depth=0.3, v2=0.2, with_angle=False), 12, 10),
]


@pytest.mark.parametrize(("name", "window", "fault", "n", "seed"), CASES)
def test_the_compiled_play_is_predict_parts(name, window, fault, n, seed):
    model = dynamic_model(name, f_hz=60.0, window_s=window)
    event = _fault(**fault)
    theta, q_sh, th = _draws(model, n, seed)
    # A draw whose motor cannot run at the voltage (load torque far past breakdown): both
    # paths must refuse it.
    theta[0, model.theta_names.index("log_x_prime_t0" + model._tags[0])] += 3.0
    got = play_draws(model, event, theta, P0, Q0, q_sh, th)
    ref = play_reference(model, event, theta, P0, Q0, q_sh, th)
    np.testing.assert_array_equal(got.ok, ref.ok)
    np.testing.assert_array_equal(got.why, ref.why)  # plays, not settled, not finite, ...
    np.testing.assert_array_equal(got.iterations[ref.ok], ref.iterations[ref.ok])
    for a, b in ((got.p, ref.p), (got.q, ref.q), (got.vl, ref.vl), (got.tripped, ref.tripped)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8)  # NaN where failed, in both
    np.testing.assert_array_equal(got.stalled, ref.stalled)
    seen = {"ok": int(ref.ok.sum()), "failed": int((~ref.ok).sum()),
            "stalled": int(ref.stalled[ref.ok].sum()), "running": int((~ref.stalled[ref.ok]).sum()),
            "tripped": int(np.sum(ref.tripped[ref.ok] > 0.01))}  # fmt: skip
    assert seen["failed"] >= 1 and seen["ok"] >= n // 2, seen
    if model.motor_d and fault["depth"] >= 0.4:  # deep: some draws stall, some ride through
        assert seen["stalled"] >= 1 and seen["running"] >= 1, seen
        assert seen["tripped"] >= 1, seen
    if model.motor_d and fault["depth"] < 0.2:  # shallow: above every stall voltage drawn
        assert seen["stalled"] == 0, seen
    if fault.get("v2"):  # the braking is played: the same draws without V2 draw more P
        bal = play_draws(model, _fault(**{**fault, "v2": 0.0}), theta, P0, Q0, q_sh, th)
        both = ref.ok & bal.ok
        assert np.max(np.abs(bal.p[both] - got.p[both])) > 1e-3


def test_the_answer_does_not_depend_on_the_threads():
    model = dynamic_model("cmld-lite", f_hz=60.0)
    event = _fault(0.4, angle_deg=10.0)
    theta, q_sh, th = _draws(model, 9, 8)
    one = play_draws(model, event, theta, P0, Q0, q_sh, th, threads=1)
    three = play_draws(model, event, theta, P0, Q0, q_sh, th, threads=3)
    for a, b in zip((one.p, one.q, one.vl, one.ok, one.stalled, one.tripped, one.iterations,
                     one.why),
                    (three.p, three.q, three.vl, three.ok, three.stalled, three.tripped,
                     three.iterations, three.why), strict=True):  # fmt: skip
        np.testing.assert_array_equal(a, b)


#: A static Q extrapolated as the stalling load's shallow fit extrapolates it
#: (``tests/statistical/test_parts_stall_threshold.py``: shares of ``x^2, x, 1`` like
#: these, their sum one): +1 at the operating point, -160 times it at 0.56 p.u.
WILD_Q = np.array([-1349.5, 2483.9, -1133.4])


def test_where_the_static_q_swings_both_paths_tell_the_same():
    # Draws 1, 3, 5, 7 get 20 % to 50 % of WILD_Q: the plain and the damped sweeps do not
    # settle them; the tries that solve each sample's load bus tell each one as the
    # reference does: its load bus's P-V equation has no root (a collapse), or the loop
    # does not settle on one operating point; then the march in time (parts_march) plays
    # or collapses them (measured: 2 collapsed and 2 failed before the march; with it 3
    # collapse, and draw 7, whose last sweep found no root, plays: its load bus rises to
    # 1.03 as V falls to 0.7, the wild Q's capacitive share lifting it). Draws that
    # settle are checked against the feeder's loop, S_L recomputed from the parts.
    model = dynamic_model("cmld-lite", f_hz=60.0)
    event = _fault(0.3)
    theta, q_sh, th = _draws(model, 8, 11)
    w = np.linspace(0.2, 0.5, 4)[:, None]
    q_sh[1::2] = w * WILD_Q + (1 - w) * np.array([0.0, 0.0, 1.0])
    got = play_draws(model, event, theta, P0, Q0, q_sh, th)
    ref = play_reference(model, event, theta, P0, Q0, q_sh, th)
    np.testing.assert_array_equal(got.why, ref.why)
    np.testing.assert_array_equal(got.iterations[ref.ok], ref.iterations[ref.ok])
    for a, b in ((got.p, ref.p), (got.q, ref.q), (got.vl, ref.vl)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8)
    assert np.sum(got.iterations[1::2] == -2) >= 1, got.iterations  # no root: a collapse
    assert np.all(got.why[got.iterations == -2] == COLLAPSES)
    th_all = model.with_thresholds(theta, th)
    for j in np.flatnonzero(got.ok):
        mj = replace(model, motor_d_params={**model.motor_d_params,
                                            **{k: float(th[k][j]) for k in ("vstall", "tstall")}},
                     vd1=float(th["vd1"][j]), vd2=float(th["vd2"][j]))  # fmt: skip
        # The loop stops where V_L moves by under 1e-7; the check recomputes S_L one step
        # on, at V - Z I, which a swinging static Q moves by |Z dI/dV_L| times as much.
        assert _loop_residual(mj, event, th_all[j], got.p[j], got.q[j], q_sh[j]) < 1e-5


@pytest.mark.parametrize("p", [0.5, 1.2, 2.4, 2.6])
def test_the_sample_solve_is_the_p_v_curve(p):
    # A constant-P load behind a reactance X = 0.2 from |V| = 1 (no dynamic part):
    # |V_L|^4 - |V_L|^2 + X^2 P^2 = 0, the upper root sqrt((1 + sqrt(1 - 4 X^2 P^2)) / 2)
    # for P up to the nose 1 / (2 X) = 2.5, none past it: NaN, the collapse.
    x = 0.2
    got = pv_root(1.0, 1.0, 1.0, complex(0.0, -x), 0j, 0.0, 0.0, p, 0.0, 0.0, 0.0, 1.0)
    ref = _pv_root(1.0, 1.0 + 0j, 1.0 + 0j, complex(0.0, x), complex(p, 0.0), [0.0, 0.0, p],
                   [0.0, 0.0, 0.0], 1.0)  # fmt: skip
    if p < 1 / (2 * x):
        exact = np.sqrt((1 + np.sqrt(1 - 4 * x * x * p * p)) / 2)
        assert abs(got - exact) < 1e-12 and abs(ref[1] - exact) < 1e-12, (got, exact)
    else:
        assert np.isnan(got) and ref is None


def _loop_residual(model, event, theta, p, q, q_sh):
    # |V - Z conj(S_L(V_L) / V_L) - V_L| at its largest: S_L from the parts at V_L.
    c = model._split(theta)
    v = event.v * np.exp(1j * event.delta)
    z = complex(model.rx, 1.0) * model.feeder_x(P0, Q0, c)
    vl = v - z * np.conj((p + 1j * q) / v)
    i0 = np.conj(complex(P0, Q0) / v[0])
    s_l0 = complex(P0, Q0) - z * abs(i0) ** 2
    ev = replace(event, v=np.abs(vl), delta=np.angle(vl))
    col_p, col_qp, _ = model.load_columns(ev, c, model.drive_of(event)[1], None)
    xl = np.abs(vl) / abs(v[0] - z * i0)
    q_s = s_l0.imag * (q_sh[0] * xl**2 + q_sh[1] * xl + q_sh[2])
    s_l = s_l0.real * col_p + 1j * (s_l0.real * col_qp + q_s)
    return float(np.max(np.abs(v - z * np.conj(s_l / vl) - vl)))


MARCH_CASES = [  # model, fault, draws, seed: point samples at 120/s (no sweep merges samples)
    ("cmld-lite", dict(depth=0.4), 16, 5),
    ("cmld-lite", dict(depth=0.4, angle_deg=20.0, recovery=0.1), 16, 6),
    ("slm", dict(depth=0.2, v2=0.15, recovery=0.1), 12, 9),
    ("cmld-lite", dict(depth=0.3, v2=0.2, with_angle=False), 12, 10),
]


@pytest.mark.parametrize(("name", "fault", "n", "seed"), MARCH_CASES)
def test_the_march_is_the_sweeps_where_they_settle(name, fault, n, seed):
    # parts_march solves the sweeps' equations sample by sample (the braking by V2 and a
    # record without an angle included): where the sweeps settle at tol 1e-12, P and Q
    # agree to 1e-9 (the sweeps' stopping rule leaves up to 100 tol in V_L, and P, Q move
    # by at most about 10 times that: tests/integration/test_predict_march.py), and the
    # march plays, collapses or fails the same draws as all five tries do. Measured: at
    # most 8.2e-12 (cmld-lite at 40 %, 8 of 13 playing draws stalled), 2.3e-12 with V2.
    model = dynamic_model(name, f_hz=60.0)
    event = _fault(**fault)
    theta, q_sh, th = _draws(model, n, seed)
    swept = play_draws(model, event, theta, P0, Q0, q_sh, th, tol=1e-12)
    marched = play_draws(model, event, theta, P0, Q0, q_sh, th, only_march=True)
    np.testing.assert_array_equal(swept.why, marched.why)
    ok = swept.ok
    assert ok.sum() >= n // 2
    for a, b in ((swept.p, marched.p), (swept.q, marched.q)):
        assert np.abs(a[ok] - b[ok]).max() < 1e-9
    np.testing.assert_array_equal(swept.stalled[ok], marched.stalled[ok])
