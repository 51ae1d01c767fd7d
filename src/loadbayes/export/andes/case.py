"""The ANDES case of a composite load, shared by the simulation harness and the export.

Three buses in a row, all at ``VN_KV``, on the system base ``base_mva``
(:func:`add_composite`, the harness's case and ``export --to andes --bus N``)::

    source (Slack: infinite bus) --z_src-- network bus --Z_FEED-- load bus

or, the export's default (:func:`add_single_bus`), the load bus fed straight from the
source through ``z_src``::

    source (Slack: infinite bus, idx 2) --z_src-- load bus (idx 1)

The load bus carries a ``PQ`` replaced in the time domain by a ``ZIP`` (the static part),
a ``Motor3`` and, when ``q_c`` is not zero, a ``Shunt`` capacitor. The Slack's voltage is
set by Ohm's law so that the power flow puts the load bus at ``v0`` with angle 0: the
ZIP's reference voltage is then ``v0`` in ANDES as in loadbayes, and the motor sits at
loadbayes's steady state there. A fault or other event is added at the network bus by
the caller.

The parameter set follows the naming contract (docs/andes.md); the split of ``p0, q0``
is the one of :mod:`loadbayes.cases.composite_reference`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.export.andes.conventions import motor3_fields, zip_fields
from loadbayes.models.motor import MotorParams, steady_state

__all__ = [
    "CASE_IDS",
    "SINGLE_LOAD_BUS",
    "VN_KV",
    "Z_FEED",
    "CompositeCase",
    "add_composite",
    "add_single_bus",
    "add_to_case",
]

VN_KV = 110.0
"""Nominal voltage of every bus and device (kV); equal everywhere so ANDES rescales nothing."""
Z_FEED = complex(0.002, 0.02)
"""Feeder impedance between bus 2 and the load bus (system p.u.)."""
SINGLE_LOAD_BUS = 1
"""The load bus's idx in the single-bus case (the source bus is the next one)."""


@dataclass(frozen=True)
class CompositeCase:
    """One composite load, resolved into ANDES device parameters.

    Build it with :meth:`from_values`. ``motor`` is None for a pure ZIP load.
    """

    p0: float
    q0: float
    v0: float
    a_p: tuple[float, float, float]
    a_q: tuple[float, float, float]
    q_c: float
    motor: MotorParams | None
    t0: float
    mva_m: float
    base_mva: float
    z_src: complex
    vn_kv: float = VN_KV
    #: A second rotor cage ``(rr2, xr2)`` (motor base): the motor is then ANDES's
    #: fifth-order ``Motor5`` (its first cage the motor's ``rr, xr``), not ``Motor3``.
    cage2: tuple[float, float] | None = None

    @classmethod
    def from_values(
        cls,
        values: Mapping[str, float],
        *,
        with_motor: bool,
        base_mva: float = 100.0,
        z_src: complex = complex(0.01, 0.1),
        vn_kv: float = VN_KV,
    ) -> CompositeCase:
        """Resolve a parameter set (naming contract) into the case.

        Parameters
        ----------
        values : mapping
            ``p0, q0`` (system p.u.), ``a1..a6`` (``a3``, ``a6`` default to the rest of 1),
            optional ``v0`` (default 1), ``q_c`` (default 0); with the motor also
            ``f_m, rs, xs, xm, rr, xr, h_s, t0`` and optional ``a, b, c, f_hz``.
        with_motor : bool
            Composite (True) or ZIP only (False).
        base_mva : float
            System base (MVA).
        z_src : complex
            Source impedance from the infinite bus to bus 2 (system p.u.).
        vn_kv : float
            Nominal voltage of every bus and device (kV).

        Returns
        -------
        CompositeCase
            The case; ``mva_m = f_m p0 / P_m(v0)`` (the motor's own-base P at its steady
            state), so the motor draws exactly ``f_m p0`` at ``v0``.
        """
        a_p = _shares(values, ("a1", "a2", "a3"))
        a_q = _shares(values, ("a4", "a5", "a6"))
        p0, q0 = float(values["p0"]), float(values["q0"])
        v0, q_c = float(values.get("v0", 1.0)), float(values.get("q_c", 0.0))
        if not (np.isfinite([p0, q0, v0, q_c]).all() and v0 > 0):
            raise ValueError(f"need finite p0, q0, q_c and v0 > 0; got {p0}, {q0}, {q_c}, {v0}")
        motor, t0, mva_m = None, 0.0, 0.0
        if with_motor:
            f_m = float(values["f_m"])
            if not (0 < f_m <= 1 and p0 > 0):
                raise ValueError(f"need 0 < f_m <= 1 and p0 > 0, got f_m={f_m}, p0={p0}")
            # The one conversion every export uses (export/loadparts.py): the motor
            # draws f_m p0 at v0, its rating follows from its own-base P there.
            from loadbayes.export.loadparts import load_parts

            part = load_parts(
                {**values, "p0": p0, "q0": q0, "v0": v0},
                model="composite",
                options={"s_base_mva": base_mva, "v0": v0},
            ).motor
            motor, t0, mva_m = part.params, part.t0, part.mva / base_mva
        return cls(p0, q0, v0, a_p, a_q, q_c, motor, t0, mva_m, base_mva, z_src, float(vn_kv))

    @property
    def motor_pq(self) -> complex:
        """The motor's P + jQ at ``v0`` (system p.u.)."""
        if self.motor is None:
            return 0j
        op = steady_state(self.motor, v_pu=self.v0, t0=self.t0)
        return self.mva_m * complex(op.p, op.q)

    @property
    def static_pq(self) -> complex:
        """The ``PQ``'s (so the ZIP's) P + jQ at ``v0``: the load less motor and shunt."""
        return complex(self.p0, self.q0 + self.q_c) - self.motor_pq

    @property
    def v_src(self) -> complex:
        """Infinite-bus voltage that puts the load bus at ``v0`` (Ohm's law, no shunts)."""
        return self.source_voltage(self.z_src + Z_FEED)

    def source_voltage(self, z: complex) -> complex:
        """The voltage behind ``z`` (system p.u.) that puts the load bus at ``v0``, angle 0."""
        current = (complex(self.p0, self.q0) / self.v0).conjugate()
        return self.v0 + z * current

    def motor3(self) -> dict[str, float]:
        """``Motor3`` parameters (:func:`loadbayes.export.andes.conventions.motor3_fields`)."""
        if self.motor is None:
            raise ValueError("a ZIP-only case has no motor")
        return motor3_fields(
            self.motor, t0=self.t0, mva_m=self.mva_m, base_mva=self.base_mva, vn_kv=self.vn_kv
        )


