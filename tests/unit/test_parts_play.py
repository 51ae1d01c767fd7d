"""The compiled play of many draws equals ``predict_parts``, draw for draw.

``models/parts_play.play_draws`` solves each draw's feeder loop in one compiled call;
``models/parts_predict.predict_parts`` is the NumPy reference. On random draws around
the models' priors (``slm`` and ``cmld-lite``) and faults built here (a shallow sag, a
deep one that stalls motor D and trips the electronics, one with a phase jump and a
recovery ramp, a profile without an angle, window means), every draw's P, Q at the
recorded bus, the load bus's |V_L|, the sweeps the loop took, whether it converged,
whether motor D stalled and the share of the electronics tripped must agree with the
reference read as ``fit/composite/predict.py`` read it before (motor D's trajectory
against one that never stalls; the electronics' last connected share), P, Q and |V_L|
to 1e-8 p.u. Deterministic (fixed seeds); each case also asserts it saw what it is
about (stalls, trips, a failed draw where one is planted), so a vacuous pass fails.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.parts import MOTOR_D_DEFAULTS, electronics_fraction, motor_d
from loadbayes.models.parts_play import play_draws
from loadbayes.models.parts_predict import predict_parts

P0, Q0 = 0.9, 0.3


def _fault(depth, *, angle_deg=0.0, recovery=0.0, rate=120.0, end=0.8, with_angle=True):
    # A sag at 0.1 s for 0.1 s, written here (not predict_scope.sag_profile).
    t = np.arange(0.0, end, 1.0 / rate)
    share = np.where((t >= 0.1) & (t < 0.2), 1.0, 0.0)
    if recovery > 0:
        ramp = (t >= 0.2) & (t < 0.2 + recovery)
        share[ramp] = 1.0 - (t[ramp] - 0.2) / recovery
    zeros = np.zeros(t.size)
    delta = np.radians(angle_deg) * share if with_angle else None
    return EventRecord(t, 1.0 - depth * share, zeros, zeros, delta, f"sag {depth}")


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


def _reference(model, event, theta, q_sh, th, j):
    # One draw as fit/composite/predict.py played it before the compiled path.
    params = {**model.motor_d_params, "vstall": float(th["vstall"][j]),
              "tstall": float(th["tstall"][j])}  # fmt: skip
    mj = replace(model, motor_d_params=params, vd1=float(th["vd1"][j]), vd2=float(th["vd2"][j]))
    out = predict_parts(mj, event, theta[j], P0, Q0, q_sh[j])
    if out is None:
        return None
    mp, mq, its = out
    d = np.zeros(event.n) if event.delta is None else event.delta - event.delta[0]
    v = event.v * np.exp(1j * d)
    z = complex(mj.rx, 1.0) * mj.feeder_x(P0, Q0, mj._split(theta[j]))
    vl = np.abs(v - z * np.conj((mp + 1j * mq) / v))
    stalled = tripped = None
    if model.motor_d:
        kw = {**MOTOR_D_DEFAULTS, **params}
        run = motor_d(event.t, vl, **(kw | {"vstall": -1.0}))[0]
        stalled = bool(np.any(np.abs(motor_d(event.t, vl, **kw)[0] - run) > 1e-9))
    if model.electronics:
        tripped = 1.0 - float(electronics_fraction(vl, mj.vd1, mj.vd2, mj.frcel)[-1])
    return mp, mq, vl, its, stalled, tripped


CASES = [  # model, window, fault, draws, seed
    ("slm", 0.0, dict(depth=0.45), 12, 1),
    ("slm", 0.0, dict(depth=0.6, angle_deg=-25.0, recovery=0.15), 12, 2),
    ("slm", 1 / 60, dict(depth=0.3, with_angle=False), 8, 3),
    ("cmld-lite", 0.0, dict(depth=0.15), 12, 4),
    ("cmld-lite", 0.0, dict(depth=0.4), 16, 5),
    ("cmld-lite", 0.0, dict(depth=0.4, angle_deg=20.0, recovery=0.1), 16, 6),
    ("cmld-lite", 1 / 60, dict(depth=0.3, with_angle=False), 12, 7),
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
    seen = {"ok": 0, "failed": 0, "stalled": 0, "running": 0, "tripped": 0}
    for j in range(n):
        ref = _reference(model, event, theta, q_sh, th, j)
        if ref is None:
            assert not got.ok[j] and np.isnan(got.p[j]).all()
            seen["failed"] += 1
            continue
        assert got.ok[j], j
        seen["ok"] += 1
        mp, mq, vl, its, stalled, tripped = ref
        np.testing.assert_allclose(got.p[j], mp, rtol=0, atol=1e-8)
        np.testing.assert_allclose(got.q[j], mq, rtol=0, atol=1e-8)
        np.testing.assert_allclose(got.vl[j], vl, rtol=0, atol=1e-8)
        assert got.iterations[j] == its
        if model.motor_d:
            assert got.stalled[j] == stalled
            seen["stalled" if stalled else "running"] += 1
        if model.electronics:
            assert abs(got.tripped[j] - tripped) <= 1e-8
            seen["tripped"] += tripped > 0.01
    assert seen["failed"] >= 1 and seen["ok"] >= n // 2, seen
    if model.motor_d and fault["depth"] >= 0.4:  # deep: some draws stall, some ride through
        assert seen["stalled"] >= 1 and seen["running"] >= 1, seen
        assert seen["tripped"] >= 1, seen
    if model.motor_d and fault["depth"] < 0.2:  # shallow: above every stall voltage drawn
        assert seen["stalled"] == 0, seen


def test_the_answer_does_not_depend_on_the_threads():
    model = dynamic_model("cmld-lite", f_hz=60.0)
    event = _fault(0.4, angle_deg=10.0)
    theta, q_sh, th = _draws(model, 9, 8)
    one = play_draws(model, event, theta, P0, Q0, q_sh, th, threads=1)
    three = play_draws(model, event, theta, P0, Q0, q_sh, th, threads=3)
    for a, b in zip((one.p, one.q, one.vl, one.ok, one.stalled, one.tripped, one.iterations),
                    (three.p, three.q, three.vl, three.ok, three.stalled, three.tripped,
                     three.iterations), strict=True):  # fmt: skip
        np.testing.assert_array_equal(a, b)
