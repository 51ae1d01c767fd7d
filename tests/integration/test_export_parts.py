"""A model of parts (slm, cmld-lite) out to PSS/E's CMLDBLU2, pandapower, and refused by ANDES.

The posterior is written here (NumPy draws: shares from a Dirichlet, motors around the
WECC typical motors A and B), not by a fit. The expected record is computed here: the
recorded bus's power by solving the feeder's circuit with SciPy (``fsolve``), the
fractions as the draws' medians, and the CMLDBLU1 layout of the tests' GridDyn harness
(``loadbayes.cases.griddyn/cmld.py``), which CMLDBLU2's first 132 CONs must follow; GridDyn
runs the exported record (skipped, saying why, without its environment) and the fit's own
prediction of the same numbers is held to its P. The
held-out playback of an ``slm`` fit is checked against the tests' own SciPy feeder
simulator (``tests/feeder_generator.py``) with the posterior at its truth.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.optimize import fsolve

from loadbayes.cases.griddyn.cmld import Cmld, Motor3, MotorD
from loadbayes.cli import main
from loadbayes.export.cmld import CON_NAMES, read_cmldblu2
from loadbayes.export.psse import read_loads
from loadbayes.models.dynamic import dynamic_model
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration

S = 100.0
SHAPE = (2, 200)
MOTOR = {"a": {"rs": 0.04, "x_open": 1.8, "x_prime": 0.12, "t_prime_s": 0.095, "h_s": 0.1,
               "t0": 0.6},
         "b": {"rs": 0.03, "x_open": 1.8, "x_prime": 0.19, "t_prime_s": 0.2, "h_s": 0.5,
               "t0": 0.7}}  # fmt: skip


def _posterior(path, model: str, rs_a: float = 0.04):
    rng = np.random.default_rng(11)
    opts = dynamic_model(model, f_hz=50.0).options()
    tags = ["_a", "_b"] if model == "cmld-lite" else [""]
    parts = ["f_m_a", "f_m_b", "f_d", "f_el", "f_s"] if model == "cmld-lite" else ["f_m", "f_s"]
    alpha = [20, 25, 8, 10, 37] if model == "cmld-lite" else [40, 60]
    shares = rng.dirichlet(alpha, SHAPE)
    draws = {n: shares[..., k] for k, n in enumerate(parts)}
    zip_p = rng.dirichlet([30, 30, 40], SHAPE)
    draws |= {"a1": zip_p[..., 0], "a2": zip_p[..., 1], "a3": zip_p[..., 2]}
    for t, cls in zip(tags, ("a", "b"), strict=False):
        for k, v in MOTOR[cls].items():
            draws[k + t] = v * np.exp(0.1 * rng.standard_normal(SHAPE))
    if model == "cmld-lite":
        draws["rs_a"] = rs_a * np.exp(0.05 * rng.standard_normal(SHAPE))
    x_fd = 0.06 * np.exp(0.2 * rng.standard_normal(SHAPE))
    draws |= {"x_fd": x_fd, "r_fd": opts["rx"] * x_fd, "v0": np.full(SHAPE, 0.99),
              "p0": 0.9 + 0.01 * rng.standard_normal(SHAPE),
              "cq2": -0.2 + 0.02 * rng.standard_normal(SHAPE),
              "cq1": 0.3 + 0.02 * rng.standard_normal(SHAPE),
              "cq0": 0.2 + 0.02 * rng.standard_normal(SHAPE),
              "tau_p": np.full(SHAPE, 4e4), "tau_q": np.full(SHAPE, 4e4)}  # fmt: skip
    draws["q0"] = draws["cq2"] + draws["cq1"] + draws["cq0"]
    settings = {"model": model, "model_options": opts, "s_base_mva": S, "v_base_kv": 110.0,
                "f_hz": 50.0}  # fmt: skip
    Posterior(draws, model="composite", method="test", settings=settings).to_netcdf(path)
    return {k: np.asarray(v).reshape(-1) for k, v in draws.items()}, opts


def _export(*args):
    return CliRunner().invoke(main, ["export", *map(str, args)])


def _recorded(p0, q0, r, x, v):
    """The recorded bus's S (system p.u.): the load behind r + jx on the base |S|."""

    def eq(z):
        s_rec = complex(*z)
        s = abs(s_rec)
        loss = complex(r, x) / s * (s / v) ** 2
        d = s_rec - loss - complex(p0, q0)
        return [d.real, d.imag]

    return complex(*fsolve(eq, [p0, q0], xtol=1e-13))


