"""Issue 40, exports: what an export checks in the fit it exports, and the red-team's
H5, M5, M6 in the export area.

- (a) unconverged, (b) non-physical static part (refused without --force-unphysical),
  (c) motor data outside published ranges, (d) a share at its prior's bound: each said
  on stderr in one ``loadbayes: warning:`` line and as a comment in every file written;
- the PSS/E case takes the fit's frequency (BASFRQ);
- ``--case`` with a bus that has a load needs --replace-load or --add-load;
- H5: ``--draws N`` is one transaction; M5: ``--out case.dyd``; M6: shares not summing to 1.

The posterior JSON files are written here by hand, as in test_cli_export_checks.py.
"""

from __future__ import annotations

import json
import signal
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration

COMPOSITE = {
    "p0": 1.0, "q0": 0.45, "v0": 1.0, "a1": 0.4, "a2": 0.3, "a3": 0.3, "a4": 0.5, "a5": 0.3,
    "a6": 0.2, "f_m": 0.4, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018, "xr": 0.18,
    "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6, "q_c": 0.05,
}  # fmt: skip


def posterior_json(path: Path, values: dict, *, settings=None, rows=None) -> Path:
    params = {k: {"mean": v, "sd": 0.01, "hdi_low": v - 0.02, "hdi_high": v + 0.02,
                  "r_hat": 1.001, "ess_bulk": 2000.0} for k, v in values.items()}  # fmt: skip
    for k, row in (rows or {}).items():
        params[k].update(row)
    doc = {"model": "composite", "hdi_prob": 0.95, "parameters": params,
           "settings": {"v0": 1.0, "s_base_mva": 10.0, "v_base_kv": 11.0, "f_hz": 60.0,
                        **(settings or {})}}  # fmt: skip
    path.write_text(json.dumps(doc))
    return path


def run(*args, cwd: Path, monkeypatch):
    monkeypatch.chdir(cwd)
    r = CliRunner().invoke(main, ["export", *map(str, args)])
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        raise r.exception
    return r


def warnings_of(r) -> list[str]:
    return [ln for ln in r.stderr.splitlines() if ln.startswith("loadbayes: warning: ")]


