"""IEEE 33-bus feeder with a ZIP load at bus 18: the paper's power-flow data generator.

The paper (section "Case Study: ZIP") takes the Baran & Wu 33-bus feeder, replaces the
load at bus 18 with a ZIP load, multiplies every other load by its own factor drawn
from U[0.1, 4.5] in each experiment, runs a power flow and records V, P and Q at bus 18.
Here the feeder is pandapower's ``case33bw``; the paper's bus 18 is pandapower bus 17
(the paper numbers buses from 1, pandapower from 0).

ZIP load in pandapower
----------------------
pandapower models the load of bus ``k`` with nominal ``P0 = p_mw * scaling`` as::

    P = P0 (cz V^2 + ci V + (1 - cz - ci)),   cz = const_z_p_percent / 100,
                                              ci = const_i_p_percent / 100

with ``V = vm_pu`` relative to the bus's ``vn_kv`` (so V0 = 1.0 p.u.), and the same for
Q with ``const_z_q_percent`` and ``const_i_q_percent``. So the paper's ``a1 = cz``,
``a2 = ci``, ``a3 = 1 - a1 - a2`` (``a4``, ``a5``, ``a6`` for Q), and
``y = P / P0`` in this module is ``res_load.p_mw / p_mw``. Checked in pandapower 3.5:
``res_load`` and ``res_bus`` follow the formula to machine precision, and the network
injection ``V conj(Ybus V)`` at bus 17 matches it to the power-flow tolerance.

Coefficient limits found in pandapower 3.5: a negative ``a1`` or ``a2`` (a percent below
0 or above 100) is accepted and solved correctly; ``a1 + a2 > 1`` (a negative constant-
power share ``a3``) is refused with a ``ValueError`` when the case is built. The
``"newton"`` engine writes the shares into the solver's bus matrix directly, so it takes
any real coefficients that sum to one; ``"runpp"`` and ``"recycle"`` cannot take a3 < 0.
pandapower also *averages* the percentages of all loads at a bus without weighting them
by their power, and ``res_load`` then disagrees with the power flow; that is why
exactly one load sits at bus 17 here.

Engines (``Feeder33(engine=...)``)
-----------------------------------
``"newton"`` (default)
    pandapower's own Newton-Raphson (``pandapower.pypower.newtonpf``, the function
    ``runpp`` calls) on the admittance matrix and bus table that a first ``runpp`` built;
    each run only rewrites the bus loads and the ZIP shares and starts flat. It skips
    pandapower's pandas bookkeeping (for a ZIP load that is a Python loop over buses),
    which is most of ``runpp``'s time. It uses pandapower internals, so the feeder checks
    itself against ``runpp`` when it is built.
``"recycle"``
    ``runpp(net, recycle={"bus_pq": True, "trafo": False, "gen": False})``, pandapower's
    time-series fast path. ``bus_pq`` must be True (else the new loads are silently
    ignored); ``trafo`` and ``gen`` may be False because branches and the slack do not
    change. It warm-starts from the previous solution, so results depend on the order of
    runs at the tolerance level, and after a failed run the stale voltages make the next
    feasible runs fail too; the engine therefore does a full ``runpp`` after a failure,
    at the start of every chunk, and when the ZIP shares change (pandapower turns its
    voltage-dependent-load option off when the first full run has no ZIP share).
``"runpp"``
    a plain ``runpp`` per experiment: the reference.

Every engine uses the same tolerance (``tolerance_mva``, default 1e-10; pandapower's
default is 1e-8, compared with the mismatch in per unit of ``net.sn_mva`` = 10 MVA).
Two runs from different starting points then agree to about 1e-10 in V; at 1e-8 they can
differ by 2e-8 at bus 18, because pandapower's Jacobian omits the ZIP load's voltage
derivative and the last Newton step is not quadratically small.
"""

from __future__ import annotations

import copy
import functools
import multiprocessing
import sys
import warnings
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "DEFAULT_ZIP",
    "ENGINES",
    "FACTOR_RANGE",
    "N_FACTORS",
    "ZIP_BUS",
    "BusSolution",
    "Feeder33",
    "base_case",
    "draw_factors",
    "generate_experiments",
    "validate",
]

#: pandapower index of the ZIP bus (the paper's bus 18).
ZIP_BUS = 17
#: Number of loads other than the ZIP load, i.e. columns of a load-factor matrix.
N_FACTORS = 31
#: The paper's true ZIP shares (Z, I, P), for both P and Q.
DEFAULT_ZIP = (0.25, 0.25, 0.5)
#: The paper's range of the per-load factors.
FACTOR_RANGE = (0.1, 4.5)
#: Power-flow engines, by name (see the module notes).
ENGINES = ("newton", "recycle", "runpp")

Engine = Literal["newton", "recycle", "runpp"]
# What an engine returns for one run: V (p.u.), P (MW), Q (Mvar), converged.
_Raw = tuple[float, float, float, bool]
Seed = int | np.random.SeedSequence | None

