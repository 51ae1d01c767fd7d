"""Bases carried from the fit to the export: MW on the data's kV, overrides said aloud."""

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.export.psse import read_loads

pytestmark = pytest.mark.integration

SHORT = ["--draws", "400", "--burn", "100", "--chains", "2", "--quiet"]


@pytest.fixture(scope="module")
def kv_mw(tmp_path_factory):
    """A ZIP load recorded in kV and MW on an 11 kV, 5 MVA bus (written here)."""
    rng = np.random.default_rng(23)
    v = 1.0 + 0.04 * np.sin(np.linspace(0, 20, 600)) + 0.005 * rng.standard_normal(600)
    p = 0.9 * (0.3 * v**2 + 0.2 * v + 0.5) + 0.002 * rng.standard_normal(600)
    q = 0.35 * (0.5 * v**2 + 0.2 * v + 0.3) + 0.002 * rng.standard_normal(600)
    path = tmp_path_factory.mktemp("bases") / "bus.csv"
    pd.DataFrame({"v": 11.0 * v, "p": 5.0 * p, "q": 5.0 * q}).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def fitted(kv_mw):
    """The ZIP fitted on its bases, once for the module."""
    return _fit(kv_mw, "--v-base", "11", "--s-base", "5")


def _fit(path, *extra):
    out = path.with_name(f"fit{len(extra)}.json")
    res = CliRunner().invoke(main, ["fit", "zip", str(path), "--json", str(out), *SHORT,
                                    "--force", *extra])  # fmt: skip
    assert res.exit_code == 0, res.output
    return out, json.loads(out.read_text())


def _export(post, fmt, out, *extra):
    return CliRunner().invoke(main, ["export", str(post), "--to", fmt, "--out", str(out),
                                     "--force", *extra])  # fmt: skip


def test_zip_fitted_on_bases_exports_mw_on_its_bus(fitted, tmp_path):
    import pandapower as pp

    post, doc = fitted
    s = doc["settings"]
    assert (s["v_base_kv"], s["s_base_mva"]) == (11.0, 5.0) and "f_hz" in s
    p0, q0 = doc["parameters"]["p0"]["mean"], doc["parameters"]["q0"]["mean"]
    res = _export(post, "pandapower", tmp_path / "net.json")
    assert res.exit_code == 0, res.output
    assert "note" not in res.output  # nothing overridden, nothing assumed
    net = pp.from_json(str(tmp_path / "net.json"))
    assert net.bus.vn_kv.iloc[0] == 11.0
    assert net.load.p_mw.iloc[0] == pytest.approx(5.0 * p0, rel=1e-9)
    assert net.load.q_mvar.iloc[0] == pytest.approx(5.0 * q0, rel=1e-9)
    assert 4.3 < net.load.p_mw.iloc[0] < 4.7  # the data's own 5 MVA x 0.9 p.u.
    res = _export(post, "psse", tmp_path / "case.raw")
    assert res.exit_code == 0, res.output
    rec = read_loads(tmp_path / "case.raw")["1"]
    assert rec["pl"] + rec["ip"] + rec["yp"] == pytest.approx(5.0 * p0, rel=1e-9)
    bus_line = (tmp_path / "case.raw").read_text().splitlines()[4]
    assert float(bus_line.split(",")[2]) == 11.0


def test_override_is_said_and_per_unit_fit_names_the_options(kv_mw, fitted, tmp_path):
    import pandapower as pp

    post, doc = fitted
    p0 = doc["parameters"]["p0"]["mean"]
    res = _export(post, "pandapower", tmp_path / "o.json", "--s-base", "10", "--v-base", "33")
    assert res.exit_code == 0, res.output
    assert "--s-base 10 MVA overrides the fit's base of 5 MVA" in res.output
    assert "--v-base 33 kV overrides the fit's base of 11 kV" in res.output
    net = pp.from_json(str(tmp_path / "o.json"))
    assert net.load.p_mw.iloc[0] == pytest.approx(10.0 * p0, rel=1e-9)
    assert net.bus.vn_kv.iloc[0] == 33.0
    # A per-unit fit (the same data divided here) records null bases; its export says so.
    pu = kv_mw.with_name("pu.csv")
    d = pd.read_csv(kv_mw)
    pd.DataFrame({"v": d.v / 11.0, "p": d.p / 5.0, "q": d.q / 5.0}).to_csv(pu, index=False)
    post_pu, doc_pu = _fit(pu)
    assert doc_pu["settings"]["s_base_mva"] is None and doc_pu["settings"]["v_base_kv"] is None
    res = _export(post_pu, "psse", tmp_path / "pu.raw")
    assert res.exit_code == 0, res.output
    assert "records no power base or voltage base" in res.output
    assert "give --s-base MVA and --v-base kV" in res.output
    assert "records no power base" in (tmp_path / "pu.raw.summary.txt").read_text()


def test_tampered_base_is_refused_in_one_line(fitted, tmp_path):
    import copy

    post, doc = fitted
    doc = copy.deepcopy(doc)
    doc["settings"]["s_base_mva"] = "5 MVA"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    res = _export(bad, "pandapower", tmp_path / "x.json")
    assert res.exit_code == 2
    assert "settings.s_base_mva is '5 MVA', expected a positive number" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "x.json").exists()
