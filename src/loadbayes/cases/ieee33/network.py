"""The 33-bus case itself: its constants, pandapower access, ZIP shares, the base case.

pandapower is imported only when a function here needs it (``loadbayes[grid]``).
"""

from __future__ import annotations

import copy
import functools
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

#: pandapower index of the ZIP bus (the paper's bus 18).
ZIP_BUS = 17
#: Number of loads other than the ZIP load, i.e. columns of a load-factor matrix.
N_FACTORS = 31
#: The paper's true ZIP shares (Z, I, P), for both P and Q.
DEFAULT_ZIP = (0.25, 0.25, 0.5)
#: Power-flow engines, by name (see the notes of :mod:`loadbayes.cases.ieee33`).
ENGINES = ("newton", "recycle", "runpp")

Engine = Literal["newton", "recycle", "runpp"]
_ZIP_COLUMNS = ("const_z_p_percent", "const_i_p_percent", "const_z_q_percent", "const_i_q_percent")
_GRID_HINT = "pandapower is needed for the IEEE 33-bus case: pip install loadbayes[grid]"


class BusSolution(NamedTuple):
    """Result of one power flow at the ZIP bus (per unit of the nominal load)."""

    v_pu: float
    p_pu: float
    q_pu: float
    converged: bool


def _pandapower() -> tuple[Any, Any]:
    try:
        import pandapower
        import pandapower.networks
    except ImportError as err:
        raise ImportError(_GRID_HINT) from err
    return pandapower, pandapower.networks


@functools.cache
def _pristine_case() -> Any:
    return _pandapower()[1].case33bw()


def _case33bw() -> Any:
    # Reading the case from JSON takes most of a second; a deep copy takes milliseconds.
    return copy.deepcopy(_pristine_case())


def as_zip(coeffs: ArrayLike, name: str = "zip") -> np.ndarray:
    """Return ZIP shares as ``(..., 3)`` with ``a3 = 1 - a1 - a2``.

    Accepts ``(..., 2)`` (a1, a2) or ``(..., 3)`` (a1, a2, a3) whose rows sum to one.
    """
    a = np.asarray(coeffs, dtype=float)
    if a.ndim == 0 or a.shape[-1] not in (2, 3):
        raise ValueError(f"{name}: expected (a1, a2) or (a1, a2, a3), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: coefficients must be finite")
    if a.shape[-1] == 3 and not np.allclose(a.sum(axis=-1), 1.0, rtol=0, atol=1e-9):
        raise ValueError(f"{name}: a1 + a2 + a3 must be 1, got {a.sum(axis=-1)}")
    out = np.empty((*a.shape[:-1], 3))
    out[..., :2] = a[..., :2]
    # pandapower derives the constant-power share the same way.
    out[..., 2] = 1.0 - a[..., 0] - a[..., 1]
    return out


def _per_row(shares: np.ndarray, n: int, name: str) -> np.ndarray:
    if shares.ndim == 2 and shares.shape[0] != n:
        raise ValueError(f"{name}: {shares.shape[0]} rows of shares for {n} experiments")
    if shares.ndim > 2:
        raise ValueError(f"{name}: expected shape (3,) or (n, 3), got {shares.shape}")
    return np.broadcast_to(shares, (n, 3))


def base_case() -> dict[str, float | int]:
    """Solve the unmodified ``case33bw`` feeder.

    Returns
    -------
    dict
        ``min_vm_pu`` (lowest bus voltage), ``min_bus`` (its bus in the paper's 1-based
        numbering), ``losses_kw`` (line losses), ``load_p_mw`` and ``load_q_mvar``
        (total load).

    Notes
    -----
    Baran & Wu (1989) report 0.9131 p.u. at bus 18 and 202.7 kW of losses.
    """
    pp, _ = _pandapower()
    net = _case33bw()
    pp.runpp(net)
    return {
        "min_vm_pu": float(net.res_bus.vm_pu.min()),
        "min_bus": int(net.res_bus.vm_pu.idxmin()) + 1,
        "losses_kw": float(net.res_line.pl_mw.sum() * 1e3),
        "load_p_mw": float(net.load.p_mw.sum()),
        "load_q_mvar": float(net.load.q_mvar.sum()),
    }
