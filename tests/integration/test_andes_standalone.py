"""An exported ANDES case runs in ANDES alone: a process that cannot import loadbayes.

``export --to andes`` (no ``--bus``: the single-bus case) writes a composite; a child
Python in isolated mode (``-I``, an empty environment, a temporary folder, loadbayes's
path entries removed and its import blocked) loads it with ANDES's own reader, runs
ANDES's power flow with ANDES's defaults (KLU) and a time-domain run with a fault on the
load bus, and prints what it found. The parent checks it against loadbayes's steady state.

The negative control writes the same case with the ``_config`` rows that make it
solvable turned back to ANDES's defaults: ANDES 2.0's KLU then kills the child with a
segmentation fault (docs/andes.md, "The power flow").
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")

from click.testing import CliRunner  # noqa: E402

from loadbayes.cli import main  # noqa: E402
from loadbayes.models.motor import MotorParams, steady_state  # noqa: E402

pytestmark = pytest.mark.integration

MOTOR = {"rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018, "xr": 0.18, "h_s": 0.7, "a": 1.0,
         "b": 0.0, "c": 0.0}  # fmt: skip
VALUES = {"p0": 1.0, "q0": 0.45, "v0": 1.02, "a1": 0.4, "a2": 0.3, "a3": 0.3, "a4": 0.5,
          "a5": 0.3, "a6": 0.2, "f_m": 0.4, "t0": 0.6, "q_c": 0.05, **MOTOR}  # fmt: skip

CHILD = r"""
import json, os, sys
# Whatever installed loadbayes (an editable .pth adds its source folder) is taken away.
sys.path[:] = [p for p in sys.path if not os.path.isdir(os.path.join(p or ".", "loadbayes"))]
class Block:
    def find_spec(self, name, path=None, target=None):
        if name == "loadbayes" or name.startswith("loadbayes."):
            raise ImportError("loadbayes is not installed here")
sys.meta_path.insert(0, Block())
out = {}
try:
    import loadbayes  # noqa
    out["loadbayes"] = True
except ImportError:
    out["loadbayes"] = False
import andes
# file=False and a log_path: ANDES makes a new /tmp/andes-* folder whenever log_path is None
andes.config_logger(stream_level=50, file=False, log_path=os.path.dirname(sys.argv[1]))
ss = andes.load(sys.argv[1], setup=False, no_output=True, default_config=True)
ss.add("Fault", {"idx": 1, "bus": 1, "tf": 0.2, "tc": 0.3, "xf": 0.08})
ss.setup()
out["sparselib"] = ss.PFlow.solver.sparselib
out["pflow"] = bool(ss.PFlow.run())
out["v"] = float(ss.Bus.v.v[0])
m = ss.Motor3
out.update(slip=float(m.slip.v[0]), p_motor=float(m.p.v[0]), q_motor=float(m.q.v[0]))
ss.TDS.config.tf, ss.TDS.config.no_tqdm = 1.5, 1
out["tds"] = bool(ss.TDS.run())
out["t_end"] = float(ss.dae.ts.t[-1])
v = ss.dae.ts.y[:, ss.Bus.v.a[0]]
out.update(v_min=float(v.min()), v_end=float(v[-1]), slip_end=float(m.slip.v[0]))
out["modules"] = sorted(k for k in sys.modules if k.startswith("loadbayes"))
print(json.dumps(out))
"""


def _export(folder: Path) -> Path:
    doc = {
        "model": "composite",
        "parameters": {k: {"mean": v} for k, v in VALUES.items()},
        "settings": {"v0": VALUES["v0"]},
    }
    (folder / "post.json").write_text(json.dumps(doc))
    r = CliRunner().invoke(
        main, ["export", str(folder / "post.json"), "--to", "andes", "--out",
               str(folder / "case.json"), "--quiet"],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    return folder / "case.json"


def _child(case: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-I", "-c", CHILD, str(case)],
        env={"PATH": "/usr/bin:/bin"},
        cwd=case.parent,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_andes_alone_solves_the_exported_composite(tmp_path):
    r = _child(_export(tmp_path))
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["loadbayes"] is False and got["modules"] == []
    assert got["sparselib"] == "klu"  # ANDES's default solver, nothing swapped
    assert got["pflow"] and got["tds"] and got["t_end"] == pytest.approx(1.5)
    # ANDES's power flow, from its own start-up guess (slip = 1), lands where loadbayes's
    # steady state is: load bus at v0, motor drawing f_m p0 at the steady slip.
    params = MotorParams(**MOTOR, name="test")
    op = steady_state(params, v_pu=VALUES["v0"], t0=VALUES["t0"])
    assert got["v"] == pytest.approx(VALUES["v0"], abs=1e-6)
    assert got["p_motor"] == pytest.approx(VALUES["f_m"] * VALUES["p0"], rel=1e-6)
    assert got["slip"] == pytest.approx(op.slip, rel=1e-5)
    assert got["q_motor"] == pytest.approx(got["p_motor"] * op.q / op.p, rel=1e-5)
    # The fault made a real sag, and the load came back to its operating point.
    assert got["v_min"] < 0.7 * VALUES["v0"]
    assert got["v_end"] == pytest.approx(VALUES["v0"], abs=5e-3)
    assert got["slip_end"] == pytest.approx(op.slip, rel=0.05)


@pytest.mark.skipif(
    not __import__("andes").__version__.startswith("2.0."),
    reason="the KLU crash is ANDES 2.0's; a later ANDES may not have it",
)
def test_without_the_case_config_andes_klu_crashes(tmp_path):
    case = _export(tmp_path)
    doc = json.loads(case.read_text())
    rows = [r for r in doc["_config"] if r["key"] == "linsolve"]
    assert {(r["section"], r["value"]) for r in rows} >= {("PFlow", 1), ("TDS", 1)}
    for row in rows:
        row["value"] = 0
    case.write_text(json.dumps(doc))
    r = _child(case)
    assert r.returncode == -11, (r.returncode, r.stderr[-500:])  # SIGSEGV
