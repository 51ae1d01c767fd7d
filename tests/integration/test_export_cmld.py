"""The composite load as a WECC CMLDBLU2 record (PSS/E) and CMPLDW (PSLF), read back.

The expected fields are computed here from the motor's equivalent circuit (docs/formats.md),
not through the export's code; ANDES's PSS/E dyr reader splits the record independently.
"""

import math

import pytest

from loadbayes.export import get
from loadbayes.export.cmld import CON_NAMES, read_cmldblu2
from loadbayes.export.psse import read_loads
from loadbayes.models.motor import MotorParams, steady_state

pytestmark = pytest.mark.integration

DRAW = {
    "p0": 0.9, "q0": 0.3, "v0": 0.97, "a1": 0.35, "a2": 0.25, "a3": 0.4, "a4": 0.55,
    "a5": 0.3, "a6": 0.15, "f_m": 0.45, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018,
    "xr": 0.12, "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6,
}  # fmt: skip
S = 50.0
HEADER = ["loadbayes composite posterior from c.json; exported: mean"]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmld") / "case.raw"
    files = get("psse").write(DRAW, out, model="composite", header=HEADER,
                              options={"s_base_mva": S, "bus": 7, "vn_kv": 11.0})  # fmt: skip
    return out, files


def test_files_and_the_whole_load_in_the_raw(written):
    out, files = written
    assert [p.name for p in files] == ["case.raw", "case.dyr", "case.dyd", "case.raw.summary.txt"]
    loads = read_loads(out)
    assert set(loads) == {"1"}
    # The composite model's Q at v0 is q0 (the motor's Q is compensated there).
    assert loads["1"]["pl"] == pytest.approx(0.9 * S, rel=1e-12)
    assert loads["1"]["ql"] == pytest.approx(0.3 * S, rel=1e-9)
    assert loads["1"]["ip"] == loads["1"]["yp"] == 0.0


def test_cmldblu2_fields_are_the_fitted_motor_and_static_load(written):
    out, _ = written
    rec = read_cmldblu2(out.with_suffix(".dyr"))
    assert rec["bus"] == 7 and rec["id"] == "1" and len(CON_NAMES) == 133
    params = MotorParams(rs=0.031, xs=0.10, xm=3.2, rr=0.018, xr=0.12, h_s=0.7)
    op = steady_state(params, v_pu=0.97, t0=0.6)
    expect = {
        "Fma": 0.45, "Fmb": 0.0, "Fmc": 0.0, "Fmd": 0.0, "Fel": 0.0,
        "P1e": 2.0, "P1c": 0.35, "P2e": 1.0, "P2c": 0.25, "Q1e": 2.0, "Q1c": 0.55,
        "Q2e": 1.0, "Q2c": 0.3, "Pfrq": 0.0, "Qfrq": 0.0,
        "Rfdr": 0.0, "Xfdr": 0.0, "Xxf": 0.0, "Bss": 0.0, "LTC": 0.0,
        "MtpA": 3.0, "RsA": 0.031, "LsA": 3.3, "LpA": 0.10 + 3.2 * 0.12 / 3.32,
        "LppA": 0.10 + 3.2 * 0.12 / 3.32, "TpoA": 3.32 / (2 * math.pi * 60 * 0.018),
        "HA": 0.7, "EtrqA": 2.0, "LFmA": op.p,
        # static load: (1 - f_m) p0 against q0 at v0
        "PFs": 0.55 * 0.9 / math.hypot(0.55 * 0.9, 0.3),
    }  # fmt: skip
    for name, val in expect.items():
        assert rec[name] == pytest.approx(val, rel=1e-9, abs=1e-12), name
    # Motor A's MW = Fma x the load's P (PSS/E's split) = f_m P0 s_base of the draw.
    p_load = read_loads(out)["1"]["pl"]
    assert rec["Fma"] * p_load == pytest.approx(0.45 * 0.9 * S, rel=1e-12)


def test_andes_dyr_reader_splits_the_record(written):
    pytest.importorskip("andes")
    from andes.io.psse import _read_dyr_dict

    out, _ = written
    table = _read_dyr_dict(str(out.with_suffix(".dyr")))
    # ANDES keys a record by its first quoted name: 'USRLOD' (a user model it does not
    # support); the numbers are all there, in order.
    row = [c for c in table["USRLOD"].iloc[0].tolist() if c is not None]
    k = row.index("CMLDBLU2")
    assert row[k + 1 : k + 10] == [12, 1, 2, 133, 27, 146, 48, 0, 0]
    cons = row[k + 10 :]
    assert len(cons) == 133
    assert cons[CON_NAMES.index("Fma")] == pytest.approx(0.45)
    assert cons[CON_NAMES.index("HA")] == pytest.approx(0.7)


def test_cmpldw_carries_the_same_numbers(written):
    out, _ = written
    text = out.with_suffix(".dyd").read_text()
    assert text.startswith('cmpldw 7 "LOADBAYES" 11 "1" : #9 mva=')
    # PSLF's order, by position after mva= (InterPSS's PSLF reader: FmA 18th after MVA,
    # frcel 26th, PFs 27th, P1c 29th, Q1c 34th, MtypA 38th, LfmA 42nd ... HA 49th).
    vals = [float(v) for v in text.split("mva=")[1].replace("/", " ").split()]
    rec = read_cmldblu2(out.with_suffix(".dyr"))
    at = {"MVA": 0, "Fma": 18, "Fmb": 19, "Fel": 22, "PFs": 27, "P1e": 28, "P1c": 29,
          "P2c": 31, "Q1c": 34, "Q2c": 36, "MtpA": 38, "LFmA": 42, "RsA": 43, "LsA": 44,
          "LpA": 45, "LppA": 46, "TpoA": 47, "TppoA": 48, "HA": 49, "EtrqA": 50}  # fmt: skip
    for name, k in at.items():
        assert vals[k] == pytest.approx(rec[name], rel=1e-9), name
    assert vals[26] == 1.0  # frcel: not in CMLDBLU2
    assert len(vals) == 5 + 22 + 11 + 4 + 3 * 19 + 22  # 121, InterPSS's list after MVA + 1


def test_cli_default_is_cmldblu2_and_cim5bl_stays_an_option(tmp_path):
    import json

    from click.testing import CliRunner

    from loadbayes.cli import main
    from loadbayes.export.psse import read_dyr

    doc = {"model": "composite", "parameters": {k: {"mean": v} for k, v in DRAW.items()},
           "settings": {"s_base_mva": S, "v_base_kv": 11.0, "f_hz": 60.0}}  # fmt: skip
    post = tmp_path / "c.json"
    post.write_text(json.dumps(doc))
    r = CliRunner().invoke(main, ["export", str(post), "--to", "psse", "--out",
                                  str(tmp_path / "a.raw")])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert read_cmldblu2(tmp_path / "a.dyr")["Fma"] == pytest.approx(0.45)
    assert (tmp_path / "a.dyd").is_file()
    r = CliRunner().invoke(main, ["export", str(post), "--to", "psse", "--out",
                                  str(tmp_path / "b.raw"), "--motor-record", "cim5bl"])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert read_dyr(tmp_path / "b.dyr")["id"] == "M"
    assert not (tmp_path / "b.dyd").exists()
