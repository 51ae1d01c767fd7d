"""Test-wide settings.

The fit entry points issue a fit's warnings as :class:`loadbayes.posterior.FitWarning`
as well as keeping them in ``post.warnings``. Under ``filterwarnings = error`` every test
of degenerate data would stop at the warning instead of checking ``post.warnings``, which
is what those tests assert on; so FitWarning is ignored here, and the warning channel
itself is tested with ``pytest.warns`` (which records whatever the filters say) in
``tests/unit/test_api.py``. Every other warning still fails a test.
"""

import os
import subprocess
import sys

import pytest

#: NumPy's dispatch targets that bring its own AVX-512 elementary functions.
_AVX512_TARGETS = ("X86_V4", "AVX512")

_PROBE = """
try:
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
except ImportError:
    from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
print(int(bool(__cpu_features__.get("AVX512F"))), *__cpu_dispatch__)
"""


def _same_arithmetic_in_numpy_and_numba() -> None:
    """On a CPU with AVX-512: NumPy's and numba's arithmetic made the same, for every worker.

    Several tests run one algorithm twice, in NumPy and compiled by numba, and ask for the
    same draws bit for bit (``test_compiled_chain``, ``test_parts_ar1``,
    ``test_composite_bounded``): any changed step shows as a different draw. On a CPU
    with AVX-512 (measured on an AMD Zen 4) the two differ in the last bit where the
    algorithm does not:

    - NumPy dispatches ``exp``, ``log``, ``expm1``, ``log1p`` and ``arctan2`` to its own
      AVX-512 versions (``np.exp`` differs from the C library's, which numba calls, on
      4,663 of 100,000 normal draws, ``np.log1p`` on 8,561); with its X86_V4 target off,
      on none (``NPY_DISABLE_CPU_FEATURES``);
    - NumPy's and SciPy's OpenBLAS (two builds; numba's linear algebra calls SciPy's)
      both pick their SkylakeX kernels, which round small products and factorisations
      differently from each other; with both on the Haswell kernels
      (``OPENBLAS_CORETYPE``, which any AVX-512 CPU runs) they agree.

    There the two paths drifted apart by 1e-6 within a few hundred iterations and the
    comparisons failed on arithmetic. Both variables are read when the libraries load:
    set here, before any test module imports NumPy, and inherited by the workers and the
    processes the tests start. A user's process keeps its fastest kernels: the package
    promises the same posterior on every CPU, not the same bits. NumPy's target names vary
    with its version, so they are read from NumPy itself, in a child process, once.
    """
    if "numpy" in sys.modules or "NPY_DISABLE_CPU_FEATURES" in os.environ:
        return
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                             timeout=60, check=True).stdout.split()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return
    if not out or out[0] != "1":
        return
    off = [t for t in out[1:] if t.startswith(_AVX512_TARGETS)]
    if off:
        os.environ["NPY_DISABLE_CPU_FEATURES"] = " ".join(off)
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")


_same_arithmetic_in_numpy_and_numba()


def _rank(item) -> int:
    """Statistical tests first, then integration, then the rest (see below)."""
    if item.get_closest_marker("statistical"):
        return 0
    return 1 if item.get_closest_marker("integration") else 2


def pytest_collection_modifyitems(items):  # noqa: D103
    for item in items:
        item.add_marker(pytest.mark.filterwarnings("ignore::loadbayes.posterior.FitWarning"))
    # The longest tests first (a stable sort: the order within a tier is kept). With
    # `-n 2` a long test collected last ran alone at the end while the other worker had
    # nothing left (the independent-events study: 345 s), and `make test` passed 15
    # minutes; started first, the short ones fill the other worker around it.
    items.sort(key=_rank)


def pytest_configure(config):
    """In each of ``-n 2``'s workers: one BLAS thread (and in the processes they start).

    Two workers on two cores leave no core for a BLAS pool: OpenBLAS's second thread only
    contends (and spins) beside the other worker, where a fit ran 3-4x its CPU on small
    regressions (fit_cvr, fit_steps). A user's process keeps its pools; the tests that
    check the package's own capping (test_fleet_threads) lift this cap around themselves.
    """

    if not hasattr(config, "workerinput"):
        return
    for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")
    from threadpoolctl import threadpool_limits

    config._blas_cap = threadpool_limits(limits=1, user_api="blas")


def pytest_sessionstart(session):
    """With workers (``-n 2``, as ``make test``): the numba kernels compiled once, first.

    Runs before pytest-xdist starts its workers (its hook is ``trylast``); on a fresh
    clone the two workers otherwise compiled the same kernels side by side (about 50 CPU
    s each). ``tests/warm_kernels.py`` says why and what; a warm cache skips it.
    """
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    from warm_kernels import warm

    line = warm()
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(line)


@pytest.fixture
def no_cost_probe(monkeypatch):
    """Skip the composite fit's announced-cost probe (a throw-away timed run).

    Every ``fit composite`` from the CLI times a short run of its own before sampling, to
    announce the cost; on a slow-stepping event it ran hundreds of iterations (97 s of
    a 98 s test under `make test`). Tests that do not check the announcement use this:
    the probe has its own generator, so the draws and the JSON are unchanged (checked:
    the frequency test's JSON equals an unstubbed run's but for the timings). The
    announcement itself is tested in test_composite_estimate and
    test_cli_composite_signals, without it.
    """
    from loadbayes.fit.composite import driver

    monkeypatch.setattr(driver, "_estimate_seconds", lambda *args, **kwargs: 0.0)


@pytest.fixture(scope="session")
def cmld_lite_nc():
    """A cmld-lite posterior of one 15 % sag from the tests' SciPy feeder simulator.

    Frozen draws (``tests/data/cmld_lite_draws.nc``; ``tests/make_cmld_lite_draws.py``
    made it and says why): what ``predict`` and ``export --planning`` do with a fit of
    parts, the same draws on every machine.
    """
    from pathlib import Path

    return Path(__file__).resolve().parent / "data" / "cmld_lite_draws.nc"


@pytest.fixture(scope="session")
def cmld_lite_short_nc():
    """The same data's one chain of 300 (``tests/data/cmld_lite_short_draws.nc``).

    Wild static Q, where the feeder loop's sweeps fail at deep sags: the march's tests.
    """
    from pathlib import Path

    return Path(__file__).resolve().parent / "data" / "cmld_lite_short_draws.nc"
