"""Under an address-space limit (``ulimit -v``), one line and exit 2 (issue 40, red-team H8).

Before: ``fit zip`` under 650-800 MB hung for ever (Arrow's jemalloc and OpenBLAS's threads
retrying ``mmap``), ``fit composite`` under 2 GB aborted natively (exit 134).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytestmark = pytest.mark.integration

SRC = str(Path(__file__).resolve().parents[2] / "src")
LIMITED = (
    "import os, resource, sys; n = int(sys.argv[1]); "
    "resource.setrlimit(resource.RLIMIT_AS, (n, resource.RLIM_INFINITY)); "
    "os.execv(sys.executable, [sys.executable, '-m', 'loadbayes', *sys.argv[2:]])"
)


def run_limited(limit: int, args, *, cwd) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "ARROW_DEFAULT_MEMORY_POOL"):
        env.pop(name, None)  # as a user's shell has them: unset
    cmd = [sys.executable, "-c", LIMITED, str(limit), *map(str, args)]
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        out, err = proc.communicate(timeout=90)
    except subprocess.TimeoutExpired:  # the hang: a failure of this test, not of the suite
        proc.kill()
        proc.communicate()
        pytest.fail(f"{args[:2]} under a {limit >> 20} MiB limit did not end in 90 s")
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


def test_fit_zip_under_a_small_memory_limit_is_one_line(tmp_path):
    rng = np.random.default_rng(1)
    v = rng.uniform(0.95, 1.05, 300)
    pd.DataFrame({"v": v, "p": 0.2 * v**2 + 0.3 * v + 0.5 + rng.normal(0, 0.01, 300)}).to_csv(
        tmp_path / "bus.csv", index=False
    )
    r = run_limited(650 * 10**6, ["fit", "zip", "bus.csv", "--draws", "500", "--burn", "100",
                                  "--quiet", "--json", "m.json"], cwd=tmp_path)  # fmt: skip
    assert r.returncode == 2, r.stderr[-3000:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error: not enough memory: "), lines
    assert "ulimit -v" in lines[0]
    # Lower still, the libraries cannot even be mapped: the same line, not an ImportError.
    r = run_limited(500 * 10**6, ["fit", "zip", "bus.csv", "--quiet"], cwd=tmp_path)
    low = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(low) == 1 and "is 477 MiB; raise it" in low[0], low
    assert sorted(os.listdir(tmp_path)) == ["bus.csv"]


def test_fit_composite_under_2_gb_is_refused_before_any_work(tmp_path):
    r = run_limited(2 * 10**9, ["fit", "composite", "sag.csv", "--json", "c.json"], cwd=tmp_path)
    (tmp_path / "sag.csv").write_text("t_s,v,p,q\n")  # never read: refused first
    assert r.returncode == 2, r.stderr[-3000:]
    assert r.stderr.strip().splitlines() == [
        "loadbayes: error: not enough memory: fit composite needs about 3 GiB of address "
        "space and the limit (ulimit -v) is 1.86 GiB; raise it"
    ]
