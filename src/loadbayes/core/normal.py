"""The standard normal's CDF, its log and its inverse in compiled code: SciPy's own.

numba compiles no call into ``scipy.special``, and a ctypes pointer to SciPy's C function
would keep every caller out of numba's cache (an address is a "dynamic global"). So the
C functions SciPy exports for Cython (``scipy.special.cython_special``: ``ndtr``,
``log_ndtr`` and ``ndtri`` on doubles) are registered with LLVM under names of their own
when this module is imported, and compiled code calls them by name (:func:`ndtr`,
:func:`log_ndtr`, :func:`ndtri`): a cached function holds the name, not the address, and
the numbers are ``scipy.special``'s to the bit (``tests/unit/test_parts_density.py``). Beside
them, :func:`log_add_exp`, NumPy's ``logaddexp`` in compiled code, which the log-densities
built on them share.
"""

from __future__ import annotations

import ctypes
import math
import re

import numba
from llvmlite import binding, ir
from numba.core import cgutils, types
from numba.extending import get_cython_function_address, intrinsic
from scipy.special import cython_special

__all__ = ["log_add_exp", "log_ndtr", "ndtr", "ndtri"]

#: The name each function is registered under, and SciPy's.
_SYMBOLS = {"loadbayes_ndtr": "ndtr", "loadbayes_log_ndtr": "log_ndtr", "loadbayes_ndtri": "ndtri"}
#: The C signature of the one taken (a fused function has a complex twin beside it).
_SIGNATURE = b"double (double, int __pyx_skip_dispatch)"


def _double_version(name: str) -> str:
    # SciPy's exported name of ``name`` on doubles: itself, or one of its fused copies
    # (``__pyx_fuse_<k>name``), told apart by their capsules' signatures.
    capi = cython_special.__pyx_capi__
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    for key in sorted(capi):
        if re.fullmatch(rf"(__pyx_fuse_\d+)?{name}", key) and get_name(capi[key]) == _SIGNATURE:
            return key
    raise ImportError(f"scipy.special.cython_special has no {name}(double): SciPy changed")


for _name, _scipy in _SYMBOLS.items():
    binding.add_symbol(_name, get_cython_function_address("scipy.special.cython_special",
                                                          _double_version(_scipy)))  # fmt: skip


def _external(name: str):
    # A compiled call of the registered C function ``double f(double, int skip_dispatch)``.
    @intrinsic
    def call(typingctx, x):
        def codegen(context, builder, signature, args):
            fnty = ir.FunctionType(ir.DoubleType(), [ir.DoubleType(), ir.IntType(32)])
            fn = cgutils.get_or_insert_function(builder.module, fnty, name)
            return builder.call(fn, [args[0], ir.Constant(ir.IntType(32), 0)])

        return types.float64(types.float64), codegen

    return call


#: ``Phi(x)``, ``log Phi(x)`` and ``Phi^-1(p)`` of a float, for compiled code only.
ndtr = _external("loadbayes_ndtr")
log_ndtr = _external("loadbayes_log_ndtr")
ndtri = _external("loadbayes_ndtri")


_LOG2 = math.log(2.0)


@numba.njit(cache=True, nogil=True)
def log_add_exp(x, y):  # pragma: no cover - compiled
    """NumPy's ``logaddexp`` of two floats (``npy_logaddexp``), its branches in its order."""
    if x == y:
        return x + _LOG2
    d = x - y
    if d > 0:
        return x + math.log1p(math.exp(-d))
    if d <= 0:
        return y + math.log1p(math.exp(d))
    return d