def _shares(values: Mapping[str, float], names: tuple[str, str, str]) -> tuple:
    first, second = float(values[names[0]]), float(values[names[1]])
    third = float(values.get(names[2], 1.0 - first - second))
    shares = (first, second, third)
    if not np.isfinite(shares).all() or abs(sum(shares) - 1.0) > 1e-6:
        raise ValueError(f"{', '.join(names)} must be finite and sum to 1, got {shares}")
    return shares


def add_composite(system: Any, case: CompositeCase, *, load_bus: int = 3) -> dict[str, Any]:
    """Add the three buses, the source, the lines and the load devices to an ANDES system.

    Parameters
    ----------
    system : andes.System
        A system not yet set up (``System()`` or ``andes.load(..., setup=False)``).
    case : CompositeCase
        The load.
    load_bus : int
        The load bus's idx; the infinite bus and the network bus get the next two.

    Returns
    -------
    dict
        The idx of the load bus, network bus, ``PQ``, ``ZIP``, ``Motor3`` and ``Shunt``
        (None when absent).
    """
    base, v_src = case.base_mva, case.v_src
    system.config.mva = base
    bus_load, bus_source, bus_net = load_bus, load_bus + 1, load_bus + 2
    for idx, name in ((bus_load, "load"), (bus_source, "source"), (bus_net, "network")):
        system.add("Bus", {"idx": idx, "name": name, "Vn": case.vn_kv, "v0": case.v0})
    system.add(
        "Slack",
        {"idx": 1, "bus": bus_source, "Vn": case.vn_kv, "Sn": base, "v0": abs(v_src),
         "a0": float(np.angle(v_src))},
    )  # fmt: skip
    lines = ((bus_source, bus_net, case.z_src), (bus_net, bus_load, Z_FEED))
    for idx, (b1, b2, z) in enumerate(lines, start=1):
        system.add(
            "Line",
            {"idx": idx, "bus1": b1, "bus2": b2, "r": z.real, "x": z.imag, "b": 0.0,
             "Vn1": case.vn_kv, "Vn2": case.vn_kv, "Sn": base},
        )  # fmt: skip
    ids: dict[str, Any] = {"load_bus": bus_load, "net_bus": bus_net}
    return {**ids, **_add_load(system, case, bus_load)}


