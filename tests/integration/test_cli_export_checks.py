"""Issue 25, exports: ANDES without --bus (H6), NaN/inf into PSS/E (M9), ``--out X.dyr``
(M10), and tampered posterior JSON files (L14): one line naming the key, exit 2, nothing
written.

The posterior JSON files are written here by hand, as a user's tool might.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration

ZIP = {"a1": 0.45, "a2": -0.15, "a3": 0.70, "a4": 1.6, "a5": -0.9, "a6": 0.3, "p0": 0.8,
       "q0": 0.3}  # fmt: skip
COMPOSITE = {
    "p0": 1.0, "q0": 0.45, "v0": 1.0, "a1": 0.4, "a2": 0.3, "a3": 0.3, "a4": 0.5, "a5": 0.3,
    "a6": 0.2, "f_m": 0.4, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018, "xr": 0.18,
    "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6, "q_c": 0.05,
}  # fmt: skip


def posterior_json(path: Path, values: dict, model: str = "zip", **extra) -> Path:
    doc = {
        "model": model,
        "hdi_prob": 0.95,
        "parameters": {
            k: {"mean": v, "sd": 0.01, "hdi_low": v - 0.02, "hdi_high": v + 0.02}
            for k, v in values.items()
        },  # fmt: skip
        "settings": {"v0": 1.0},
        **extra,
    }
    path.write_text(json.dumps(doc))
    return path


def run(*args, cwd: Path, monkeypatch):
    monkeypatch.chdir(cwd)
    r = CliRunner().invoke(main, ["export", *map(str, args)])
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        raise r.exception
    return r


def one_line(r, *needles) -> str:
    assert r.exit_code == 2, (r.exit_code, r.output)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error: "), r.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ------------------------------------------------------------------ H6: ANDES, no --bus
@pytest.mark.parametrize(("model", "values"), [("zip", ZIP), ("composite", COMPOSITE)])
def test_andes_without_bus_takes_the_documented_bus(tmp_path, monkeypatch, model, values):
    pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")
    from loadbayes.export.andes.writer import DEFAULT_BUS

    posterior_json(tmp_path / "post.json", values, model)
    # ZIP's shares are not physical (a2 < 0): the export needs --force-unphysical (issue 40)
    r = run("post.json", "--to", "andes", "--out", "case.json", "--quiet",
            "--force-unphysical", cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    side = (tmp_path / "case.json.summary.txt").read_text()
    assert f"Load bus idx {DEFAULT_BUS} " in side
    case = json.loads((tmp_path / "case.json").read_text())
    assert any(row.get("bus") == DEFAULT_BUS for row in case["PQ"])


# ----------------------------------------------------------- M10: --out NAME.dyr (PSS/E)
def test_psse_out_dyr_gives_both_files_their_own_name(tmp_path, monkeypatch):
    from loadbayes.export.psse import read_dyr, read_loads

    posterior_json(tmp_path / "comp.json", COMPOSITE, "composite")
    r = run("comp.json", "--to", "psse", "--out", "case.dyr", "--motor-record", "cim5bl",
            cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert files(tmp_path) == ["case.dyr", "case.raw", "case.raw.summary.txt", "comp.json"]
    assert "case.raw, case.dyr, case.raw.summary.txt" in r.stderr
    assert read_dyr(tmp_path / "case.dyr")["id"] == "M"  # the .dyr holds the dynamics
    assert set(read_loads(tmp_path / "case.raw")) == {"1", "M"}  # and the .raw the case
    # again, without --force: refused before anything is touched
    before = (tmp_path / "case.dyr").read_bytes()
    one_line(run("comp.json", "--to", "psse", "--out", "case.dyr", "--motor-record", "cim5bl",
                 cwd=tmp_path, monkeypatch=monkeypatch), "exists", "--force")  # fmt: skip
    assert (tmp_path / "case.dyr").read_bytes() == before


# ----------------------------------------------- M9, L14: what a tampered JSON may hold
def _tampered(tmp_path: Path, kind: str) -> Path:
    path = tmp_path / "t.json"
    if kind == "deep":
        path.write_text('{"model": "zip", "parameters": ' + "[" * 100_000 + "]" * 100_000 + "}")
        return path
    doc = json.loads(posterior_json(path, ZIP).read_text())
    par = doc["parameters"]
    if kind in ("nan", "inf", "-inf"):
        par["a1"]["mean"] = float(kind)
    elif kind == "huge":
        par["a1"]["mean"] = 1e308
    elif kind == "huge-p0":
        par["p0"]["mean"] = 1e300
    elif kind == "list":
        doc["parameters"] = [1, 2]
    elif kind == "string":
        par["a1"]["mean"] = "abc"
    elif kind == "numeric-string":
        par["a1"]["mean"] = "0.3"
    elif kind == "sd-string":
        par["a1"]["sd"] = "wide"
    elif kind == "v0-string":
        doc["settings"]["v0"] = "x"
    elif kind == "settings-list":
        doc["settings"] = ["v0"]
    elif kind == "hdi-prob":
        doc["hdi_prob"] = "95%"
    path.write_text(json.dumps(doc))  # Python's json writes NaN and Infinity
    return path


TAMPERED = [
    ("nan", ["t.json", "parameters.a1.mean", "nan", "finite"]),
    ("inf", ["t.json", "parameters.a1.mean", "inf", "finite"]),
    ("-inf", ["t.json", "parameters.a1.mean", "-inf", "finite"]),
    ("huge", ["t.json", "'a1'", "1e+308"]),
    ("huge-p0", ["t.json", "'p0'", "1e+300"]),
    ("list", ["t.json", "'parameters' is list"]),
    ("deep", ["t.json", "nested too deeply"]),
    ("string", ["t.json", "parameters.a1.mean", "'abc'"]),
    ("numeric-string", ["t.json", "parameters.a1.mean", "'0.3'"]),
    ("sd-string", ["t.json", "parameters.a1.sd", "'wide'"]),
    ("v0-string", ["t.json", "settings.v0", "'x'"]),
    ("settings-list", ["t.json", "'settings' is list"]),
    ("hdi-prob", ["t.json", "'hdi_prob'", "'95%'"]),
]


@pytest.mark.parametrize("fmt", ["psse", "pandapower"])
@pytest.mark.parametrize(("kind", "needles"), TAMPERED, ids=[t[0] for t in TAMPERED])
def test_a_tampered_posterior_is_one_line_naming_the_key(tmp_path, monkeypatch, kind, needles,
                                                          fmt):  # fmt: skip
    _tampered(tmp_path, kind)
    out = "case.raw" if fmt == "psse" else "net.json"
    r = run("t.json", "--to", fmt, "--out", out, cwd=tmp_path, monkeypatch=monkeypatch)
    line = one_line(r, *needles)
    assert "Traceback" not in r.output and line.count("loadbayes:") == 1
    assert files(tmp_path) == ["t.json"]  # nothing written


def test_psse_refuses_a_negative_load_and_a_field_past_its_range(tmp_path, monkeypatch):
    posterior_json(tmp_path / "neg.json", dict(ZIP, p0=-5.0))
    # p0 = -5 p.u. on the default 100 MVA base
    # --force-unphysical past the shares' refusal (issue 40): the writer's own refusal
    one_line(run("neg.json", "--to", "psse", "--out", "neg.raw", "--force-unphysical", cwd=tmp_path,
                 monkeypatch=monkeypatch), "P = -500 MW", "negative load")  # fmt: skip
    # finite parameters whose products leave a PSS/E field's range (1e9): named by field
    posterior_json(tmp_path / "big.json", dict(ZIP, p0=1e6, a1=1e6, a2=-1e6 + 0.3))
    one_line(run("big.json", "--to", "psse", "--out", "big.raw", "--s-base", "100",
                 "--force-unphysical",
                 cwd=tmp_path, monkeypatch=monkeypatch), "field IP", "-1e+14")  # fmt: skip
    assert files(tmp_path) == ["big.json", "neg.json"]


def test_netcdf_draws_with_nan_are_refused(tmp_path, monkeypatch):
    """M9 from the other source: a NaN in the draws of a NetCDF posterior."""
    import numpy as np

    from loadbayes.posterior import Posterior

    rng = np.random.default_rng(0)
    draws = {k: v + 0.01 * rng.standard_normal((2, 50)) for k, v in ZIP.items()}
    draws["a2"][0, 3] = np.nan
    Posterior(draws, model="zip", method="gibbs-blocked").to_netcdf(tmp_path / "p.nc")
    one_line(run("p.nc", "--to", "psse", "--out", "c.raw", "--stat", "median", cwd=tmp_path,
                 monkeypatch=monkeypatch), "p.nc", "'a2'", "nan")  # fmt: skip
    assert files(tmp_path) == ["p.nc"]


# ---------------------------------------------- issue 23: ANDES, --case NAME --bus N
def test_andes_case_and_bus_place_the_load_in_that_case(tmp_path, monkeypatch):
    pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")
    import andes

    from loadbayes.export.andes.playback import load_devices

    posterior_json(tmp_path / "post.json", COMPOSITE, "composite")
    r = run("post.json", "--to", "andes", "--out", "kundur.json", "--case",
            "kundur/kundur_full.xlsx", "--bus", 7, "--add-load", "--quiet", cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    # quiet, with no log file: by default ANDES makes a new /tmp/andes-* folder for one
    andes.config_logger(stream_level=50, file=False, log_path=str(tmp_path))
    ss = andes.load(str(tmp_path / "kundur.json"), no_output=True, default_config=True)
    orig = andes.load(andes.get_case("kundur/kundur_full.xlsx"), no_output=True,
                      default_config=True, setup=False)  # fmt: skip
    assert ss.GENROU.n == orig.GENROU.n and ss.PQ.n == orig.PQ.n + 1  # the case, plus ours
    assert ss.PFlow.run()  # ANDES alone, with KLU: the case's _config carries linsolve
    k = ss.Motor3.idx2uid("loadbayes_motor")
    assert ss.Motor3.bus.v[k] == 7 and ss.Motor3.Vn.v[k] == ss.Bus.Vn.v[ss.Bus.idx2uid(7)]
    assert 0 < ss.Motor3.slip.v[k] < 0.05  # running, not the start-up guess
    # Playback takes our devices only, not the case's own load on bus 7.
    dev = load_devices(tmp_path / "kundur.json")
    assert [d["idx"] for d in dev["PQ"]] == ["loadbayes_pq"] and dev["Bus"][0]["idx"] == 7
    # Refused in one line: no --bus, a bus the case lacks, another format, a wrong name.
    for args, needle in (
        (("--to", "andes", "--case", "kundur/kundur_full.xlsx"), "give --bus N"),
        (("--to", "andes", "--case", "kundur/kundur_full.xlsx", "--bus", 77), "no bus 77"),
        (("--to", "psse", "--case", "kundur/kundur_full.xlsx", "--bus", 7), "--to andes"),
        (("--to", "andes", "--case", "nowhere.xlsx", "--bus", 7), "neither a file"),
    ):
        out = "c.raw" if "psse" in args else "c.json"
        one_line(run("post.json", *args, "--out", out, cwd=tmp_path, monkeypatch=monkeypatch),
                 needle)  # fmt: skip
        assert not (tmp_path / out).exists()


# ------------------------------------------------------- the red-team's Lows (L9, L13)
@pytest.mark.parametrize("fmt", ["psse", "pandapower", "andes"])
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--vn-kv", "1e300"), "--vn-kv 1e+300: outside [0.001, 2000] kV"),
        (("--s-base", "1e-300"), "--s-base 1e-300: outside [1e-06, 1e+06] MVA"),
        (("--s-base", "1e300"), "--s-base 1e+300: outside [1e-06, 1e+06] MVA"),
    ],
)
def test_bases_no_network_has_are_refused(tmp_path, monkeypatch, fmt, args, needle):
    # L9: --vn-kv 1e300 and --s-base 1e-300 were exported without a word.
    posterior_json(tmp_path / "z.json", ZIP)
    out = {"psse": "c.raw", "pandapower": "n.json", "andes": "c.xlsx"}[fmt]
    one_line(run("z.json", "--to", fmt, "--out", out, *args, cwd=tmp_path,
                 monkeypatch=monkeypatch), needle)  # fmt: skip
    assert files(tmp_path) == ["z.json"]


@pytest.mark.parametrize("fmt", ["psse", "pandapower", "andes"])
def test_a_vanishing_load_is_refused(tmp_path, monkeypatch, fmt):
    # L9: p0 1e-300 (a tampered JSON) was a ZeroDivisionError traceback from pandapower.
    posterior_json(tmp_path / "post.json", dict(COMPOSITE, p0=1e-300), "composite")
    out = {"psse": "c.raw", "pandapower": "n.json", "andes": "c.xlsx"}[fmt]
    r = run("post.json", "--to", fmt, "--out", out, cwd=tmp_path, monkeypatch=monkeypatch)
    one_line(r, "post.json", "parameter 'p0' is 1e-300: below 1e-09 per unit, no load")
    assert files(tmp_path) == ["post.json"]


def test_a_case_andes_cannot_find_buses_in_is_not_an_andes_case(tmp_path, monkeypatch):
    # L13: --case /etc/passwd said "no bus 2 (its buses: none)".
    posterior_json(tmp_path / "c.json", COMPOSITE, "composite")
    (tmp_path / "passwd").write_text("root:x:0:0:root:/root:/bin/bash\n")
    r = run("c.json", "--to", "andes", "--out", "c.json.xlsx", "--case", "passwd", "--bus", 2,
            cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    one_line(r, "--case passwd: not an ANDES case")
    assert files(tmp_path) == ["c.json", "passwd"]
