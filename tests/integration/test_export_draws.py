"""Monte Carlo exports: N posterior draws, one output each, for every format.

Each output must hold *its* draw: the motor of draw i draws f_m[i] x p0[i] x s_base, read
back from the file (the draw's index is the one its summary names).
"""

import re

import numpy as np
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration

MEAN = {
    "p0": 0.9, "q0": 0.3, "v0": 0.97, "a1": 0.35, "a2": 0.25, "a4": 0.55, "a5": 0.3,
    "f_m": 0.45, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018, "xr": 0.12, "h_s": 0.7,
    "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6,
}  # fmt: skip
S = 20.0
N = 3


@pytest.fixture(scope="module")
def posterior(tmp_path_factory):
    rng = np.random.default_rng(5)
    draws = {}
    for k, v in MEAN.items():
        jitter = 0.0 if k in ("v0", "a", "b", "c") else 0.03 * abs(v)
        draws[k] = v + jitter * rng.standard_normal((2, 40))
    draws["a3"] = 1 - draws["a1"] - draws["a2"]
    draws["a6"] = 1 - draws["a4"] - draws["a5"]
    path = tmp_path_factory.mktemp("mc") / "c.nc"
    bases = {"s_base_mva": S, "v_base_kv": 11.0, "f_hz": 60.0}
    post = Posterior(draws, model="composite", method="mwg-adaptive-metropolis", settings=bases)
    post.to_netcdf(path)
    pooled = {k: np.asarray(v).reshape(-1) for k, v in draws.items()}
    return path, pooled


def _export(post, fmt, out, *extra):
    r = CliRunner().invoke(main, ["export", str(post), "--to", fmt, "--out", str(out),
                                  "--draws", str(N), "--seed", "4", *extra])  # fmt: skip
    assert r.exit_code == 0, r.output
    return r


def _draw_index(summary_path):
    return int(re.search(r"exported: posterior draw (\d+)", summary_path.read_text()).group(1))


def _check_motor(pooled, summary, p_motor):
    i = _draw_index(summary)
    assert p_motor == pytest.approx(pooled["f_m"][i] * pooled["p0"][i] * S, rel=1e-9)
    return i


def test_pandapower_draws(posterior, tmp_path):
    import pandapower as pp

    post, pooled = posterior
    _export(post, "pandapower", tmp_path / "net.json")
    seen = set()
    for k in range(1, N + 1):
        out = tmp_path / f"net_draw{k:03d}.json"
        net = pp.from_json(str(out))
        seen.add(_check_motor(pooled, out.with_name(out.name + ".summary.txt"),
                              net.motor.pn_mech_mw.iloc[0]))  # fmt: skip
    assert len(seen) == N


@pytest.mark.parametrize("record", ["cmldblu2", "cim5bl"])
def test_psse_draws(posterior, tmp_path, record):
    from loadbayes.export.cmld import read_cmldblu2
    from loadbayes.export.psse import read_loads

    post, pooled = posterior
    _export(post, "psse", tmp_path / "case.raw", "--motor-record", record)
    seen = set()
    for k in range(1, N + 1):
        raw = tmp_path / f"case_draw{k:03d}.raw"
        loads = read_loads(raw)
        if record == "cim5bl":
            p_m = loads["M"]["pl"]
        else:
            p_m = read_cmldblu2(raw.with_suffix(".dyr"))["Fma"] * loads["1"]["pl"]
            assert raw.with_suffix(".dyd").is_file()
        seen.add(_check_motor(pooled, raw.with_name(raw.name + ".summary.txt"), p_m))
    assert len(seen) == N


def test_andes_draws(posterior, tmp_path):
    pytest.importorskip("andes")
    post, _ = posterior
    r = _export(post, "andes", tmp_path / "case.xlsx")
    written = sorted(p.name for p in tmp_path.glob("case_draw*.xlsx"))
    assert written == [f"case_draw{k:03d}.xlsx" for k in range(1, N + 1)], r.output
