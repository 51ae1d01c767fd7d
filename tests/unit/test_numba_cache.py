"""The package's guard against numba's stale cache (loadbayes/_numba_cache.py).

Numba keys a cached function by its own file's time stamp, so a cached caller keeps the
old code of a callee in another file. The test shows that premise on a two-file package
written here, then that ``purge_stale`` makes the caller see the new callee.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

from loadbayes import _numba_cache

CALLER = """
import numba
from pkg.callee import g

@numba.njit(cache=True)
def f():
    return g()
"""

RUN = "import sys; sys.path.insert(0, {root!r}); {pre}from pkg.caller import f; print(f())"


def _call(root, pre=""):
    # -B: no .pyc of the package written here. Python checks a .pyc by its source's size and
    # mtime in whole seconds, and callee.py is rewritten at the same size: where the first
    # call took under a second, the later ones ran the old callee from its .pyc, and the
    # purged caller still gave 1 (a fresh clone's make test, 30 Nov 2026, once `make test`
    # let pytest write bytecode). The test is about numba's cache, not Python's.
    code = RUN.format(root=str(root), pre=pre)
    out = subprocess.run([sys.executable, "-B", "-c", code], capture_output=True, text=True,
                         check=True)  # fmt: skip
    return out.stdout.strip()


def _callee(pkg, value):
    (pkg / "callee.py").write_text(f"import numba\n\n@numba.njit\ndef g():\n    return {value}\n")


def test_a_changed_callee_is_seen_after_the_purge(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "caller.py").write_text(textwrap.dedent(CALLER))
    _callee(pkg, 1)
    assert _numba_cache.purge_stale(pkg) is False  # no cache yet: nothing to delete
    assert _call(tmp_path) == "1"
    assert list((pkg / "__pycache__").glob("caller.f-*.nbi"))
    _callee(pkg, 2)
    # Numba's own behaviour, the reason for the guard: the cached caller keeps g's old code.
    assert _call(tmp_path) == "1"
    purge = (
        "from pathlib import Path; from loadbayes._numba_cache import purge_stale; "
        f"purge_stale(Path({str(pkg)!r})); "
    )
    assert _call(tmp_path, pre=purge) == "2"
    # The stamp now matches: a second import keeps the fresh cache.
    assert _numba_cache.purge_stale(pkg) is False
    assert list((pkg / "__pycache__").glob("caller.f-*.nbi"))


def test_the_user_cache_folder_is_named_as_numba_names_it(tmp_path, monkeypatch):
    from numba.core.caching import _CacheLocator

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "sub" / "m.py").write_text("")
    want = tmp_path / "cache" / _CacheLocator.get_suitable_cache_subpath(str(pkg / "sub" / "m.py"))
    assert want in _numba_cache.cache_dirs(pkg)
