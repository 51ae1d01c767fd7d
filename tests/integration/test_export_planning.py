"""``loadbayes export --planning``: the draws at quantiles of a predicted fault's outcome.

Two small fits of events the package did not make (few hundred draws, one chain: the
mechanics, not converged numbers): a ``zip+motor`` fit of a 20 % sag from the tests'
SciPy generator (``tests/independent_composite.py``) and a ``cmld-lite`` fit of a 15 %
sag from the tests' SciPy feeder simulator (``tests/feeder_generator.py``). Each is
exported as a planning ensemble for a 45 % sag: the chosen draws' outcomes are ordered
and are the prediction's own quantiles of it (``loadbayes.predict`` with the same seed
and draws), the files parse (the CMLDBLU2 record by ``export.cmld.read_cmldblu2``, the
``.raw`` by ``export.psse.read_loads``, the ANDES case by ANDES's reader) and carry the
draw (its motor's T', a parts fit's thresholds), and every file's comment names its
quantile, the outcome's value, the fault and the draw. Bad requests are one line, exit
2, with nothing written or overwritten.
"""

import numpy as np
import pytest
from click.testing import CliRunner

import independent_composite as ic
from loadbayes.cli import main
from loadbayes.core.settings import SamplerSettings
from loadbayes.export.cmld import read_cmldblu2
from loadbayes.export.planning import label, parse_quantiles, select
from loadbayes.export.psse import read_loads
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.fit.composite.predict import predict
from loadbayes.fit.composite.predict_scope import OUTCOME
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration

QS = (0.05, 0.5, 0.95)
FAULT = ("--sag", "0.45", "--duration", "0.15")


@pytest.fixture(scope="module")
def zip_motor(tmp_path_factory):
    df, _ = ic.simulate_event(sags=(ic.Sag(0.2, 0.2, 0.1),), rate_hz=120, t_end_s=1.5,
                              noise=0.005, seed=1)  # fmt: skip
    ev = EventRecord(df.t_s.to_numpy(), df.v.to_numpy(), df.p.to_numpy(), df.q.to_numpy(),
                     None, "independent 20%")  # fmt: skip
    model = dynamic_model("zip+motor", f_hz=60.0, shares="bounded")  # a simulator's shares
    fit = fit_composite(model, [ev], sampler=SamplerSettings(draws=300, burn=150, chains=1,
                                                              seed=5))  # fmt: skip
    path = tmp_path_factory.mktemp("planning_zm") / "zm.nc"
    fit.posterior.to_netcdf(path)
    return path


@pytest.fixture(scope="module")
def cmld_lite(cmld_lite_nc):
    """The cmld-lite fit of one 15 % sag that test_predict plays too (tests/conftest.py)."""
    return cmld_lite_nc


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _picks(nc, played):
    pred = predict(nc, sag=0.45, duration=0.15, draws=played, seed=0)
    return pred, select(pred.outcomes, QS, outcome=OUTCOME)


def _check_picks(pred, picks):
    x = pred.outcomes[OUTCOME]
    values = [p.outcome for p in picks]
    assert values == sorted(values) and values[0] < values[-1]
    assert values == [float(np.quantile(x, q, method="inverted_cdf")) for q in QS]
    for p in picks:  # the pick is the played draw with that outcome
        j = list(pred.outcomes["index"]).index(p.index)
        assert x[j] == p.outcome


def test_zip_motor_to_cmldblu2_and_cmpldw(zip_motor, tmp_path):
    out = tmp_path / "case.raw"
    r = _run("export", zip_motor, "--to", "psse", "--out", out, "--planning", *FAULT,
             "--played", 60)  # fmt: skip
    assert r.exit_code == 0, r.output
    pred, picks = _picks(zip_motor, 60)
    _check_picks(pred, picks)
    draws = Posterior.from_netcdf(zip_motor).draws
    tp = np.asarray(draws["t_prime_s"]).reshape(-1)
    for pick, tag in zip(picks, ("q05", "q50", "q95"), strict=True):
        rec = read_cmldblu2(tmp_path / f"case_{tag}.dyr")
        assert rec["TpoA"] == pytest.approx(tp[pick.index], rel=1e-6)  # the picked draw
        assert read_loads(tmp_path / f"case_{tag}.raw")["1"]["pl"] > 0
        q = f"the {100 * pick.quantile:g}% quantile of {OUTCOME}"
        for suffix, mark in ((".dyr", "/ loadbayes: "), (".dyd", "# loadbayes: "),
                             (".raw", "@! loadbayes: ")):  # fmt: skip
            text = (tmp_path / f"case_{tag}{suffix}").read_text()
            assert f"{mark}planning ensemble: {q}" in text, (suffix, text[-600:])
            assert f"{pick.outcome:.6g} p.u. s" in text
            assert f"posterior draw {pick.index}" in text and "'sag 0.45 for 0.15 s'" in text
        assert f"exported: planning ensemble: {q}" in (
            tmp_path / f"case_{tag}.raw.summary.txt").read_text()  # fmt: skip
        assert "the induction motor does not stall" in text


