"""The compiled sums of a model of parts equal the NumPy channels' sums, draw for draw."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.inference.condlinear import GroupSums
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model


def _events(angle: bool, negative: bool):
    rng = np.random.default_rng(3)
    t = np.arange(0, 0.6, 1 / 60)
    out = []
    for depth in (0.15, 0.45):  # the deep one trips the electronics, stalls motor D
        v = np.where((t > 0.2) & (t < 0.3), 1 - depth, 1.0) + rng.normal(0, 1e-3, t.size)
        p = 1.0 - 0.4 * (1 - v) + rng.normal(0, 5e-3, t.size)
        q = 0.3 + 1.5 * (1 - v) + rng.normal(0, 5e-3, t.size)
        d = 0.05 * np.sin(3 * t) if angle else None
        ev = EventRecord(t, v, p, q, d, f"sag {depth}")
        if negative:
            v2 = np.where((t > 0.2) & (t < 0.3), 0.1 + 0.02j, 0.0)
            ev = ev.take(np.ones(t.size, bool))
            object.__setattr__(ev, "v2", v2.astype(complex))
            object.__setattr__(ev, "i2", (4 - 3j) * v2)
        out.append(ev)
    # A record whose rows straddling the steps were left out by its reader: gaps.
    cut = np.ones(t.size, bool)
    cut[[12, 18]] = False
    out.append(out[0].take(cut))
    return out


@pytest.mark.parametrize(
    ("name", "window", "angle", "negative"),
    [("cmld-lite", 0.0, True, True), ("cmld-lite", 1 / 60, False, False),
     ("slm", 1 / 60, True, True), ("slm", 0.0, False, True)],
)  # fmt: skip
def test_the_compiled_sums_are_the_channels_sums(name, window, angle, negative):
    model = dynamic_model(name, f_hz=60.0, window_s=window)
    events = _events(angle, negative)
    prior = model.default_prior(events)
    mean, cov, _, _ = prior.scale_free()
    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(40):
        theta = rng.multivariate_normal(mean, 0.3 * cov)
        for ev in events:
            ch = model.channels(ev, theta)
            got = model.event_sums(ev, theta)
            if ch is None or got is None:
                assert ch is None and got is None or ch is None
                continue
            want = GroupSums.from_arrays([z for z, _ in ch], [y for _, y in ch])
            for a, b in zip((want.ztz, want.zty, want.yty, want.n), got, strict=True):
                assert np.allclose(a, b, rtol=1e-9, atol=1e-9)
            checked += 1
    assert checked > 40


@pytest.mark.parametrize(("name", "window"), [("cmld-lite", 0.0), ("slm", 1 / 60)])
def test_the_motors_brake_alike_in_the_kernel_and_the_channels(name, window):
    # An unbalanced event (|V2| 0.1 through the sag): the motors brake with |V2 - Z I2|
    # (motor_kernel.brake_torque) in the compiled sums as in the NumPy channels, to 1e-9,
    # with the I2 channel off too (the braking is the motors', not the I2 data's); and
    # it moves the sums, which the same event without V2 does not give.
    from dataclasses import replace

    events = _events(True, True)
    plain = [replace(ev, v2=None, i2=None) for ev in events]  # held: the model caches by id
    for ns in ("off", "auto"):
        model = dynamic_model(name, f_hz=60.0, window_s=window, negative_sequence=ns)
        mean, cov, _, _ = model.default_prior(events).scale_free()
        rng = np.random.default_rng(5)
        checked = moved = 0
        for _ in range(12):
            theta = rng.multivariate_normal(mean, 0.1 * cov)
            for ev, ev_plain in zip(events, plain, strict=True):
                ch = model.channels(ev, theta)
                got = model.event_sums(ev, theta)
                if ch is None or got is None:
                    assert ch is None and got is None
                    continue
                want = GroupSums.from_arrays([z for z, _ in ch], [y for _, y in ch])
                for a, b in zip((want.ztz, want.zty, want.yty, want.n), got, strict=True):
                    assert np.allclose(a, b, rtol=1e-9, atol=1e-9)
                bal = model.event_sums(ev_plain, theta)
                if bal is not None:
                    moved += not np.allclose(bal[0][:2], got[0][:2], rtol=1e-6, atol=0)
                checked += 1
        assert checked >= 20 and moved >= checked // 2, (checked, moved)