@pytest.fixture(scope="module")
def cmld_lite(tmp_path_factory):
    folder = tmp_path_factory.mktemp("parts")
    draws, opts = _posterior(folder / "fit.nc", "cmld-lite")
    res = _export(folder / "fit.nc", "--to", "psse", "--out", folder / "case.raw")
    assert res.exit_code == 0, res.output
    med = {k: float(np.median(v)) for k, v in draws.items()}
    return folder, read_cmldblu2(folder / "case.dyr"), med, opts, res.output


def test_every_fraction_is_the_median_and_they_sum_to_one(cmld_lite):
    _, rec, med, _, _ = cmld_lite
    for con, name in (("Fma", "f_m_a"), ("Fmb", "f_m_b"), ("Fmd", "f_d"), ("Fel", "f_el")):
        assert rec[con] == pytest.approx(med[name], rel=1e-9)
    assert rec["Fmc"] == 0.0
    static = 1 - sum(rec[k] for k in ("Fma", "Fmb", "Fmc", "Fmd", "Fel"))
    assert 0 < static < 1
    # The medians of the shares do not sum to 1; the record's static part takes the rest.
    assert static == pytest.approx(med["f_s"], abs=0.02)
    assert (rec["P1c"], rec["P2c"]) == pytest.approx((med["a1"], med["a2"]), rel=1e-9)
    assert (rec["P1e"], rec["P2e"]) == (2.0, 1.0)


def test_motors_and_motor_d_and_electronics(cmld_lite):
    _, rec, med, opts, _ = cmld_lite
    for m in "AB":
        t = "_" + m.lower()
        got = [rec[f"{k}{m}"] for k in ("Rs", "Ls", "Lp", "Lpp", "Tpo", "H")]
        want = [med[k + t] for k in ("rs", "x_open", "x_prime", "x_prime", "t_prime_s", "h_s")]
        assert got == pytest.approx(want, rel=1e-9)
        assert rec[f"Mtp{m}"] == 3.0 and 0.3 < rec[f"LFm{m}"] < 1.5
    assert (rec["EtrqA"], rec["EtrqB"]) == (0.0, 2.0)
    d = opts["motor_d_params"]
    for con, key in (("Vstall", "vstall"), ("Tstall", "tstall"), ("Rstall", "rstall"),
                     ("Xstall", "xstall"), ("Frst", "frst"), ("Vrst", "vrst"),
                     ("Trst", "trst"), ("CompPF", "comp_pf"), ("Vbrk", "vbrk")):  # fmt: skip
        assert rec[con] == d[key], con
    assert (rec["Vd1"], rec["Vd2"], rec["Frcel"]) == (opts["vd1"], opts["vd2"], opts["frcel"])


def test_feeder_on_the_load_base_and_the_power_flow_load(cmld_lite):
    folder, rec, med, _, _ = cmld_lite
    s_rec = _recorded(med["p0"], med["q0"], med["r_fd"], med["x_fd"], med["v0"])
    assert rec["MVA"] == pytest.approx(abs(s_rec) * S, rel=1e-8)
    assert rec["Rfdr"] == pytest.approx(med["r_fd"], rel=1e-9)
    # The lumped X: the feeder's X equal to its R, the transformer's the rest.
    assert rec["Xfdr"] == pytest.approx(med["r_fd"], rel=1e-9)
    assert rec["Xfdr"] + rec["Xxf"] == pytest.approx(med["x_fd"], rel=1e-9)
    assert (rec["Fb"], rec["Bss"], rec["LTC"]) == (0.0, 0.0, 0.0)
    load = read_loads(folder / "case.raw")["1"]
    assert (load["pl"], load["ql"]) == pytest.approx((s_rec.real * S, s_rec.imag * S), rel=1e-8)
    # The static part's Q: the load bus's q0, split as its cq terms.
    ps = (1 - sum(rec[k] for k in ("Fma", "Fmb", "Fmd", "Fel"))) * med["p0"]
    assert rec["PFs"] == pytest.approx(ps / math.hypot(ps, med["q0"]), rel=1e-9)
    assert rec["Q1c"] == pytest.approx(med["cq2"] / med["q0"], rel=1e-9)
    assert rec["Q2c"] == pytest.approx(med["cq1"] / med["q0"], rel=1e-9)