# Experiments per task. Fixed, not derived from the worker count, so that chunk
# boundaries (where the "recycle" engine restarts cold) and hence every number are the
# same for any number of workers.
_CHUNK = 200
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


def _as_zip(coeffs: ArrayLike, name: str = "zip") -> np.ndarray:
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


def _zip_power(nominal: float, shares: np.ndarray, vm: np.ndarray) -> np.ndarray:
    # Same grouping as pandapower's res_load: constant part plus voltage-dependent part.
    return nominal * shares[..., 2] + nominal * (shares[..., 1] * vm + shares[..., 0] * vm**2)


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


def _streams(seed: Seed, rng: np.random.Generator | None) -> list[np.random.Generator]:
    # Separate streams for the load factors and the noise: the factors of a seed do not
    # depend on the noise settings, and draw_factors can rebuild them alone.
    if rng is not None:
        return rng.spawn(2)
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2)]


def draw_factors(
    n: int,
    *,
    seed: Seed = 0,
    rng: np.random.Generator | None = None,
    factor_range: tuple[float, float] = FACTOR_RANGE,
) -> np.ndarray:
    """Draw the load factors of ``n`` experiments.

    Parameters
    ----------
    n : int
        Number of experiments.
    seed : int or numpy.random.SeedSequence, optional
        Seed; ignored when ``rng`` is given.
    rng : numpy.random.Generator, optional
        Generator to spawn the factor stream from.
    factor_range : (float, float)
        Bounds of the uniform distribution of each factor.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, N_FACTORS)``; column ``j`` multiplies ``p_mw`` and ``q_mvar`` of the
        ``j``-th non-ZIP load (``Feeder33.factor_loads``).

    Notes
    -----
    This is the matrix :func:`generate_experiments` and :func:`validate` use for the same
    ``seed`` (for any ``noise_sd`` and ``workers``). Rows are drawn in order, so the
    first ``k`` rows do not depend on ``n``.
    """
    return _draw(_streams(seed, rng)[0], n, factor_range)


def _draw(gen: np.random.Generator, n: int, factor_range: tuple[float, float]) -> np.ndarray:
    lo, hi = _check_range(factor_range)
    return gen.uniform(lo, hi, size=(int(n), N_FACTORS))


def _check_range(factor_range: tuple[float, float]) -> tuple[float, float]:
    lo, hi = (float(b) for b in factor_range)
    if not 0.0 <= lo <= hi:
        raise ValueError(f"factor_range must satisfy 0 <= low <= high, got {factor_range}")
    return lo, hi


