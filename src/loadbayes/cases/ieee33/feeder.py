"""``Feeder33``: the 33-bus feeder with one ZIP load, its API and its checks.

The engines are in :mod:`loadbayes.cases.ieee33.engines`, the process pool in
:mod:`loadbayes.cases.ieee33.parallel`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from loadbayes.cases.ieee33.engines import NewtonEngine, PandapowerEngines
from loadbayes.cases.ieee33.network import (
    _ZIP_COLUMNS,
    DEFAULT_ZIP,
    ENGINES,
    N_FACTORS,
    ZIP_BUS,
    BusSolution,
    Engine,
    _case33bw,
    _pandapower,
    _per_row,
    as_zip,
)
from loadbayes.cases.ieee33.parallel import solve_chunks

#: With ``numba=None``: the flows this process solves (all its feeders together) from which
#: it compiles pandapower's numba kernels, like renting skis until their price is spent.
#: Measured on the 33-bus case (CPU s, one process, load average 1-2): compiling costs
#: 2.9-4.5 s; a flow then takes 8.7 instead of 22 ms (``newton``), 39 instead of 54 ms
#: (``recycle``), 72 instead of 86 ms (``runpp``): even at about 200-330 flows.
NUMBA_FROM_FLOWS = 300
#: Flows solved here so far with ``numba=None``, and whether numba took over.
_PROCESS = {"flows": 0, "numba": False}

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


class Feeder33(PandapowerEngines, NewtonEngine):
    """The 33-bus feeder with one ZIP load at bus 17 (paper's bus 18).

    Parameters
    ----------
    zip_p, zip_q : sequence of float
        ZIP shares (a1, a2, a3) of P and (a4, a5, a6) of Q, Z first; two values mean
        (a1, a2) with a3 = 1 - a1 - a2.
    engine : {"newton", "recycle", "runpp"}
        Power-flow path (see the package notes); all agree to about 1e-10.
    tolerance_mva : float
        Newton mismatch tolerance, in per unit of ``net.sn_mva`` as pandapower uses it.
    max_iteration : int
        Newton iterations before a run counts as not converged.
    numba : bool or None
        Use pandapower's numba kernels. They solve a flow about twice as fast, but
        pandapower compiles them in every process (``cache=False``: about 5 CPU s on the
        first flow), which pays back only after some hundreds of flows; SciPy's path
        gives the same numbers (bit for bit, checked on 300 flows of each engine). None
        (the default) uses numba once the process has come to solve at least
        ``NUMBA_FROM_FLOWS`` flows (counted over its :meth:`run_many` calls), SciPy
        before.

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
        numba: bool | None = None,
    ) -> None:
        if engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
        self.zip_p = as_zip(zip_p, "zip_p")
        self.zip_q = as_zip(zip_q, "zip_q")
        self.engine = engine
        self.tolerance_mva = float(tolerance_mva)
        self.max_iteration = int(max_iteration)
        self.numba = None if numba is None else bool(numba)
        # What the solver uses now; automatic: numba if this process has compiled it.
        self._numba_now = _PROCESS["numba"] if numba is None else bool(numba)
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
            ok = self._runpp_ok()
            check = self._solve_runpp(base, self.zip_p, self.zip_q, numba=False) if ok else None
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
            "numba": self._numba_now,  # what the solver uses now (as given, or automatic)
        }

    def __repr__(self) -> str:
        return (
            f"Feeder33(zip_p={self.zip_p.tolist()}, zip_q={self.zip_q.tolist()}, "
            f"engine={self.engine!r})"
        )

    def _auto_numba(self, flows: float) -> None:
        # numba from the call that brings this process's flows to NUMBA_FROM_FLOWS (a
        # worker's share counts as its own process's); once compiled, for every feeder.
        if _PROCESS["numba"] or _PROCESS["flows"] + flows >= NUMBA_FROM_FLOWS:
            _PROCESS["numba"] = self._numba_now = True
            if self.engine == "newton":
                self._opts["numba"] = True
        _PROCESS["flows"] += int(flows)

    def _runpp_ok(self) -> bool:
        return bool(self.zip_p[2] >= 0 and self.zip_q[2] >= 0)

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
        zp = self.zip_p if zip_p is None else as_zip(zip_p, "zip_p")
        zq = self.zip_q if zip_q is None else as_zip(zip_q, "zip_q")
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
        lets them reuse the pandapower case and any numba code compiled here (a fresh
        process needs about 8 s for both); elsewhere they are spawned. Python >= 3.12
        warns when it forks a process that runs threads (e.g. a Dask client). With
        ``numba=None``, the call that brings this process's flows (or a worker's share)
        to ``NUMBA_FROM_FLOWS`` switches to numba, for it and every later call.
        """
        f = self._check_factors(factors, ndim=2)
        n = f.shape[0]
        if self.numba is None:
            self._auto_numba(n / max(int(workers), 1))
        zp = _per_row(self.zip_p if zip_p is None else as_zip(zip_p, "zip_p"), n, "zip_p")
        zq = _per_row(self.zip_q if zip_q is None else as_zip(zip_q, "zip_q"), n, "zip_q")
        out, ok = solve_chunks(self, f, zp, zq, workers=workers, progress=progress)
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
        zp = as_zip(zip_p, "zip_p")
        if zp.ndim != 2:
            raise ValueError(f"zip_p: expected draws of shape (m, 2 | 3), got {zp.shape}")
        m, n = zp.shape[0], f.shape[0]
        zq = self.zip_q if zip_q is None else as_zip(zip_q, "zip_q")
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