def test_the_first_132_cons_are_the_griddyn_harness_cmldblu1_layout(cmld_lite):
    """CMLDBLU2 = CMLDBLU1's 132 CONs + Frcel: the harness's record from our numbers."""
    folder, rec, _, _, _ = cmld_lite

    def motor(m):
        return Motor3(lfm=rec[f"LFm{m}"], rs=rec[f"Rs{m}"], ls=rec[f"Ls{m}"], lp=rec[f"Lp{m}"],
                      tpo_s=rec[f"Tpo{m}"], h_s=rec[f"H{m}"], etrq=rec[f"Etrq{m}"])  # fmt: skip

    ours = [rec[n] for n in CON_NAMES]
    theirs = Cmld(
        f_a=rec["Fma"], f_b=rec["Fmb"], f_d=rec["Fmd"], f_el=rec["Fel"],
        motor_a=motor("A"), motor_b=motor("B"),
        motor_d=MotorD(lfm=rec["CompLF"], comp_pf=rec["CompPF"], vstall=rec["Vstall"],
                       rstall=rec["Rstall"], xstall=rec["Xstall"], tstall_s=rec["Tstall"],
                       trst_s=rec["Trst"], frst=rec["Frst"], vrst=rec["Vrst"]),
        r_fdr=rec["Rfdr"], x_fdr=rec["Xfdr"], fb=rec["Fb"], x_xf=rec["Xxf"], tap_ls=1.0,
        pf_el=rec["PFel"], vd1=rec["Vd1"], vd2=rec["Vd2"], pf_s=rec["PFs"],
        p1c=rec["P1c"], p2c=rec["P2c"], q1c=rec["Q1c"], q2c=rec["Q2c"],
    ).cons()  # fmt: skip
    assert len(ours) == 133 and len(theirs) == 132
    assert CON_NAMES[132] == "Frcel"
    # Where the harness takes our numbers, the positions agree one by one: the feeder
    # (2-5), the fractions and PFs (18-26), each motor's circuit (A 37-46, B 57-66),
    # motor D's stall and its fixed constants (97-98, 101-119).
    same = [*range(2, 6), *range(18, 27), *range(37, 43), 43, 45, 46, *range(57, 63), 63,
            65, 66, 97, 98, *range(101, 120)]  # fmt: skip
    for k in same:
        assert ours[k] == pytest.approx(theirs[k], rel=1e-12), CON_NAMES[k]
    # The static polynomial's pairs: PSS/E's and PSLF's order (GridPACK's parser,
    # TDcoSim's table, InterPSS's reader) is exponent then coefficient (P1e, P1c, ...);
    # GridDyn 0.13's reader, and so its harness, takes coefficient then exponent.
    for e, c in ((27, 28), (29, 30), (32, 33), (34, 35)):
        assert (ours[e], ours[c]) == pytest.approx((theirs[c], theirs[e]), rel=1e-12)
    # Where they differ, by design: the MVA (ours |S| in MVA, the harness a loading
    # factor), Tppo (ours Tpo/100, GridDyn's 0) and motor D's filter Tv and relays.
    assert ours[0] > 0 > theirs[0]


def test_the_warnings_and_the_comments(tmp_path):
    _posterior(tmp_path / "fit.nc", "cmld-lite", rs_a=0.15)
    res = _export(tmp_path / "fit.nc", "--to", "psse", "--out", tmp_path / "c.raw")
    assert res.exit_code == 0, res.output
    cite = "(WECC composite load model; IEEE load task force 1995)"
    said = "motor A stator resistance Rs (p.u.) = 0.1498 is outside the published range"
    assert said in res.output and cite in res.output
    dyr = (tmp_path / "c.dyr").read_text()
    assert said in dyr and "transformer Xxf" in dyr and "Fb 0" in dyr
    assert "# loadbayes cmld-lite:" in (tmp_path / "c.dyd").read_text()