class Feeder33:
    """The 33-bus feeder with one ZIP load at bus 17 (paper's bus 18).

    Parameters
    ----------
    zip_p, zip_q : sequence of float
        ZIP shares (a1, a2, a3) of P and (a4, a5, a6) of Q, Z first; two values mean
        (a1, a2) with a3 = 1 - a1 - a2.
    engine : {"newton", "recycle", "runpp"}
        Power-flow path (see the module notes); all agree to about 1e-10.
    tolerance_mva : float
        Newton mismatch tolerance, in per unit of ``net.sn_mva`` as pandapower uses it.
    max_iteration : int
        Newton iterations before a run counts as not converged.
    numba : bool
        Use pandapower's numba kernels (faster; compiled once per process).

    Attributes
    ----------
    net : pandapowerNet
        The network; its ZIP load is ``net.load.loc[zip_load]``.
    zip_load : int
        Index of the ZIP load in ``net.load``.
    factor_loads : numpy.ndarray
        Indices in ``net.load`` of the loads the factor columns scale, in column order.
    p0_mw, q0_mvar : float
        Nominal P and Q of the ZIP load at V = 1 p.u. (the case's load at bus 17); per
        unit values are relative to these.

    Notes
    -----
    The ``"newton"`` engine does not write ``net.res_*``; those tables hold the last
    ``runpp`` the feeder made (the base-case self-check).
    """

    def __init__(
        self,
        *,
        zip_p: ArrayLike = DEFAULT_ZIP,
        zip_q: ArrayLike = DEFAULT_ZIP,
        engine: Engine = "newton",
        tolerance_mva: float = 1e-10,
        max_iteration: int = 30,
        numba: bool = True,
    ) -> None:
        if engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
        self.zip_p = _as_zip(zip_p, "zip_p")
        self.zip_q = _as_zip(zip_q, "zip_q")
        self.engine = engine
        self.tolerance_mva = float(tolerance_mva)
        self.max_iteration = int(max_iteration)
        self.numba = bool(numba)
        if engine != "newton" and not self._runpp_ok():
            raise ValueError(
                f"engine {engine!r}: pandapower refuses a negative constant-power share "
                "(a1 + a2 > 1); use engine='newton'"
            )
        self._pp, _ = _pandapower()

        net = _case33bw()
        missing = set(_ZIP_COLUMNS) - set(net.load.columns)
        if missing:  # pragma: no cover - older pandapower had const_z_percent only
            raise RuntimeError(f"this pandapower has no load columns {sorted(missing)}")
        at_bus = net.load.index[net.load.bus == ZIP_BUS]
        if len(at_bus) == 0:
            raise RuntimeError(f"case33bw has no load at bus {ZIP_BUS}")
        # One load at the ZIP bus: pandapower averages ZIP percentages over the loads of a
        # bus without weighting them by power, so a second load would distort the model.
        keep = at_bus[0]
        here = net.load.loc[at_bus]
        weight = here.scaling * here.in_service
        merged = [(here.p_mw * weight).sum(), (here.q_mvar * weight).sum(), 1.0, True]
        net.load.loc[keep, ["p_mw", "q_mvar", "scaling", "in_service"]] = merged
        net.load = net.load.drop(index=at_bus[1:])
        others = net.load.index[(net.load.bus != ZIP_BUS) & net.load.in_service]
        if len(others) != N_FACTORS or not net.load.in_service.at[keep]:
            raise RuntimeError("case33bw does not have the expected 31 + 1 loads")
        self.net = net
        self.zip_load = int(keep)
        self.factor_loads = others.to_numpy()
        self.p0_mw = float(net.load.p_mw.at[keep])
        self.q0_mvar = float(net.load.q_mvar.at[keep])
        self._p_base = net.load.p_mw.to_numpy(dtype=float).copy()
        self._q_base = net.load.q_mvar.to_numpy(dtype=float).copy()
        self._pos = net.load.index.get_indexer(self.factor_loads)
        self._warm = False
        self._last_zip: tuple[float, ...] | None = None

        base = np.ones(N_FACTORS)
        if engine == "newton":
            self._setup_newton()
            check = self._solve_runpp(base, self.zip_p, self.zip_q) if self._runpp_ok() else None
            got = self._solve_newton(base, self.zip_p, self.zip_q)
            if check is not None and not np.allclose(got, check, rtol=0, atol=1e-8):
                raise RuntimeError(
                    "the 'newton' engine disagrees with runpp on the base case; pandapower's "
                    f"internals may have changed, use engine='runpp' ({got} vs {check})"
                )
        self._solve = {
            "newton": self._solve_newton,
            "recycle": self._solve_recycle,
            "runpp": self._solve_runpp,
        }[engine]

    def _config(self) -> dict[str, Any]:
        return {
            "zip_p": self.zip_p,
            "zip_q": self.zip_q,
            "engine": self.engine,
            "tolerance_mva": self.tolerance_mva,
            "max_iteration": self.max_iteration,
            "numba": self.numba,
        }

    def __repr__(self) -> str:
        return (
            f"Feeder33(zip_p={self.zip_p.tolist()}, zip_q={self.zip_q.tolist()}, "
            f"engine={self.engine!r})"
        )

    def _runpp_ok(self) -> bool:
        return bool(self.zip_p[2] >= 0 and self.zip_q[2] >= 0)

    # -- engines: each maps (factors, zip_p, zip_q) to (vm_pu, p_mw, q_mvar, converged) --

    def _set_loads(self, factors: np.ndarray, zp: np.ndarray, zq: np.ndarray) -> None:
        if zp[2] < 0 or zq[2] < 0:
            raise ValueError(
                f"engine {self.engine!r}: pandapower refuses a negative constant-power share "
                "(a1 + a2 > 1); use engine='newton'"
            )
        p, q = self._p_base.copy(), self._q_base.copy()
        p[self._pos] *= factors
        q[self._pos] *= factors
        load = self.net.load
        load["p_mw"] = p
        load["q_mvar"] = q
        load.loc[self.zip_load, ["const_z_p_percent", "const_i_p_percent"]] = zp[:2] * 100.0
        load.loc[self.zip_load, ["const_z_q_percent", "const_i_q_percent"]] = zq[:2] * 100.0

    def _read_result(self) -> _Raw:
        net = self.net
        return (
            float(net.res_bus.vm_pu.at[ZIP_BUS]),
            float(net.res_load.p_mw.at[self.zip_load]),
            float(net.res_load.q_mvar.at[self.zip_load]),
            True,
        )

    def _runpp(self, **kwargs: Any) -> bool:
        try:
            self._pp.runpp(
                self.net,
                tolerance_mva=self.tolerance_mva,
                max_iteration=self.max_iteration,
                numba=self.numba,
                **kwargs,
            )
        except self._pp.LoadflowNotConverged:
            return False
        return True

    def _solve_runpp(self, factors: np.ndarray, zp: np.ndarray, zq: np.ndarray) -> _Raw:
        self._set_loads(factors, zp, zq)
        return self._read_result() if self._runpp() else (np.nan, np.nan, np.nan, False)

    def _solve_recycle(self, factors: np.ndarray, zp: np.ndarray, zq: np.ndarray) -> _Raw:
        self._set_loads(factors, zp, zq)
        zip_key = (*zp, *zq)
        if self._warm and zip_key == self._last_zip:
            ok = self._runpp(recycle={"bus_pq": True, "trafo": False, "gen": False})
        else:
            ok = self._runpp()
        # A failed run leaves diverged voltages behind as the next warm start.
        self._warm, self._last_zip = ok, zip_key
        return self._read_result() if ok else (np.nan, np.nan, np.nan, False)

    def _setup_newton(self) -> None:
        from scipy.sparse.linalg import MatrixRankWarning

        self._rank_warning = MatrixRankWarning
        try:
            from pandapower.pypower.idx_bus import CID_P, CID_Q, CZD_P, CZD_Q, PD, QD, VA
            from pandapower.pypower.idx_gen import GEN_BUS, GEN_STATUS, VG
            from pandapower.pypower.makeSbus import makeSbus
            from pandapower.pypower.newtonpf import newtonpf
        except ImportError as err:  # pragma: no cover - depends on the pandapower release
            raise ImportError(
                "pandapower's Newton solver moved; use Feeder33(engine='runpp')"
            ) from err
        self._newtonpf, self._makeSbus = newtonpf, makeSbus
        self._cols = {
            "PD": PD,
            "QD": QD,
            "CZD_P": CZD_P,
            "CID_P": CID_P,
            "CZD_Q": CZD_Q,
            "CID_Q": CID_Q,
        }
        # One full runpp with constant-power loads builds the solver's arrays; the ZIP
        # shares are then written into the bus matrix for every run.
        self._set_loads(np.ones(N_FACTORS), np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0]))
        if not self._runpp(init="flat"):
            raise RuntimeError("the base case of case33bw did not converge")
        ppc = self.net._ppc
        internal = ppc["internal"]
        lookup = self.net._pd2ppc_lookups["bus"]
        bus0 = internal["bus"].copy()
        self._nb = bus0.shape[0]
        self._row = int(lookup[ZIP_BUS])
        self._rows = lookup[self.net.load.bus.to_numpy()][self._pos]
        load = self.net.load
        scaling = load.scaling.to_numpy(dtype=float)[self._pos]
        self._p_other = self._p_base[self._pos] * scaling
        self._q_other = self._q_base[self._pos] * scaling
        if not np.all(load.in_service.to_numpy()[self._pos]):  # pragma: no cover
            raise RuntimeError("a scaled load is out of service")
        for name in ("CZD_P", "CID_P", "CZD_Q", "CID_Q"):
            if np.any(bus0[:, self._cols[name]] != 0):  # pragma: no cover
                raise RuntimeError("unexpected voltage-dependent load outside the ZIP bus")
        bus0[:, self._cols["PD"]] = 0.0
        bus0[:, self._cols["QD"]] = 0.0
        self._bus0 = bus0
        gen = internal["gen"].copy()
        self._gen = gen
        self._base_mva = internal["baseMVA"]
        self._ybus = internal["Ybus"].copy()
        self._ref, self._pv, self._pq = internal["ref"], internal["pv"], internal["pq"]
        # Flat start, as runpp(init="flat"): 1 p.u. and 0 deg except at the slack, which
        # keeps its set point and angle.
        v0 = np.ones(self._nb, dtype=complex)
        on = gen[:, GEN_STATUS] > 0
        gbus = gen[on, GEN_BUS].real.astype(np.int64)
        v0[gbus] = gen[on, VG].real * np.exp(1j * np.deg2rad(bus0[gbus, VA].real))
        self._v0 = v0
        self._ppci = {k: v for k, v in ppc.items() if k != "internal"}
        self._ppci.update(bus=bus0, gen=gen, branch=internal["branch"], baseMVA=self._base_mva)
        self._internal = dict(internal)
        opts = dict(self.net._options)
        # Always on: with all shares zero the ZIP factor is exactly 1 (constant power).
        opts.update(
            voltage_depend_loads=True,
            max_iteration=self.max_iteration,
            tolerance_mva=self.tolerance_mva,
            numba=self.numba,
        )
        self._opts = opts

    def _solve_newton(self, factors: np.ndarray, zp: np.ndarray, zq: np.ndarray) -> _Raw:
        c = self._cols
        bus = self._bus0.copy()
        bus[:, c["PD"]] = np.bincount(self._rows, self._p_other * factors, minlength=self._nb)
        bus[:, c["QD"]] = np.bincount(self._rows, self._q_other * factors, minlength=self._nb)
        r = self._row
        bus[r, c["PD"]] += self.p0_mw
        bus[r, c["QD"]] += self.q0_mvar
        bus[r, [c["CZD_P"], c["CID_P"], c["CZD_Q"], c["CID_Q"]]] = (zp[0], zp[1], zq[0], zq[1])
        ppci = dict(self._ppci, bus=bus, internal=dict(self._internal))  # solver writes here
        sbus = self._makeSbus(self._base_mva, bus, self._gen)
        # A diverging Newton run may overflow or hit a singular Jacobian; that run is
        # reported as not converged, so these warnings carry no extra information.
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", self._rank_warning)
            v, ok, *_ = self._newtonpf(
                self._ybus, sbus, self._v0.copy(), self._ref, self._pv, self._pq, ppci, self._opts
            )
            vm = float(np.abs(v[r]))
        if not (ok and np.isfinite(vm)):
            return np.nan, np.nan, np.nan, False
        p = float(_zip_power(self.p0_mw, zp, np.float64(vm)))
        q = float(_zip_power(self.q0_mvar, zq, np.float64(vm)))
        return vm, p, q, True

    # -- public API --

    def reset(self) -> None:
        """Forget the warm start of the ``"recycle"`` engine (no-op for the others)."""
        self._warm = False

    def run(
        self,
        factors: ArrayLike,
        *,
        zip_p: ArrayLike | None = None,
        zip_q: ArrayLike | None = None,
    ) -> BusSolution:
        """Run one experiment.

        Parameters
        ----------
        factors : array_like
            Shape ``(N_FACTORS,)``: multipliers of ``p_mw`` and ``q_mvar`` of the non-ZIP
            loads, in the order of ``factor_loads``.
        zip_p, zip_q : array_like, optional
            ZIP shares for this run; default the feeder's.

        Returns
        -------
        BusSolution
            ``(v_pu, p_pu, q_pu, converged)`` at bus 17; P and Q in per unit of
            ``p0_mw`` and ``q0_mvar`` (multiply by them for MW and Mvar). NaN when the
            power flow did not converge.
        """
        f = self._check_factors(factors, ndim=1)
        zp = self.zip_p if zip_p is None else _as_zip(zip_p, "zip_p")
        zq = self.zip_q if zip_q is None else _as_zip(zip_q, "zip_q")
        if zp.ndim != 1 or zq.ndim != 1:
            raise ValueError("run takes one set of ZIP shares; use run_many for many")
        v, p, q, ok = self._solve(f, zp, zq)
        return BusSolution(v, p / self.p0_mw, q / self.q0_mvar, ok)

    def run_many(
        self,
        factors: ArrayLike,
        *,
        zip_p: ArrayLike | None = None,
        zip_q: ArrayLike | None = None,
        workers: int = 1,
        progress: bool = False,
    ) -> dict[str, np.ndarray]:
        """Run many experiments, optionally in worker processes.

        Parameters
        ----------
        factors : array_like
            Shape ``(n, N_FACTORS)``, one row per experiment.
        zip_p, zip_q : array_like, optional
            ZIP shares: one set, shape ``(2,)`` or ``(3,)``, or one per experiment,
            ``(n, 2)`` or ``(n, 3)``. Default the feeder's.
        workers : int
            Processes; 1 runs here. Results do not depend on it.
        progress : bool
            Show a progress bar on stderr if ``tqdm`` is installed.

        Returns
        -------
        dict of numpy.ndarray
            ``v_pu``, ``p_pu``, ``q_pu``, ``p_mw``, ``q_mvar`` (NaN where not converged)
            and ``converged`` (bool), each of shape ``(n,)``.

        Notes
        -----
        Work is cut into chunks of a fixed size, so the numbers are identical for any
        ``workers``. Worker processes are forked where the platform allows it, which
        lets them reuse the pandapower case and the numba code compiled here (a fresh
        process needs about 8 s for both); elsewhere they are spawned. Python >= 3.12
        warns when it forks a process that runs threads (e.g. a Dask client).
        """
        f = self._check_factors(factors, ndim=2)
        n = f.shape[0]
        zp = _per_row(self.zip_p if zip_p is None else _as_zip(zip_p, "zip_p"), n, "zip_p")
        zq = _per_row(self.zip_q if zip_q is None else _as_zip(zip_q, "zip_q"), n, "zip_q")
        out = np.full((n, 3), np.nan)
        ok = np.zeros(n, dtype=bool)
        chunks = [slice(i, min(i + _CHUNK, n)) for i in range(0, n, _CHUNK)]
        workers = int(workers)
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        if workers == 1 or len(chunks) == 1:
            with _progress(n, progress) as bar:
                for s in chunks:
                    out[s], ok[s] = self._solve_chunk(f[s], zp[s], zq[s])
                    bar(s.stop - s.start)
        else:
            with ProcessPoolExecutor(
                max_workers=min(workers, len(chunks)),
                mp_context=_mp_context(),
                initializer=_worker_init,
                initargs=(self._config(),),
            ) as pool:
                futures = {pool.submit(_worker_solve, f[s], zp[s], zq[s]): s for s in chunks}
                # The bar (a thread) starts after the workers are forked.
                with _progress(n, progress) as bar:
                    for fut in as_completed(futures):
                        s = futures[fut]
                        out[s], ok[s] = fut.result()
                        bar(s.stop - s.start)
        return {
            "v_pu": out[:, 0],
            "p_pu": out[:, 1] / self.p0_mw,
            "q_pu": out[:, 2] / self.q0_mvar,
            "p_mw": out[:, 1],
            "q_mvar": out[:, 2],
            "converged": ok,
        }

    def run_draws(
        self,
        factors: ArrayLike,
        zip_p: ArrayLike,
        *,
        zip_q: ArrayLike | None = None,
        workers: int = 1,
        progress: bool = False,
    ) -> dict[str, np.ndarray]:
        """Posterior-predictive power flow: every coefficient draw on every experiment.

        Parameters
        ----------
        factors : array_like
            Shape ``(n, N_FACTORS)``.
        zip_p : array_like
            Draws of the P shares, shape ``(m, 2)`` or ``(m, 3)``.
        zip_q : array_like, optional
            Q shares: one set ``(3,)``, or draws ``(m, 2 | 3)`` paired with ``zip_p``.
            Default the feeder's (true) Q shares.
        workers : int
            Processes, as in :meth:`run_many`.
        progress : bool
            Progress bar, as in :meth:`run_many`.

        Returns
        -------
        dict of numpy.ndarray
            As :meth:`run_many`, each of shape ``(m, n)``: row ``i`` is draw ``i``.
        """
        f = self._check_factors(factors, ndim=2)
        zp = _as_zip(zip_p, "zip_p")
        if zp.ndim != 2:
            raise ValueError(f"zip_p: expected draws of shape (m, 2 | 3), got {zp.shape}")
        m, n = zp.shape[0], f.shape[0]
        zq = self.zip_q if zip_q is None else _as_zip(zip_q, "zip_q")
        if zq.ndim == 2 and zq.shape[0] != m:
            raise ValueError(f"zip_q has {zq.shape[0]} draws, zip_p has {m}")
        zq = np.broadcast_to(zq, (m, 3))
        res = self.run_many(
            np.tile(f, (m, 1)),
            zip_p=np.repeat(zp, n, axis=0),
            zip_q=np.repeat(zq, n, axis=0),
            workers=workers,
            progress=progress,
        )
        return {k: v.reshape(m, n) for k, v in res.items()}

    def _check_factors(self, factors: ArrayLike, *, ndim: int) -> np.ndarray:
        f = np.asarray(factors, dtype=float)
        if f.ndim != ndim or f.shape[-1] != N_FACTORS:
            want = "(N_FACTORS,)" if ndim == 1 else "(n, N_FACTORS)"
            raise ValueError(f"factors: expected shape {want} = {N_FACTORS} loads, got {f.shape}")
        if not np.all(np.isfinite(f)):
            raise ValueError("factors must be finite")
        return f

    def _solve_chunk(
        self, factors: np.ndarray, zp: np.ndarray, zq: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        self.reset()
        out = np.full((factors.shape[0], 3), np.nan)
        ok = np.zeros(factors.shape[0], dtype=bool)
        for i in range(factors.shape[0]):
            *out[i], ok[i] = self._solve(factors[i], zp[i], zq[i])
        return out, ok


# -- worker processes --

_WORKER: Feeder33 | None = None


def _worker_init(config: dict[str, Any]) -> None:
    global _WORKER
    _WORKER = Feeder33(**config)


def _worker_solve(
    factors: np.ndarray, zp: np.ndarray, zq: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    assert _WORKER is not None
    return _WORKER._solve_chunk(factors, zp, zq)


def _mp_context() -> multiprocessing.context.BaseContext:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("fork" if "fork" in methods else "spawn")


class _progress:
    """Context manager giving an ``update(k)`` callable; a tqdm bar if asked and installed."""

    def __init__(self, total: int, enabled: bool) -> None:
        self._bar = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                return
            self._bar = tqdm(total=total, unit="pf", file=sys.stderr)

    def __enter__(self):
        return self._bar.update if self._bar is not None else (lambda k: None)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()


# -- the paper's experiments --


def generate_experiments(
    n: int,
    *,
    zip_p: ArrayLike = DEFAULT_ZIP,
    zip_q: ArrayLike = DEFAULT_ZIP,
    factor_range: tuple[float, float] = FACTOR_RANGE,
    noise_sd: float = 0.1,
    noise_on_v: float = 0.0,
    seed: Seed = 0,
    rng: np.random.Generator | None = None,
    progress: bool = False,
    workers: int = 1,
    engine: Engine = "newton",
) -> pd.DataFrame:
    """Simulate the paper's ZIP experiments at bus 18.

    Parameters
    ----------
    n : int
        Number of experiments (power flows).
    zip_p, zip_q : array_like
        True ZIP shares of P (a1, a2, a3) and Q (a4, a5, a6).
    factor_range : (float, float)
        Each non-ZIP load is scaled by its own factor from U[low, high].
    noise_sd : float
        Standard deviation of the Gaussian noise on P and Q, as a fraction of the
        nominal P0 and Q0 (i.e. in per unit).
    noise_on_v : float
        Standard deviation of the noise on V, in p.u. (of V0 = 1).
    seed : int or numpy.random.SeedSequence, optional
        Seed of the load factors and the noise; ignored when ``rng`` is given.
    rng : numpy.random.Generator, optional
        Generator to spawn the factor and noise streams from.
    progress : bool
        Progress bar on stderr (needs ``tqdm``).
    workers : int
        Processes; the output is identical for any value.
    engine : {"newton", "recycle", "runpp"}
        Power-flow engine (:class:`Feeder33`).

    Returns
    -------
    pandas.DataFrame
        Columns ``experiment, v_pu, p_true_pu, q_true_pu, p_meas_pu, q_meas_pu,
        v_meas_pu, converged``. Experiments whose power flow did not converge keep their
        row with ``converged=False`` and NaN values. ``attrs`` holds ``n_failed``, the
        settings, ``p0_mw``, ``q0_mvar`` and ``bus`` (paper numbering). The load factors
        are ``draw_factors(n, seed=seed, factor_range=factor_range)``.

    Notes
    -----
    The paper writes the noise as N(0, 0.1) and calls it a 10% error; it is read here as
    a standard deviation of 0.1 p.u. (``noise_sd``), the project's reading of the paper.
    The paper does not say whether V is noisy; ``noise_on_v`` defaults to 0.
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if noise_sd < 0 or noise_on_v < 0:
        raise ValueError("noise_sd and noise_on_v must be >= 0")
    factor_rng, noise_rng = _streams(seed, rng)
    factors = _draw(factor_rng, n, factor_range)
    # Noise for every row, converged or not, so it does not depend on failures.
    z = noise_rng.standard_normal((n, 3))
    feeder = Feeder33(zip_p=zip_p, zip_q=zip_q, engine=engine)
    res = feeder.run_many(factors, workers=workers, progress=progress)
    df = pd.DataFrame(
        {
            "experiment": np.arange(n, dtype=np.int64),
            "v_pu": res["v_pu"],
            "p_true_pu": res["p_pu"],
            "q_true_pu": res["q_pu"],
            # Departure from the paper's "N(0, 0.1)": 0.1 is a standard deviation here.
            "p_meas_pu": res["p_pu"] + noise_sd * z[:, 0],
            "q_meas_pu": res["q_pu"] + noise_sd * z[:, 1],
            "v_meas_pu": res["v_pu"] + noise_on_v * 1.0 * z[:, 2],  # 1.0 = V0
            "converged": res["converged"],
        }
    )
    df.attrs.update(
        n_failed=int(n - res["converged"].sum()),
        zip_p=feeder.zip_p.tolist(),
        zip_q=feeder.zip_q.tolist(),
        factor_range=list(_check_range(factor_range)),
        noise_sd=float(noise_sd),
        noise_on_v=float(noise_on_v),
        seed=seed if isinstance(seed, int) and rng is None else None,
        p0_mw=feeder.p0_mw,
        q0_mvar=feeder.q0_mvar,
        bus=ZIP_BUS + 1,
        engine=engine,
    )
    return df


def validate(
    zip_true: ArrayLike,
    zip_est: ArrayLike,
    *,
    seed: Seed,
    rng: np.random.Generator | None = None,
    n: int = 100,
    factor_range: tuple[float, float] = FACTOR_RANGE,
    zip_q_true: ArrayLike = DEFAULT_ZIP,
    zip_q_est: ArrayLike | None = None,
    quantiles: Sequence[float] = (0.025, 0.5, 0.975),
    engine: Engine = "newton",
    workers: int = 1,
    progress: bool = False,
) -> pd.DataFrame:
    """Compare power flows with the true and the estimated ZIP load on fresh experiments.

    Parameters
    ----------
    zip_true : array_like
        True P shares, ``(a1, a2)`` or ``(a1, a2, a3)``.
    zip_est : array_like
        Estimated P shares: one point estimate, shape ``(2,)`` or ``(3,)``, or posterior
        draws, shape ``(m, 2)`` or ``(m, 3)``.
    seed : int, numpy.random.SeedSequence or None
        Seed of the load factors (``draw_factors(n, seed=seed)``); use another seed than
        the one that generated the fitted data, so the experiments are fresh. None takes
        fresh entropy (not reproducible).
    rng : numpy.random.Generator, optional
        Generator to draw the factors from instead (then pass ``seed=None``).
    n : int
        Number of experiments.
    factor_range : (float, float)
        Range of the load factors.
    zip_q_true : array_like
        True Q shares.
    zip_q_est : array_like, optional
        Estimated Q shares, ``(3,)`` or draws ``(m, 2 | 3)`` paired with ``zip_est``;
        default ``zip_q_true`` (only P is estimated).
    quantiles : sequence of float
        Quantiles of the predictive band, used with draws.
    engine : {"newton", "recycle", "runpp"}
        Power-flow engine.
    workers : int
        Processes; results do not depend on it.
    progress : bool
        Progress bar (needs ``tqdm``).

    Returns
    -------
    pandas.DataFrame
        One row per experiment. Point estimate: ``experiment, v_true_pu, v_est_pu,
        p_true_pu, p_est_pu, q_true_pu, q_est_pu, dv_pu, dp_pu, dq_pu, converged`` with
        ``dX = X_est - X_true``. Draws: ``experiment, v_true_pu, p_true_pu, q_true_pu``,
        then for X in v, p, q: ``X_est_mean_pu`` and ``X_est_q{100 q}_pu`` (e.g.
        ``v_est_q2.5_pu``) over the draws, ``dv_pu, dp_pu, dq_pu`` (mean over draws of
        ``X_est - X_true``), ``n_draws_ok`` and ``converged`` (of the true run). Failed
        runs are NaN and left out of the band; ``attrs`` counts them.

    Notes
    -----
    The paper's validation (100 experiments, true vs estimated ZIP at bus 18) reports
    ``|dV|`` about 1e-4 and ``|dP|`` about 1e-3. With draws this is a posterior-
    predictive check: ``m * n`` power flows, spread over ``workers``.
    """
    factors = _draw(_streams(seed, rng)[0], n, factor_range)
    feeder = Feeder33(zip_p=zip_true, zip_q=zip_q_true, engine=engine)
    true = feeder.run_many(factors, workers=workers, progress=progress)
    est_p = _as_zip(zip_est, "zip_est")
    est_q = feeder.zip_q if zip_q_est is None else _as_zip(zip_q_est, "zip_q_est")
    attrs: dict[str, Any] = {
        "zip_true": feeder.zip_p.tolist(),
        "zip_q_true": feeder.zip_q.tolist(),
        "factor_range": list(_check_range(factor_range)),
        "seed": seed if isinstance(seed, int) and rng is None else None,
        "n_failed": int(n - true["converged"].sum()),
        "bus": ZIP_BUS + 1,
    }
    cols: dict[str, Any] = {"experiment": np.arange(n, dtype=np.int64)}
    if est_p.ndim == 1:
        if est_q.ndim != 1:
            raise ValueError("zip_q_est has draws but zip_est is a point estimate")
        est = feeder.run_many(factors, zip_p=est_p, zip_q=est_q, workers=workers)
        for x in ("v", "p", "q"):
            cols[f"{x}_true_pu"] = true[f"{x}_pu"]
            cols[f"{x}_est_pu"] = est[f"{x}_pu"]
        for x in ("v", "p", "q"):
            cols[f"d{x}_pu"] = est[f"{x}_pu"] - true[f"{x}_pu"]
        cols["converged"] = true["converged"] & est["converged"]
        attrs.update(
            zip_est=est_p.tolist(), n_draws=None, n_failed_est=int(n - est["converged"].sum())
        )
        df = pd.DataFrame(cols)
        df.attrs.update(attrs)
        return df

    q = np.asarray(quantiles, dtype=float)
    if q.ndim != 1 or np.any((q < 0) | (q > 1)):
        raise ValueError(f"quantiles must be a 1-D sequence in [0, 1], got {quantiles}")
    draws = feeder.run_draws(factors, est_p, zip_q=est_q, workers=workers, progress=progress)
    for x in ("v", "p", "q"):
        cols[f"{x}_true_pu"] = true[f"{x}_pu"]
    # An experiment whose every draw failed has an all-NaN column: its band is NaN.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "All-NaN slice", RuntimeWarning)
        warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
        for x in ("v", "p", "q"):
            d = draws[f"{x}_pu"]
            cols[f"{x}_est_mean_pu"] = np.nanmean(d, axis=0)
            for qi, band in zip(q, np.nanquantile(d, q, axis=0), strict=True):
                cols[f"{x}_est_q{100 * qi:g}_pu"] = band
        for x in ("v", "p", "q"):
            cols[f"d{x}_pu"] = np.nanmean(draws[f"{x}_pu"] - true[f"{x}_pu"], axis=0)
    cols["n_draws_ok"] = draws["converged"].sum(axis=0).astype(np.int64)
    cols["converged"] = true["converged"]
    attrs.update(
        n_draws=int(est_p.shape[0]),
        quantiles=q.tolist(),
        n_failed_est=int(draws["converged"].size - draws["converged"].sum()),
    )
    df = pd.DataFrame(cols)
    df.attrs.update(attrs)
    return df