def add_single_bus(system: Any, case: CompositeCase) -> dict[str, Any]:
    """The load on bus ``SINGLE_LOAD_BUS`` fed from an infinite bus through ``case.z_src``.

    The Slack (idx 1, on the source bus ``SINGLE_LOAD_BUS + 1``) sits at the voltage that
    puts the load bus at ``v0`` with angle 0. A fault for a study goes on the load bus.

    Parameters
    ----------
    system : andes.System
        A system not yet set up.
    case : CompositeCase
        The load.

    Returns
    -------
    dict
        As :func:`add_composite`; ``net_bus`` is the source bus.
    """
    base, v_src = case.base_mva, case.source_voltage(case.z_src)
    system.config.mva = base
    bus_load, bus_source = SINGLE_LOAD_BUS, SINGLE_LOAD_BUS + 1
    for idx, name in ((bus_load, "load"), (bus_source, "source")):
        system.add("Bus", {"idx": idx, "name": name, "Vn": case.vn_kv, "v0": case.v0})
    system.add(
        "Slack",
        {"idx": 1, "bus": bus_source, "Vn": case.vn_kv, "Sn": base, "v0": abs(v_src),
         "a0": float(np.angle(v_src))},
    )  # fmt: skip
    system.add(
        "Line",
        {"idx": 1, "bus1": bus_source, "bus2": bus_load, "r": case.z_src.real,
         "x": case.z_src.imag, "b": 0.0, "Vn1": case.vn_kv, "Vn2": case.vn_kv, "Sn": base},
    )  # fmt: skip
    return {"load_bus": bus_load, "net_bus": bus_source, **_add_load(system, case, bus_load)}


#: The idx of the load's devices added to another case (``add_to_case``): named, so they
#: cannot clash with the case's own devices and playback finds them.
CASE_IDS = {"pq": "loadbayes_pq", "zip": "loadbayes_zip", "shunt": "loadbayes_shunt",
            "motor": "loadbayes_motor"}  # fmt: skip


def add_to_case(system: Any, case: CompositeCase, bus: Any) -> dict[str, Any]:
    """Add the load's devices to bus ``bus`` of a loaded ANDES case (not set up).

    The devices take the bus's ``Vn`` (``case.vn_kv`` should be it) and the idx of
    :data:`CASE_IDS`. The case's power flow sets the bus's voltage, to which the ``ZIP``
    refers its shares; the motor draws ``f_m p0`` at ``v0``.

    Returns
    -------
    dict
        As :func:`add_composite`; ``net_bus`` is None (the bus is the case's).
    """
    return {"load_bus": bus, "net_bus": None, **_add_load(system, case, bus, CASE_IDS)}


def _add_load(
    system: Any, case: CompositeCase, bus_load: Any, names: dict[str, Any] | None = None
) -> dict[str, Any]:
    idx = names or {"pq": 1, "zip": 1, "shunt": 1, "motor": 1}
    base = case.base_mva
    s_pq = case.static_pq
    pq = {"idx": idx["pq"], "bus": bus_load, "Vn": case.vn_kv, "p0": s_pq.real, "q0": s_pq.imag}
    system.add("PQ", pq)
    system.add("ZIP", {"idx": idx["zip"], "pq": idx["pq"], **zip_fields(case.a_p, case.a_q)})
    ids: dict[str, Any] = {"pq": idx["pq"], "zip": idx["zip"]}
    ids["shunt"] = ids["motor"] = None
    if case.q_c:
        b = case.q_c / case.v0**2
        shunt = {"idx": idx["shunt"], "bus": bus_load, "Vn": case.vn_kv, "Sn": base, "b": b}
        system.add("Shunt", shunt)
        ids["shunt"] = idx["shunt"]
    if case.motor is not None:
        kind, fields = "Motor3", case.motor3()
        if case.cage2 is not None:
            kind, fields = "Motor5", {**fields, "rr2": case.cage2[0], "xr2": case.cage2[1]}
        system.add(kind, {"idx": idx["motor"], "bus": bus_load, **fields})
        ids["motor"] = idx["motor"]
    return ids