def test_clean_fit_says_nothing_and_its_files_carry_no_warning(tmp_path, monkeypatch):
    posterior_json(tmp_path / "c.json", COMPOSITE)
    r = run("c.json", "--to", "psse", "--out", "c.raw", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 0, r.output
    assert warnings_of(r) == []
    for name in ("c.raw", "c.dyr", "c.dyd", "c.raw.summary.txt"):
        assert "warning" not in (tmp_path / name).read_text(), name


@pytest.mark.parametrize(
    ("change", "rows", "settings", "needle"),
    [
        ({}, {"xm": {"r_hat": 1.2}, "rs": {"ess_bulk": 90.0}}, None,
         "not converged on the exported quantities: R-hat 1.200 (xm), bulk ESS 90 (rs)"),
        ({"rs": 0.134}, None, None, "stator resistance Rs (p.u.) = 0.134"),
        ({"h_s": 4.0}, None, None, "inertia H (s) = 4 is outside the published range"),
        ({"q_c": 0.9}, None, None, "the shunt supplies 9 Mvar at v0, more than"),
        ({}, {"f_m": {"hdi_low": 0.3, "hdi_high": 0.99999}},
         {"coefficient_prior": {"shares": "bounded"}},
         "f_m 0.400 [0.300, 1.000] (95% HDI) is at its bound 1"),
    ],
)  # fmt: skip
def test_each_problem_is_said_once_and_written_in_every_file(
    tmp_path, monkeypatch, change, rows, settings, needle
):
    posterior_json(tmp_path / "c.json", {**COMPOSITE, **change}, settings=settings, rows=rows)
    r = run("c.json", "--to", "psse", "--out", "c.raw", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 0, r.output
    said = [w for w in warnings_of(r) if needle in w]
    assert len(said) == 1, r.stderr
    text = said[0].removeprefix("loadbayes: warning: ")
    assert f"@! loadbayes warning: {text}" in (tmp_path / "c.raw").read_text()
    assert "/ loadbayes warning: " in (tmp_path / "c.dyr").read_text()
    assert text in (tmp_path / "c.dyr").read_text()
    assert f"# loadbayes warning: {text}" in (tmp_path / "c.dyd").read_text()
    assert f"# warning: {text}" in (tmp_path / "c.raw.summary.txt").read_text()
    # The PSS/E files still read back (ANDES's reader stops at "Q" and at "/").
    from loadbayes.export.cmld import read_cmldblu2
    from loadbayes.export.psse import read_loads

    assert read_loads(tmp_path / "c.raw")["1"]["pl"] > 0
    assert read_cmldblu2(tmp_path / "c.dyr")["Fma"] == pytest.approx({**COMPOSITE, **change}["f_m"])


def test_pandapower_and_andes_carry_the_warning(tmp_path, monkeypatch):
    posterior_json(tmp_path / "c.json", {**COMPOSITE, "h_s": 4.0})
    r = run("c.json", "--to", "pandapower", "--out", "n.json", cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    net = json.loads((tmp_path / "n.json").read_text())
    assert "warning: motor inertia H (s) = 4" in json.dumps(net)
    r = run("c.json", "--to", "andes", "--out", "a.xlsx", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 0, r.output
    import pandas as pd

    pq = pd.read_excel(tmp_path / "a.xlsx", sheet_name="PQ")
    assert pq["name"].str.contains("loadbayes warning: motor inertia H").any()


def test_negative_shares_are_refused_without_the_flag(tmp_path, monkeypatch):
    bad = {**COMPOSITE, "a4": 1.42, "a5": -0.62, "a6": 0.2}
    posterior_json(tmp_path / "c.json", bad)
    for fmt, out in (("psse", "c.raw"), ("pandapower", "n.json"), ("andes", "a.xlsx")):
        r = run("c.json", "--to", fmt, "--out", out, cwd=tmp_path, monkeypatch=monkeypatch)
        assert r.exit_code == 2, (fmt, r.output)
        errors = [ln for ln in r.stderr.splitlines() if ln.startswith("loadbayes: error")]
        assert len(errors) == 1 and "--force-unphysical" in errors[0], r.stderr
        assert "a5 = -0.62" in errors[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]
    r = run("c.json", "--to", "psse", "--out", "c.raw", "--force-unphysical", cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert any("a5 = -0.62" in w for w in warnings_of(r))
    assert "a5 = -0.62" in (tmp_path / "c.raw").read_text()


def test_negative_static_q_is_unphysical(tmp_path, monkeypatch):
    # A small q0 with the motor's Q compensated: the static part supplies Q.
    posterior_json(tmp_path / "c.json", {**COMPOSITE, "q0": 0.01, "q_c": 0.0})
    r = run("c.json", "--to", "psse", "--out", "c.raw", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 2, r.output
    assert "the static part draws" in r.stderr and "--force-unphysical" in r.stderr


def test_psse_case_takes_the_fits_frequency(tmp_path, monkeypatch):
    posterior_json(tmp_path / "c.json", COMPOSITE, settings={"f_hz": 50.0})
    r = run("c.json", "--to", "psse", "--out", "c.raw", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 0, r.output
    first = (tmp_path / "c.raw").read_text().splitlines()[0]
    assert first.split("/")[0].split(",")[5].strip() == "50.0", first
    posterior_json(tmp_path / "d.json", COMPOSITE)
    run("d.json", "--to", "psse", "--out", "d.raw", cwd=tmp_path, monkeypatch=monkeypatch)
    assert (tmp_path / "d.raw").read_text().startswith("0,10,33,0,0,60.0     / PSS(R)E-33")


# ------------------------------------------------------------- M5, M6: PSS/E outputs
def test_m5_out_dyd_names_the_raw(tmp_path, monkeypatch):
    posterior_json(tmp_path / "c.json", COMPOSITE)
    r = run("c.json", "--to", "psse", "--out", "e.dyd", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 0, r.output
    assert (tmp_path / "e.raw").read_text().startswith("0,")
    assert (tmp_path / "e.dyd").read_text().startswith("cmpldw ")
    r = run("c.json", "--to", "psse", "--out", "f.summary.txt", cwd=tmp_path,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2 and "ends in .raw" in r.stderr, r.output


def test_m6_shares_that_do_not_sum_to_one_are_refused(tmp_path, monkeypatch):
    posterior_json(tmp_path / "c.json", {**COMPOSITE, "a1": 0.5, "a2": 0.4, "a3": 0.5})
    for fmt, out in (("psse", "c.raw"), ("pandapower", "n.json")):
        r = run("c.json", "--to", fmt, "--out", out, cwd=tmp_path, monkeypatch=monkeypatch)
        assert r.exit_code == 2, (fmt, r.output)
        assert "a1, a2, a3 must be finite and sum to 1" in r.stderr, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]


# --------------------------------------------------- ANDES: the case bus's own load
def _ieee14():
    andes = pytest.importorskip("andes")
    return andes.get_case("ieee14/ieee14_full.xlsx")


def test_case_bus_with_a_load_needs_replace_or_add(tmp_path, monkeypatch):
    case = _ieee14()
    posterior_json(tmp_path / "c.json", COMPOSITE)
    base = ("c.json", "--to", "andes", "--case", case, "--bus", 14)
    r = run(*base, "--out", "x.xlsx", cwd=tmp_path, monkeypatch=monkeypatch)
    assert r.exit_code == 2, r.output
    assert "--replace-load" in r.stderr and "--add-load" in r.stderr
    assert not (tmp_path / "x.xlsx").exists()
    import andes

    for mode, u in (("--replace-load", 0), ("--add-load", 1)):
        out = f"{mode[2:]}.xlsx"
        r = run(*base, "--out", out, mode, cwd=tmp_path, monkeypatch=monkeypatch)
        assert r.exit_code == 0, r.output
        assert ("put out of service" if u == 0 else "kept in service") in r.stderr
        ss = andes.load(str(tmp_path / out), setup=False, no_output=True, default_config=True)
        own = [ss.PQ.u.v[k] for k, b in enumerate(ss.PQ.bus.v)
               if b == 14 and ss.PQ.idx.v[k] != "loadbayes_pq"]  # fmt: skip
        assert own == [u]
        assert mode in (tmp_path / f"{out}.summary.txt").read_text()


# ------------------------------------------------------ H5: --draws is one transaction
@pytest.fixture
def draws_nc(tmp_path):
    rng = np.random.default_rng(3)
    draws = {k: v + 0.01 * abs(v) * rng.standard_normal((2, 30)) for k, v in COMPOSITE.items()
             if k not in ("a3", "a6", "a", "b", "c", "v0")}  # fmt: skip
    draws.update({k: np.full((2, 30), COMPOSITE[k]) for k in ("a", "b", "c", "v0")})
    draws["a3"] = 1 - draws["a1"] - draws["a2"]
    draws["a6"] = 1 - draws["a4"] - draws["a5"]
    post = Posterior(
        draws,
        model="composite",
        method="mwg-adaptive-metropolis",
        settings={"s_base_mva": 10.0, "v_base_kv": 11.0, "f_hz": 60.0},
    )
    post.to_netcdf(tmp_path / "p.nc")
    return tmp_path / "p.nc"


def test_h5_a_signal_during_draws_leaves_nothing_and_says_so(draws_nc, monkeypatch):
    import loadbayes.export.pandapower as writer

    real, calls = writer.write, []

    def stop_at_third(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            signal.raise_signal(signal.SIGTERM)
        return real(*args, **kwargs)

    monkeypatch.setattr(writer, "write", stop_at_third)
    folder = draws_nc.parent
    r = run("p.nc", "--to", "pandapower", "--out", "d.json", "--draws", 6, cwd=folder,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 143, r.output
    assert "no output was written" in r.stderr
    assert sorted(p.name for p in folder.iterdir()) == ["p.nc"]


def test_h5_a_refused_draw_leaves_nothing(draws_nc, monkeypatch):
    import loadbayes.export.pandapower as writer

    real, calls = writer.write, []

    def refuse_third(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise ValueError("refused by the writer")
        return real(*args, **kwargs)

    monkeypatch.setattr(writer, "write", refuse_third)
    folder = draws_nc.parent
    r = run("p.nc", "--to", "pandapower", "--out", "d.json", "--draws", 6, cwd=folder,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 2 and "refused by the writer" in r.stderr, r.output
    assert sorted(p.name for p in folder.iterdir()) == ["p.nc"]
    monkeypatch.setattr(writer, "write", real)
    r = run("p.nc", "--to", "pandapower", "--out", "d.json", "--draws", 6, cwd=folder,
            monkeypatch=monkeypatch)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert len([p for p in folder.iterdir() if p.name.startswith("d_draw")]) == 12