def test_draws_each_sum_to_one(tmp_path):
    draws, _ = _posterior(tmp_path / "fit.nc", "cmld-lite")
    res = _export(tmp_path / "fit.nc", "--to", "psse", "--out", tmp_path / "d.raw", "--draws", 3)
    assert res.exit_code == 0, res.output
    for k in (1, 2, 3):
        rec = read_cmldblu2(tmp_path / f"d_draw{k:03d}.dyr")
        i = int(np.flatnonzero(np.isclose(draws["f_m_a"], rec["Fma"], rtol=1e-9))[0])
        assert rec["Fmb"] == pytest.approx(draws["f_m_b"][i], rel=1e-9)
        static = 1 - sum(rec[n] for n in ("Fma", "Fmb", "Fmd", "Fel"))
        assert static == pytest.approx(draws["f_s"][i], abs=1e-9)  # one draw's shares


def test_slm_is_motor_a_alone(tmp_path):
    draws, _ = _posterior(tmp_path / "fit.nc", "slm")
    res = _export(tmp_path / "fit.nc", "--to", "psse", "--out", tmp_path / "s.raw")
    assert res.exit_code == 0, res.output
    rec = read_cmldblu2(tmp_path / "s.dyr")
    assert rec["Fma"] == pytest.approx(float(np.median(draws["f_m"])), rel=1e-9)
    assert rec["Fmb"] == rec["Fmd"] == rec["Fel"] == 0.0
    assert rec["RsA"] == pytest.approx(float(np.median(draws["rs"])), rel=1e-9)


def test_pandapower_holds_the_power_flow(cmld_lite, tmp_path):
    import pandapower as pp

    folder, _, med, _, _ = cmld_lite
    res = _export(folder / "fit.nc", "--to", "pandapower", "--out", tmp_path / "n.json")
    assert res.exit_code == 0, res.output
    load = pp.from_json(str(tmp_path / "n.json")).load.iloc[0]
    s_rec = _recorded(med["p0"], med["q0"], med["r_fd"], med["x_fd"], med["v0"])
    assert (load.p_mw, load.q_mvar) == pytest.approx((s_rec.real * S, s_rec.imag * S), rel=1e-7)
    assert "not in the net" in (tmp_path / "n.json.summary.txt").read_text()


@pytest.mark.parametrize("model", ["cmld-lite", "slm"])
def test_andes_refuses_in_one_line(tmp_path, model):
    _posterior(tmp_path / "fit.nc", model)
    res = _export(tmp_path / "fit.nc", "--to", "andes", "--out", tmp_path / "a.xlsx")
    assert res.exit_code == 2 and "Traceback" not in res.output
    line = res.output.strip().splitlines()[-1]
    assert line.startswith("loadbayes: error:") and "ANDES has no" in line
    assert not list(tmp_path.glob("a.*"))


def test_cim5bl_and_playback_refuse(cmld_lite, tmp_path):
    folder = cmld_lite[0]
    res = _export(folder / "fit.nc", "--to", "psse", "--out", tmp_path / "c.raw",
                  "--motor-record", "cim5bl")  # fmt: skip
    assert res.exit_code == 2 and "CMLDBLU2 only" in res.output
    fit = tmp_path / "fit.json"
    fit.write_text('{"model": "composite", "parameters": {}, "settings": {"model": "slm"}}')
    event = tmp_path / "e.csv"
    event.write_text("t_s,v,p,q\n0,1,1,0.3\n0.02,1,1,0.3\n")
    res = CliRunner().invoke(main, ["playback", str(fit), str(event), str(event)])
    assert res.exit_code == 2 and "loadbayes validate" in res.output
    assert "Traceback" not in res.output


