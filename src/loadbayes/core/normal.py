"""The standard normal's CDF, its log and its inverse in compiled code: SciPy's own.

numba compiles no call into ``scipy.special``, and a ctypes pointer to SciPy's C function
would keep every caller out of numba's cache (an address is a "dynamic global"). So the
C functions SciPy exports for Cython (``scipy.special.cython_special``: ``ndtr``,
``log_ndtr`` and ``ndtri`` on doubles) are registered with LLVM under names of their own
when this module is imported, and compiled code calls them by name (:func:`ndtr`,
:func:`log_ndtr`, :func:`ndtri`): a cached function holds the name, not the address, and
the numbers are ``scipy.special``'s to the bit (``tests/unit/test_normal.py``).
"""

from __future__ import annotations

from llvmlite import binding, ir
from numba.core import cgutils, types
from numba.extending import get_cython_function_address, intrinsic

__all__ = ["log_ndtr", "ndtr", "ndtri"]

#: The name each function is registered under, and SciPy's (the double-precision one).
_SYMBOLS = {
    "loadbayes_ndtr": "__pyx_fuse_1ndtr",
    "loadbayes_log_ndtr": "__pyx_fuse_1log_ndtr",
    "loadbayes_ndtri": "ndtri",
}
for _name, _scipy in _SYMBOLS.items():
    binding.add_symbol(_name, get_cython_function_address("scipy.special.cython_special", _scipy))


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
