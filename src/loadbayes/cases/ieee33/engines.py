"""The power-flow engines of :class:`~loadbayes.cases.ieee33.feeder.Feeder33`.

Each engine maps (load factors, P shares, Q shares) to (V p.u., P MW, Q Mvar, converged)
at the ZIP bus. :class:`PandapowerEngines` holds ``"runpp"`` and ``"recycle"``, which
use pandapower's public ``runpp``; :class:`NewtonEngine` holds ``"newton"``, the one
path that depends on pandapower *internals* (``net._ppc``, ``net._pd2ppc_lookups``,
``pandapower.pypower.newtonpf``), so that a pandapower release that moves them breaks
this module only. Both are mixins of ``Feeder33``, which sets the attributes they read
(see the notes of :mod:`loadbayes.cases.ieee33` for the engines).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from loadbayes.cases.ieee33.network import N_FACTORS, ZIP_BUS

# What an engine returns for one run: V (p.u.), P (MW), Q (Mvar), converged.
_Raw = tuple[float, float, float, bool]


def _zip_power(nominal: float, shares: np.ndarray, vm: np.ndarray) -> np.ndarray:
    # Same grouping as pandapower's res_load: constant part plus voltage-dependent part.
    return nominal * shares[..., 2] + nominal * (shares[..., 1] * vm + shares[..., 0] * vm**2)


class PandapowerEngines:
    """The ``"runpp"`` and ``"recycle"`` engines: pandapower's ``runpp`` on ``net``."""

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

    def _runpp(self, numba: bool | None = None, **kwargs: Any) -> bool:
        try:
            self._pp.runpp(
                self.net,
                tolerance_mva=self.tolerance_mva,
                max_iteration=self.max_iteration,
                numba=self._numba_now if numba is None else numba,
                **kwargs,
            )
        except self._pp.LoadflowNotConverged:
            return False
        return True

    def _solve_runpp(
        self, factors: np.ndarray, zp: np.ndarray, zq: np.ndarray, numba: bool | None = None
    ) -> _Raw:
        self._set_loads(factors, zp, zq)
        ok = self._runpp(numba=numba)
        return self._read_result() if ok else (np.nan, np.nan, np.nan, False)

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


class NewtonEngine:
    """The ``"newton"`` engine: pandapower's ``newtonpf`` on the arrays a ``runpp`` built."""

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
        # SciPy's runpp even once numba solves the flows: compiling pandapower's runpp
        # kernels (makeYbus and others, not the Newton ones) took 3 CPU s for the one or
        # two runpp of a feeder; the arrays are the same (the slack's P and Q aside, which
        # the Newton step does not read), the flows bit for bit.
        self._set_loads(np.ones(N_FACTORS), np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0]))
        if not self._runpp(numba=False, init="flat"):
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
            numba=self._numba_now,
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