def test_validate_plays_an_slm_fit_through_its_own_prediction(tmp_path):
    """An slm posterior at the truth of the tests' SciPy feeder simulator predicts its sag.

    The event and the truth come from ``tests/feeder_generator.py`` (SciPy, no package
    code); the posterior is that truth in the model's coordinates, its noise 0.5 %.
    """
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from feeder_generator import simulate

    t, v, ang, p, q, tr = simulate(sag=0.2, fs=100)
    event = tmp_path / "e.csv"
    event.write_text(
        "t_s,v,p,q,angle_rad\n"
        + "".join(f"{a},{b},{c},{d},{e}\n" for a, b, c, d, e in zip(t, v, p, q, ang, strict=True))
    )
    model = dynamic_model("slm", f_hz=50.0, rx=1 / 3)
    x, xp, t0, f_m = tr["x_open"], tr["x_prime"], tr["t0"], tr["f_m"]
    qs, qm = tr["q_static"], tr["qm0"]
    point = {
        "log_x_fd": math.log(tr["x_fd"]), "log_rs_t0": math.log(tr["rs"] * t0),
        "log_x_prime_t0": math.log(xp * t0), "log_dx_t0": math.log((x - xp) * t0),
        "log_t_prime": math.log(tr["t_prime_s"]), "log_h_over_t0": math.log(tr["h_s"] / t0),
        "log_t0": math.log(t0), "lr_m": math.log(f_m / (1 - f_m)),
        "lr_a1": math.log(tr["a1"] / tr["a3"]), "lr_a2": math.log(tr["a2"] / tr["a3"]),
        # The load bus's static Q (ZIP 0.5, 0.3, 0.2) and the motor's capacitor in cq2.
        "cq2": 0.5 * qs + qm, "cq1": 0.3 * qs, "cq0": 0.2 * qs, "p0": p[0],
        "tau_p": (0.005 * p[0]) ** -2, "tau_q": (0.005 * p[0]) ** -2,
    }  # fmt: skip
    assert set(model.theta_names) <= set(point)
    draws = {k: np.full((1, 20), v) for k, v in point.items()}
    settings = {"model": "slm", "model_options": model.options(), "f_hz": 50.0}
    Posterior(draws, model="composite", method="test", settings=settings).to_netcdf(
        tmp_path / "fit.nc"
    )
    out = tmp_path / "v.json"
    res = CliRunner().invoke(main, ["validate", str(tmp_path / "fit.nc"), str(event),
                                    "--n-draws", "20", "--json", str(out), "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    import json

    scores = json.loads(out.read_text())["events"][0]
    # The package's prediction (its feeder solved) against the independent simulator:
    # measured 5e-5 and 8e-5 of P0 here; with the feeder's X five times the truth's,
    # 0.015 and 0.036.
    assert scores["rms_p"] < 1e-3 and scores["rms_q"] < 1e-3, scores


def _griddyn_cmld(rec, load):
    """The harness's CMLDBLU1 load from an exported CMLDBLU2 record (its own order)."""

    def motor(m):
        return Motor3(lfm=rec[f"LFm{m}"], rs=rec[f"Rs{m}"], ls=rec[f"Ls{m}"], lp=rec[f"Lp{m}"],
                      tpo_s=rec[f"Tpo{m}"], h_s=rec[f"H{m}"], etrq=rec[f"Etrq{m}"])  # fmt: skip

    return Cmld(
        load_mw=load["pl"], load_mvar=load["ql"], mva_ratio=load["pl"] / rec["MVA"],
        f_a=rec["Fma"], f_b=rec["Fmb"], f_d=rec["Fmd"], f_el=rec["Fel"],
        motor_a=motor("A"), motor_b=motor("B"),
        motor_d=MotorD(lfm=rec["CompLF"], comp_pf=rec["CompPF"], vstall=rec["Vstall"],
                       rstall=rec["Rstall"], xstall=rec["Xstall"], tstall_s=rec["Tstall"],
                       trst_s=rec["Trst"], frst=rec["Frst"], vrst=rec["Vrst"], fuvr=0.0),
        r_fdr=rec["Rfdr"], x_fdr=rec["Xfdr"], fb=rec["Fb"], x_xf=rec["Xxf"], tap_ls=1.0,
        pf_el=rec["PFel"], vd1=rec["Vd1"], vd2=rec["Vd2"], pf_s=rec["PFs"],
        p1c=rec["P1c"], p2c=rec["P2c"], q1c=rec["Q1c"], q2c=rec["Q2c"],
    )  # fmt: skip


def test_griddyn_runs_the_exported_record_as_the_fit_predicts_it(cmld_lite):
    """GridDyn simulates the exported load; loadbayes's prediction of the same numbers agrees.

    The record goes through the tests' GridDyn harness (CMLDBLU1, GridDyn 0.13, a 15 %
    sag); the package's own prediction (``predict_parts``, the feeder solved) is driven
    by GridDyn's voltage at the load's bus with the record's numbers in the model's
    coordinates. Measured: P within 0.39 % of P0 (RMS). GridDyn's Q is not compared: its
    CMLD initialisation (a one-pass estimate, its reader says) sets the feeder's
    compensation from the series losses only, so its Q before the fault is 0.68 p.u.
    where the power flow's is 0.36, and the Q of its parts differs from the fit's.
    """
    from loadbayes.cases.griddyn import cases

    reason = cases.skip_reason()
    if reason is not None:
        pytest.skip(reason)
    from loadbayes.measurements.record import EventRecord
    from loadbayes.models.parts_predict import predict_parts

    folder, rec, med, _, _ = cmld_lite
    load = read_loads(folder / "case.raw")["1"]
    frame, truth = cases.run_case(cmld=_griddyn_cmld(rec, load), depth=0.15, t_end_s=0.6)
    # GridDyn starts at the record's power flow P (its bus sits at its own voltage).
    assert truth["event"]["p0"] * cases.S_BASE_MVA == pytest.approx(load["pl"], rel=0.02)
    model = dynamic_model("cmld-lite", f_hz=cases.F_HZ)
    p0, q0 = float(frame.p[0]), float(frame.q[0])
    x_load_base = (rec["Xfdr"] + rec["Xxf"]) * cases.S_BASE_MVA / rec["MVA"] * abs(complex(p0, q0))
    th = {"log_x_fd": math.log(x_load_base)}
    for m in "AB":
        t, t0 = "_" + m.lower(), med["t0_" + m.lower()]
        rs, xo, xp, tp, h = (rec[f"{k}{m}"] for k in ("Rs", "Ls", "Lp", "Tpo", "H"))
        th |= {f"log_rs_t0{t}": math.log(rs * t0), f"log_x_prime_t0{t}": math.log(xp * t0),
               f"log_dx_t0{t}": math.log((xo - xp) * t0), f"log_t_prime{t}": math.log(tp),
               f"log_h_over_t0{t}": math.log(h / t0), f"log_t0{t}": math.log(t0)}  # fmt: skip
    fs = 1 - sum(rec[k] for k in ("Fma", "Fmb", "Fmd", "Fel"))
    a3 = 1 - rec["P1c"] - rec["P2c"]
    th |= {"lr_m_a": math.log(rec["Fma"] / fs), "lr_m_b": math.log(rec["Fmb"] / fs),
           "lr_d": math.log(rec["Fmd"] / fs), "lr_el": math.log(rec["Fel"] / fs),
           "lr_a1": math.log(rec["P1c"] / a3), "lr_a2": math.log(rec["P2c"] / a3)}  # fmt: skip
    th |= {"vstall": rec["Vstall"], "log_tstall": math.log(rec["Tstall"]), "vd1": rec["Vd1"],
           "vd2": rec["Vd2"]}  # fmt: skip
    theta = np.array([th[n] for n in model.theta_names])
    ev = EventRecord(frame.t_s.values, frame.v.values, frame.p.values, frame.q.values,
                     frame.angle_rad.values, "griddyn")  # fmt: skip
    shares = np.array([rec["Q1c"], rec["Q2c"], 1 - rec["Q1c"] - rec["Q2c"]])
    mp, _, _ = predict_parts(model, ev, theta, p0, q0, shares)
    rms_p = float(np.sqrt(np.mean((mp - frame.p.values) ** 2)) / p0)
    # Measured 0.39 %. The same prediction without motor D and the electronics misses
    # GridDyn by 1.4 %, which this bound sees; with motors A and B's shares swapped
    # (0.25 %) or without the feeder (0.55 %) it does not: a 15 % sag of 0.1 s does not
    # tell those apart.
    assert rms_p < 0.01, rms_p
    assert frame.v.min() < 0.9 * frame.v[0]  # the sag happened


def test_a_json_gives_the_means_and_says_so(tmp_path):
    draws, _ = _posterior(tmp_path / "fit.nc", "cmld-lite")
    post = Posterior.from_netcdf(tmp_path / "fit.nc")
    post.to_json(tmp_path / "fit.json")
    res = _export(tmp_path / "fit.json", "--to", "psse", "--out", tmp_path / "j.raw")
    assert res.exit_code == 0, res.output
    assert "the posterior means exported" in res.output and "need its NetCDF" in res.output
    rec = read_cmldblu2(tmp_path / "j.dyr")
    assert rec["Fma"] == pytest.approx(float(np.mean(draws["f_m_a"])), rel=1e-6)
    # The means of one simplex sum to 1: the static part is the mean of f_s.
    static = 1 - sum(rec[n] for n in ("Fma", "Fmb", "Fmd", "Fel"))
    assert static == pytest.approx(float(np.mean(draws["f_s"])), rel=1e-6)