def test_zip_motor_to_andes(zip_motor, tmp_path):
    andes = pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")
    from loadbayes.export.andes.conventions import andes_quiet

    out = tmp_path / "case.xlsx"
    r = _run("export", zip_motor, "--to", "andes", "--out", out, "--planning", *FAULT,
             "--played", 40, "--quantiles", "0.1,0.9")  # fmt: skip
    assert r.exit_code == 0, r.output
    for tag, q in (("q10", 10), ("q90", 90)):
        with andes_quiet():
            ss = andes.load(str(tmp_path / f"case_{tag}.xlsx"), setup=False, no_output=True,
                            default_config=True)  # fmt: skip
        assert ss.Motor3.n == 1
        side = (tmp_path / f"case_{tag}.xlsx.summary.txt").read_text()
        assert f"planning ensemble: the {q}% quantile of {OUTCOME}" in side


def test_parts_fit_carries_its_draws_thresholds(cmld_lite, tmp_path):
    out = tmp_path / "p.raw"
    r = _run("export", cmld_lite, "--to", "psse", "--out", out, "--planning", *FAULT,
             "--played", 30)  # fmt: skip
    assert r.exit_code == 0, r.output
    pred, picks = _picks(cmld_lite, 30)
    _check_picks(pred, picks)
    for pick, tag in zip(picks, ("q05", "q50", "q95"), strict=True):
        rec = read_cmldblu2(tmp_path / f"p_{tag}.dyr")
        # The record stalls as the prediction did: the draw's own thresholds.
        for key, con in (("vstall", "Vstall"), ("tstall", "Tstall"), ("vd1", "Vd1"),
                         ("vd2", "Vd2")):  # fmt: skip
            assert rec[con] == pytest.approx(pick.thresholds[key], rel=1e-6)
        text = (tmp_path / f"p_{tag}.dyd").read_text()
        assert f"the {100 * pick.quantile:g}% quantile of {OUTCOME}" in text
        assert "motor D stalls" in text or "motor D does not stall" in text
        assert "played with vstall" in text
    r = _run("export", cmld_lite, "--to", "andes", "--out", tmp_path / "a.xlsx", "--planning",
             *FAULT, "--played", 20)  # fmt: skip
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output


@pytest.mark.parametrize(
    "args, words",
    [
        (("--sag", "0.4", "--duration", "0.1"), "--sag goes with --planning"),
        (("--planning",), "give the fault as --sag"),
        (("--planning", "--sag", "0.4"), "--sag needs --duration"),
        (("--planning", *FAULT, "--quantiles", "0.5,0.2"), "increasing"),
        (("--planning", *FAULT, "--quantiles", "0.5,x"), "numbers separated by commas"),
        (("--planning", *FAULT, "--draws", "3"), "not with --stat or --draws"),
    ],
)
def test_bad_requests_are_one_line_exit_2(zip_motor, tmp_path, args, words):
    r = _run("export", zip_motor, "--to", "psse", "--out", tmp_path / "c.raw", *args)
    assert r.exit_code == 2, r.output
    assert words in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert list(tmp_path.iterdir()) == []


def test_pandapower_is_refused_and_nothing_is_overwritten(zip_motor, tmp_path):
    r = _run("export", zip_motor, "--to", "pandapower", "--out", tmp_path / "n.json",
             "--planning", *FAULT)  # fmt: skip
    assert r.exit_code == 2 and "--to psse" in r.output
    keep = tmp_path / "c_q50.dyr"
    keep.write_text("keep")
    r = _run("export", zip_motor, "--to", "psse", "--out", tmp_path / "c.raw", "--planning",
             *FAULT, "--played", 20)  # fmt: skip
    assert r.exit_code == 2 and "--force" in r.output
    assert keep.read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c_q50.dyr"]


def test_quantile_labels_and_parsing():
    assert [label(q) for q in (0.05, 0.5, 0.95, 0.975, 0.001)] == [
        "q05", "q50", "q95", "q97.5", "q0.1"]  # fmt: skip
    assert parse_quantiles("0.05, 0.5,0.95") == QS
    for bad in ("0,0.5", "0.5,1", "", "0.2,0.2"):
        with pytest.raises(ValueError, match="--quantiles"):
            parse_quantiles(bad)


def test_a_voltage_profile_and_a_json_posterior(zip_motor, tmp_path):
    df = ic.simulate_event(sags=(ic.Sag(0.2, 0.45, 0.15),), rate_hz=240, t_end_s=1.85,
                           noise=0.0)[0]  # fmt: skip
    profile = tmp_path / "deep.csv"
    df[["t_s", "v"]].to_csv(profile, index=False)
    r = _run("export", zip_motor, "--to", "psse", "--out", tmp_path / "v.raw", "--planning",
             "--voltage", profile, "--quantiles", "0.5", "--played", 20)  # fmt: skip
    assert r.exit_code == 0, r.output
    text = (tmp_path / "v_q50.dyd").read_text()
    assert "the 50% quantile of" in text and "in the fault 'deep.csv'" in text
    js = tmp_path / "fit.json"
    Posterior.from_netcdf(zip_motor).to_json(js)
    r = _run("export", js, "--to", "psse", "--out", tmp_path / "j.raw", "--planning", *FAULT)
    assert r.exit_code == 2 and "--planning needs the NetCDF posterior" in r.output, r.output
