"""`loadbayes fit zip` stays quick: it loads only what a ZIP fit needs (issue 25).

The command runs in a fresh process on data written here; the test lists the heavy
packages it imported. ArviZ (with xarray, matplotlib and dask behind it), pandapower,
scipy.stats and the plotting code cost seconds at start-up and a ZIP fit uses none of
them: the summary's R-hat and ESS are compiled (loadbayes.core.convergence). Times are
not checked here (a shared CI machine is no clock): that is benchmarks/bench_cli.py.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.integration

HEAVY = ("arviz", "xarray", "matplotlib", "dask", "pandapower", "scipy.stats", "andes")

_RUN = """
import json, runpy, sys
sys.argv = ["loadbayes"] + sys.argv[1:]
try:
    runpy.run_module("loadbayes", run_name="__main__")
except SystemExit as exc:
    code = exc.code
else:
    code = 0
heavy = sorted(m for m in sys.modules if m in HEAVY)
sys.stderr.write("MODULES" + json.dumps({"code": code, "heavy": heavy}) + "\\n")
"""


def test_fit_zip_imports_no_heavy_package(tmp_path):
    rng = np.random.default_rng(11)
    v = rng.uniform(0.9, 1.06, 400)
    p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, v.size)
    q = 0.5 * v**2 + 0.1 * v + 0.4 + rng.normal(0, 0.01, v.size)
    rows = "\n".join(f"{a:.6f},{b:.6f},{c:.6f}" for a, b, c in zip(v, p, q, strict=True))
    (tmp_path / "bus.csv").write_text("v,p,q\n" + rows + "\n")
    code = f"HEAVY = {HEAVY!r}\n" + _RUN
    args = ["fit", "zip", "bus.csv", "--draws", "2000", "--burn", "200", "--json", "out.json"]
    proc = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    line = next(x for x in proc.stderr.splitlines() if x.startswith("MODULES"))
    info = json.loads(line[len("MODULES") :])
    assert info["code"] == 0, proc.stderr[-2000:]
    assert info["heavy"] == [], f"fit zip imported {info['heavy']}"
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["parameters"]["a1"]["r_hat"] < 1.01  # the summary is still there
