"""The negative sequence as data: the reader's V2 and I2 against an independent record.

The record is :mod:`sequence_generator`'s (SciPy and NumPy, no loadbayes): three-phase
waveforms of a static ZIP part and two third-order induction motors at a bus through a
phase-A-to-ground fault, written as COMTRADE by the tests' own writer. Its sequence
phasors are known at every sample, so the reader's ``v2_re .. i2_im`` are checked
against physics the package did not compute, and the event file and ``EventRecord``
carry them unchanged.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.io.errors import DataError
from loadbayes.measurements.events import read_events
from loadbayes.measurements.record import UNBALANCE_LIMIT, EventRecord
from loadbayes.recordings.comtrade import read_comtrade
from loadbayes.recordings.phasor_fit import fit_phasors
from loadbayes.recordings.record import record_table
from sequence_generator import write_record

F_HZ, V_BASE, S_BASE = 50.0, 110.0, 40.0
A = np.exp(2j * np.pi / 3)


def _clean(t: np.ndarray, truth: dict, rate: float) -> np.ndarray:
    """Rows whose one-cycle window lies wholly on one side of each step of the fault."""
    steps = np.array([truth["fault"]["t_on_s"], truth["fault"]["t_off_s"]])
    return np.all(np.abs(t[:, None] - steps[None, :]) > 0.5 / F_HZ + 1.0 / rate, axis=1)


def _read(tmp_path, rate: float, per_cycle: int, dc: str = "auto", **kw):
    cfg, rec = write_record(tmp_path / "gen", rate_hz=rate, f_hz=F_HZ, v_base_kv=V_BASE,
                            s_base_mva=S_BASE, **kw)  # fmt: skip
    w = read_comtrade(str(cfg))
    tab = record_table(w, per_cycle=per_cycle, v_base_kv=V_BASE, s_base_mva=S_BASE,
                       source=str(cfg), dc=dc)  # fmt: skip
    return cfg, rec, tab.columns


@pytest.mark.parametrize(("rate", "per_cycle"), [(3200.0, 4), (1000.0, 2)])
def test_reader_gives_the_generators_v2_and_i2(tmp_path, rate, per_cycle):
    # Tolerances. V2: the noise (0.05% of the peak per sample) gives each sequence
    # phasor an sd of about 0.0005 sqrt(2/N) / sqrt(3) p.u. (N samples per cycle): under
    # 1e-4 p.u. at 20-64 per cycle; 1e-3 is ten of those. I2: the noise (0.1%) gives
    # 1-2e-4; besides, a one-cycle phasor of a current that moves (the motors' flux
    # decaying after the fault's steps, dI1/dt up to ~15 p.u./s) lets its mirror,
    # about j conj(dI1/dt) exp(-2j w t) / (2 w) = 0.02 p.u., into the negative sequence;
    # the reader takes it out from the neighbouring windows (recordings/sequences.py),
    # measured to leave at most 7e-4 here (1e-4 without noise): 1.5e-3 bounds it with
    # room for the noise. At --per-cycle 1 (neighbours a cycle apart) 4e-3 is left.
    _, rec, c = _read(tmp_path, rate, per_cycle)
    t = c["t_s"]
    clean = _clean(t, rec.truth, rate)
    assert clean.sum() >= 0.85 * t.size
    v2 = c["v2_re"] + 1j * c["v2_im"]
    i2 = c["i2_re"] + 1j * c["i2_im"]
    assert np.abs(v2 - rec.at(t, "v2"))[clean].max() < 1e-3
    assert np.abs(i2 - rec.at(t, "i2"))[clean].max() < 1.5e-3
    # The frame is angle_rad's: V1 = v exp(j angle_rad) is the generator's V1.
    v1 = c["v"] * np.exp(1j * c["angle_rad"])
    assert np.abs(v1 - rec.at(t, "v1"))[clean].max() < 1e-3
    # The per-unit system: the balanced pre-fault power is V1 conj(I1) in these units.
    pre = t < rec.truth["fault"]["t_on_s"] - 0.5 / F_HZ
    s1 = rec.at(t, "v1") * np.conj(rec.at(t, "i1"))
    assert np.abs(c["p"] + 1j * c["q"] - s1)[pre].max() < 1e-3
    # In the fault, clean rows are unbalanced and their I2 / V2 is the mix's Y2.
    fault = clean & (c["v2"] > UNBALANCE_LIMIT)
    assert fault.sum() >= per_cycle
    y_true = np.interp(t[fault], rec.t, rec.truth["y2_series"].real) + 1j * np.interp(
        t[fault], rec.t, rec.truth["y2_series"].imag
    )
    assert np.abs((i2 / v2)[fault] / y_true - 1).max() < 0.005
    # Before the fault: no negative sequence in either.
    assert np.abs(v2[pre]).max() < 1e-3 and np.abs(i2[pre]).max() < 2e-3


def test_the_mirror_taken_out_is_the_estimators_physics(tmp_path):
    # Without noise: the plain one-cycle I2 (its magnitude is the ratio column i2 times
    # |I1|) errs by the mirror derived from the generator's own dI1/dt, and the phasor
    # column has it taken out. So the correction is the estimator's physics, not a fit
    # to this record.
    # (--dc off: without noise the decaying-offset test finds any misfit significant,
    # and the reader leaves the mirror in the windows the filter reads.)
    _, rec, c = _read(tmp_path, 3200.0, 4, dc="off", noise_v=0.0, noise_i=0.0)
    assert not c["dc_filtered"].any()
    t = c["t_s"]
    clean = _clean(t, rec.truth, 3200.0)
    w = 2 * math.pi * F_HZ
    h = 2 / 3200.0  # the window centres are sample instants: differences of samples
    i1 = [rec.at(t + k * h, "i1") for k in (-1, 0, 1)]
    d1, d2 = (i1[2] - i1[0]) / (2 * h), (i1[2] - 2 * i1[1] + i1[0]) / h**2
    # The window's 64 samples at c - T/2 + n dt weigh the ramp and the curvature of the
    # exp(-j w t) half of each phase's cosine by these sums (-> j / (2 w) and 1 / (4 w^2)
    # as dt -> 0); over the three phases the mirrors form a negative sequence.
    tau = (np.arange(64) - 32) / 3200.0
    k1 = np.mean(tau * np.exp(-2j * w * tau))
    k2 = np.mean(tau**2 / 2 * np.exp(-2j * w * tau))
    mirror = (np.conj(d1) * k1 + np.conj(d2) * k2) * np.exp(-2j * w * t)
    moving = clean & (np.abs(mirror) > 5e-3)
    assert moving.sum() >= 8  # the motors' flux moves enough after both steps to matter
    i2_true = rec.at(t, "i2")
    # The plain one-cycle phasors of the same windows (the reader's estimator, before
    # the sequences are taken): their I2 is the truth plus the mirror.
    w_ = read_comtrade(str(tmp_path / "gen.cfg"))
    fit = fit_phasors(w_.t_s, np.vstack([w_.v, w_.i]), f0=F_HZ, per_cycle=4, dc="off",
                      step_channels=3)  # fmt: skip
    assert np.allclose(fit.t_s, t)
    i_base = S_BASE * 1e6 / (3 * V_BASE * 1e3 / math.sqrt(3))
    plain = (fit.x[3] + A**2 * fit.x[4] + A * fit.x[5]) / 3 / i_base
    # Measured: the mirror predicted to 2.4% of it (what is left are the higher
    # derivatives of the decaying flux), and the reader leaves 1.8% of it (its
    # derivatives are from the neighbouring windows): 5% for both.
    gap = np.abs(plain - i2_true - mirror)[moving]
    assert np.all(gap < 0.05 * np.abs(mirror[moving]))
    assert np.all(np.abs(plain - i2_true)[moving] > 0.8 * np.abs(mirror[moving]))
    err = np.abs(c["i2_re"] + 1j * c["i2_im"] - i2_true)[moving]
    assert np.all(err < 0.05 * np.abs(mirror[moving]))


def test_truth_of_the_mix_is_the_motors_own_circuit():
    # The generator's recorded truth, against the equivalent circuit by hand.
    from sequence_generator import generate

    t, seq_v, seq_i, y2, truth = generate(f_hz=F_HZ, rate_hz=1000.0)
    (m1, m2) = truth["motors"]
    for m in (m1, m2):
        s = m["s0"]
        rotor = m["rr"] / (2 - s) + 1j * m["xr"]
        z2 = m["rs"] + 1j * m["xs"] + 1j * m["xm"] * rotor / (1j * m["xm"] + rotor)
        assert complex(m["y2_motor_base"]) == pytest.approx(1 / z2)
        # The approximate form differs by the magnetising branch: a few per cent.
        assert abs(m["y2_approx_motor_base"] / m["y2_motor_base"] - 1) < 0.05
    motors = m1["rating"] * m1["y2_motor_base"] + m2["rating"] * m2["y2_motor_base"]
    expect = truth["zip"]["y2"] + motors
    assert truth["y2_prefault"] == pytest.approx(expect)
    assert truth["motor_rating_total"] == pytest.approx(0.8)
    # The steady state before the fault: S = V1 conj(I1) is the truth's P0 + jQ0.
    assert seq_v[1, 0] * np.conj(seq_i[1, 0]) == pytest.approx(truth["p0"] + 1j * truth["q0"])
    # Several times a static load's |Y2| (about |S0|): what the motors add.
    assert abs(truth["y2_over_p0"]) > 3
    # One motor: the same bookkeeping.
    from sequence_generator import Motor

    one = Motor(rating=0.6, h_s=0.3, torque_exp=2)
    *_, y2_one, t1 = generate(f_hz=60.0, rate_hz=1920.0, motors=(one,))
    assert t1["y2_prefault"] == pytest.approx(t1["zip"]["y2"] + 0.6 / one.z2(one.s0))
    assert np.abs(y2_one / t1["y2_prefault"] - 1).max() < 0.01  # the slip barely moves


def test_event_file_and_event_record_carry_v2_and_i2(tmp_path):
    cfg, rec, _ = _read(tmp_path, 3200.0, 4)
    runner = CliRunner()
    res = runner.invoke(main, ["read", "comtrade", str(cfg), "--per-cycle", "4", "--v-base",
                               str(V_BASE), "--s-base", str(S_BASE), "--out",
                               str(tmp_path / "rec.csv"), "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    table = pd.read_csv(tmp_path / "rec.csv", float_precision="round_trip")
    res = runner.invoke(main, ["events", str(tmp_path / "rec.csv"), "--out",
                               str(tmp_path / "ev"), "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    ev_file = tmp_path / "ev" / "event_001.csv"
    frame = pd.read_csv(ev_file, float_precision="round_trip")
    assert {"v2", "i2", "v2_re", "v2_im", "i2_re", "i2_im"} <= set(frame.columns)
    (ev,) = read_events([str(ev_file)], f_hz=F_HZ)
    v2_file = frame["v2_re"].to_numpy() + 1j * frame["v2_im"].to_numpy()
    i2_file = frame["i2_re"].to_numpy() + 1j * frame["i2_im"].to_numpy()
    assert ev.v2 is not None and ev.i2 is not None
    assert np.array_equal(ev.v2, v2_file) and np.array_equal(ev.i2, i2_file)
    # The record is shorter than the window kept around its sag: the event is every
    # phasor row, the same numbers as the table's (CSV keeps every digit of a float).
    assert ev.n == len(table)
    for col, x in (("v2_re", ev.v2.real), ("v2_im", ev.v2.imag), ("i2_re", ev.i2.real),
                   ("i2_im", ev.i2.imag)):  # fmt: skip
        # (to 1e-16: the tables' CSV writer keeps 16 decimals, and `events` reads with
        # pandas' fast parser)
        assert np.allclose(x, table[col].to_numpy(), rtol=1e-13, atol=1e-15), col
    # Against the generator: the event's times are from its first row.
    t_rec = frame["t_s"].to_numpy() + table["t_s"].to_numpy()[0]
    clean = _clean(t_rec, rec.truth, 3200.0)
    assert np.abs(ev.v2 - rec.at(t_rec, "v2"))[clean].max() < 1e-3
    assert np.abs(ev.i2 - rec.at(t_rec, "i2"))[clean].max() < 1.5e-3
    # The event is unbalanced, and its Y2 is the mix's where V2 is meaningful.
    assert ev.unbalanced
    y2 = ev.y2
    assert y2 is not None and y2.shape == ev.v.shape
    on = np.isfinite(y2)
    assert np.array_equal(on, np.abs(ev.v2) / ev.v > UNBALANCE_LIMIT)
    good = on & clean
    assert good.sum() >= 4
    assert np.median(np.abs(y2[good])) == pytest.approx(abs(rec.truth["y2_prefault"]), rel=0.01)


def _event_table(n: int = 40) -> dict:
    t = np.arange(n) / 100.0
    v = np.where((t > 0.1) & (t < 0.2), 0.85, 1.0)
    fault = (t > 0.1) & (t < 0.2)
    return {
        "t_s": t, "v": v, "p": 0.9 * v**2, "q": 0.3 * v**2,
        "v2_re": np.where(fault, 0.1, 0.01), "v2_im": np.zeros(n),
        "i2_re": np.where(fault, 0.3, 0.0), "i2_im": np.where(fault, -0.4, 0.02),
    }  # fmt: skip


def test_event_record_sequence_properties(tmp_path):
    path = tmp_path / "e.csv"
    pd.DataFrame(_event_table()).to_csv(path, index=False)
    (ev,) = read_events([str(path)], f_hz=50.0)
    assert ev.unbalanced
    y2 = ev.y2
    fault = (ev.t > 0.1) & (ev.t < 0.2)
    assert np.all(np.isnan(y2[~fault]))  # 1% of V1: the supply's unbalance, no admittance
    assert y2[fault] == pytest.approx(np.full(fault.sum(), (0.3 - 0.4j) / 0.1))
    # Without the columns: no negative sequence, and nothing else changes.
    plain = {k: v for k, v in _event_table().items() if not k.startswith(("v2", "i2"))}
    pd.DataFrame(plain).to_csv(tmp_path / "p.csv", index=False)
    (ev0,) = read_events([str(tmp_path / "p.csv")], f_hz=50.0)
    assert ev0.v2 is None and ev0.i2 is None and ev0.y2 is None and not ev0.unbalanced
    assert np.array_equal(ev0.p, ev.p) and np.array_equal(ev0.v, ev.v)
    # A subset keeps every per-sample field in step.
    part = ev.take(np.flatnonzero(ev.t > 0.15))
    assert part.n == part.v2.size == part.i2.size == int(np.sum(ev.t > 0.15))
    assert part.y2 == pytest.approx(y2[ev.t > 0.15], nan_ok=True)
    # Balanced throughout: not unbalanced, y2 all NaN.
    bal = EventRecord(ev.t, ev.v, ev.p, ev.q, v2=np.full(ev.n, 0.02 + 0j), i2=np.zeros(ev.n))
    assert not bal.unbalanced and np.all(np.isnan(bal.y2))


def test_one_sequence_column_missing_is_refused_by_name(tmp_path):
    table = _event_table()
    del table["i2_im"]
    path = tmp_path / "e.csv"
    pd.DataFrame(table).to_csv(path, index=False)
    with pytest.raises(DataError) as err:
        read_events([str(path)], f_hz=50.0)
    assert err.value.column == "i2_im" and "e.csv" in str(err.value)
    # A cell that is not a number: file, column and row.
    table = _event_table()
    bad = pd.DataFrame(table)
    bad["v2_im"] = bad["v2_im"].astype(object)
    bad.loc[6, "v2_im"] = "x"
    bad.to_csv(path, index=False)
    with pytest.raises(DataError) as err:
        read_events([str(path)], f_hz=50.0)
    assert err.value.column == "v2_im" and err.value.row == 7


def test_bases_scale_the_sequence_as_v_and_p_over_v(tmp_path):
    # Data in kV and MW: V2 in the units of v, I2 in those of p over v.
    table = _event_table()
    kv, mva = 110.0, 40.0
    scaled = dict(table, v=table["v"] * kv, p=table["p"] * mva, q=table["q"] * mva,
                  v2_re=table["v2_re"] * kv, v2_im=table["v2_im"] * kv,
                  i2_re=table["i2_re"] * mva / kv, i2_im=table["i2_im"] * mva / kv)  # fmt: skip
    pd.DataFrame(scaled).to_csv(tmp_path / "kv.csv", index=False)
    pd.DataFrame(table).to_csv(tmp_path / "pu.csv", index=False)
    (a,) = read_events([str(tmp_path / "kv.csv")], v_base=kv, s_base=mva, f_hz=50.0)
    (b,) = read_events([str(tmp_path / "pu.csv")], f_hz=50.0)
    assert a.v2 == pytest.approx(b.v2) and a.i2 == pytest.approx(b.i2)


def test_pmu_per_phase_phasors_give_v2_and_i2_through_events(tmp_path):
    # A PMU's per-phase phasors (100 reports/s, kV and kA, degrees) of the generated
    # fault: the reader's V2, I2 are the generator's exactly (no window here), and
    # `events` on its table carries them into the event file and EventRecord.
    from loadbayes.recordings.pmu import load_map, read_pmu
    from sequence_generator import generate

    t, seq_v, seq_i, _, truth = generate(f_hz=F_HZ, rate_hz=1000.0)
    keep = slice(0, None, 10)
    t, seq_v, seq_i = t[keep], seq_v[:, keep], seq_i[:, keep]
    v_ph = V_BASE / math.sqrt(3)  # kV
    i_b = S_BASE / (3 * v_ph)  # kA
    phase = np.array([[1, 1, 1], [1, A**2, A], [1, A, A**2]])  # a, b, c from 0, 1, 2
    vph, iph = phase @ seq_v * v_ph, phase @ seq_i * i_b
    df = pd.DataFrame({"timestamp": pd.Timestamp("2026-01-01", tz="UTC") + pd.to_timedelta(t, "s")})
    df["timestamp"] = df["timestamp"].map(lambda x: x.isoformat())
    for k, ph in enumerate("abc"):
        df[f"v{ph}_mag"], df[f"v{ph}_ang"] = np.abs(vph[k]), np.degrees(np.angle(vph[k]))
        df[f"i{ph}_mag"], df[f"i{ph}_ang"] = np.abs(iph[k]), np.degrees(np.angle(iph[k]))
    df.to_csv(tmp_path / "pmu.csv", index=False)
    cols = {f"{x}_{k}": ",".join(f"{x[0]}{ph}_{k}" for ph in "abc")
            for x in ("v", "i") for k in ("mag", "ang")}  # fmt: skip
    m = load_map(None, voltage="kV", current="kA", v_kv=V_BASE, s_mva=S_BASE, **cols)
    rec = read_pmu(tmp_path / "pmu.csv", m)
    d = rec.data
    assert d["v2_re"] + 1j * d["v2_im"] == pytest.approx(seq_v[2], abs=1e-9)
    assert d["i2_re"] + 1j * d["i2_im"] == pytest.approx(seq_i[2], abs=1e-9)
    v1 = d["v"] * np.exp(1j * d["angle_rad"])  # the frame of angle_rad
    assert v1 == pytest.approx(seq_v[1], abs=1e-9)
    # A positive-sequence PMU has no negative sequence: no columns.
    m1 = load_map(None, voltage="kV", current="kA", v_kv=V_BASE, s_mva=S_BASE,
                  v_mag="va_mag", v_ang="va_ang", i_mag="ia_mag", i_ang="ia_ang")  # fmt: skip
    assert "v2_re" not in read_pmu(tmp_path / "pmu.csv", m1).data
    pd.DataFrame(d).to_csv(tmp_path / "pmu_pu.csv", index=False)
    res = CliRunner().invoke(main, ["events", str(tmp_path / "pmu_pu.csv"), "--out",
                                    str(tmp_path / "ev"), "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    (ev,) = read_events([str(tmp_path / "ev" / "event_001.csv")], f_hz=F_HZ)
    assert ev.n == t.size and ev.v2 == pytest.approx(seq_v[2], abs=1e-12)
    assert ev.unbalanced
    fault = np.isfinite(ev.y2)
    assert fault.sum() >= 5
    assert ev.y2[fault] == pytest.approx(truth["y2_series"][keep][fault], rel=1e-9)


def test_a_table_given_to_fit_composite_carries_its_negative_sequence():
    # fit_composite(data=DataFrame) reads its events with read(): the columns, when all
    # four are there, become each event's v2 and i2 (split by the event column too).
    from loadbayes.core.settings import DataSpec
    from loadbayes.fit.composite.api import read

    one = pd.DataFrame(_event_table())
    two = pd.concat([one.assign(event=1), one.assign(event=2, p=one["p"] * 1.01)])
    a, b = read(two, DataSpec(), f_hz=50.0)
    assert a.v2 == pytest.approx(one["v2_re"].to_numpy() + 1j * one["v2_im"].to_numpy())
    assert b.i2 == pytest.approx(one["i2_re"].to_numpy() + 1j * one["i2_im"].to_numpy())
    assert a.unbalanced and b.unbalanced
    (plain,) = read(one.drop(columns=["v2_re", "v2_im", "i2_re", "i2_im"]), f_hz=50.0)
    assert plain.v2 is None and plain.i2 is None
    with pytest.raises(DataError) as err:
        read(one.drop(columns=["v2_im"]), f_hz=50.0)
    assert err.value.column == "v2_im"
