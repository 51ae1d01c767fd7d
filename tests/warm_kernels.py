"""Compile the package's numba kernels into their on-disk cache before the tests start.

A fresh clone has no cache: each of ``make test``'s two workers (and every CLI test's
subprocess started before a kernel's cache is written) compiled the same kernels, about
22 CPU s for the composite fit's path alone. :func:`warm` runs two processes, each a
share of the kernels, once, before the workers start (``tests/conftest.py``); a tree
whose cache is already there skips it. Nothing here is asserted: the tests that call the
same code check it. A part that fails is said and the session goes on (its kernels then
compile where they are first used, as before).

Usage: ``python tests/warm_kernels.py a`` (or ``b``), or :func:`warm` for both.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _event(sag: float = 0.2):
    import numpy as np

    from feeder_generator import simulate
    from loadbayes.measurements.record import EventRecord

    rng = np.random.default_rng(0)
    t, v, d, p, q, _ = simulate(sag=sag)
    noise = 0.005 * np.hypot(p[0], q[0])
    return EventRecord(t, v, p + rng.normal(0, noise, t.size), q + rng.normal(0, noise, t.size),
                       d, f"sag {sag}")  # fmt: skip


def part_a() -> None:
    """ZIP (one level, drifting), zip+motor (point and window readings), its predict; tracker."""
    import tempfile
    from importlib.resources import files

    import loadbayes as lb

    with tempfile.TemporaryDirectory() as tmp:
        bus = Path(tmp) / "bus.csv"  # the README's example day
        bus.write_text(files("loadbayes").joinpath("data", "zip_example.csv").read_text())
        s = lb.SamplerSettings(draws=300, burn=100, chains=2, seed=0)
        lb.fit_zip(bus, spec=lb.DataSpec(v_base=11, s_base=5), sampler=s)
        lb.fit_zip(bus, spec=lb.DataSpec(v_base=11, s_base=5, t_col="time"), level="drift",
                   sampler=s)  # fmt: skip
    ev, s = _event(), lb.SamplerSettings(draws=300, burn=150, chains=2, seed=0)
    for window in (0.0, None):
        fit = lb.fit_composite(lb.CompositeModel(f_hz=50.0, window_s=window), [ev], sampler=s)
    lb.predict(fit.posterior, sag=0.4, duration=0.1, draws=20)
    _track()


def part_b() -> None:
    """The parts models (slm, cmld-lite), their play and predict; fleets.

    The warm-up lasts as long as its longer part, so the fleet and the tracker go where
    they even the two out (both parts at once into one empty cache, 2 idle cores, 30 Nov
    2026): with both here, a took 68 s and b 81 s; with the tracker in part a, 74 s each.
    Putting the fleet first here, so that part a's zip+motor fits would cache the kernels
    both parts use (the motor's, R-hat) before b asked for them, gained nothing (81 s).
    """
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.fit.composite.predict import predict
    from loadbayes.models.dynamic import dynamic_model

    ev = _event()
    s = SamplerSettings(draws=200, burn=100, chains=1, seed=0)
    for name in ("slm", "cmld-lite"):
        fit = fit_composite(dynamic_model(name, f_hz=50.0), [ev], sampler=s)
        predict(fit.posterior, sag=0.45, duration=0.1, draws=20)
    _fleet()


def _fleet() -> None:
    # A fleet pooled by class (the hierarchical kernels).
    import tempfile

    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fleet.generate import fleet_truth, write_fleet
    from loadbayes.fleet.partitions import ReadSpec
    from loadbayes.fleet.run import run_fleet

    with tempfile.TemporaryDirectory() as tmp:
        write_fleet(fleet_truth(12, seed=4, rows=(10, 100)), Path(tmp), layout="table")
        run_fleet(
            str(Path(tmp) / "fleet.parquet"),
            ReadSpec(class_col="customer_class"),
            pool="class",
            sampler=SamplerSettings(chains=2, draws=60, burn=20, seed=1),
        )


def _track() -> None:
    # The online tracker's kernels.
    import tempfile

    import numpy as np
    import pandas as pd

    from loadbayes.fit.track import track_zip

    with tempfile.TemporaryDirectory() as tmp:
        rng = np.random.default_rng(0)
        v = 1 + 0.05 * np.sin(np.linspace(0, 12, 300)) + rng.normal(0, 0.002, 300)
        shape = 0.4 * v**2 + 0.3 * v + 0.3
        bus = Path(tmp) / "bus.csv"
        pd.DataFrame({"t": np.arange(300) * 0.1, "v": v, "p": 2 * shape,
                      "q": 0.5 * shape}).to_csv(bus, index=False)  # fmt: skip
        for _ in track_zip(str(bus), forgetting=0.999):
            pass


def _cache_is_warm() -> bool:
    import importlib.util

    # The import first: its guard (loadbayes/_numba_cache.py) deletes caches built from
    # other sources. Looked at before it, a tree whose numba sources had changed since its
    # last run counted as warm, and both workers then compiled every kernel side by side
    # (a whole suite at 941 s, as long as the warmed run it should have beaten).
    import loadbayes  # noqa: F401

    spec = importlib.util.find_spec("loadbayes")
    roots = [Path(spec.origin).parent] if spec and spec.origin else []
    if os.environ.get("NUMBA_CACHE_DIR"):
        roots.append(Path(os.environ["NUMBA_CACHE_DIR"]))
    return any(next(r.rglob("*.nbi"), None) for r in roots if r.is_dir())


def warm() -> str:
    """Run both parts in parallel processes; the line to print."""
    if _cache_is_warm():
        return "numba cache present: no warm-up"
    t0 = time.perf_counter()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE), env.get("PYTHONPATH")]))
    procs = {k: subprocess.Popen([sys.executable, str(Path(__file__)), k], env=env,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
             for k in ("a", "b")}  # fmt: skip
    failed = []
    for k, proc in procs.items():
        try:
            _, err = proc.communicate(timeout=600)
        except subprocess.TimeoutExpired:
            proc.kill()
            err = "timed out after 600 s"
        if proc.returncode:
            failed.append(f"part {k}: {(err or '').strip().splitlines()[-1:] or ['?']}")
    said = f"numba kernels compiled in {time.perf_counter() - t0:.0f} s by two processes"
    return said + (f" ({'; '.join(failed)}: those compile where first used)" if failed else "")


if __name__ == "__main__":
    import warnings

    warnings.simplefilter("ignore")
    {"a": part_a, "b": part_b}[sys.argv[1]]()
