"""Issue 35's recorder chain as a generator: a motor + ZIP event as a real recorder stores it.

On top of :mod:`waveform_composite` (the SciPy trajectory of :mod:`independent_composite`
turned into three-phase waveforms and written as C37.111-1999), what a recorder on a
13.8 kV feeder sees and that module leaves out; each is a switch, to bisect:

- ``f_sys_hz``: the system runs off nominal (59.98 Hz) while the ``.cfg``'s line
  frequency stays at 60 Hz;
- ``angle_deg``: the bus angle jumps with the sag (``Sag.angle_rad``);
- ``dip_hz``: a frequency dip after the sag, ``df(t) = -dip (1 - e^{-u/0.1}) e^{-u/0.8}``
  scaled to reach ``-dip`` at its deepest (``u`` the time since the sag started).

  The motor sees all three, as a real one sees the system's frequency: the system's
  phase relative to the 60 Hz frame (:func:`system_phase`, in closed form) is the
  trajectory's ``angle_extra`` (:func:`independent_composite.simulate`), so it is in the
  motor's terminal voltage, in the waveforms' phase and in the currents alike, and the
  trajectory starts in its steady state at 59.98 Hz (no start-up transient: P and Q
  before the sag flat to 1e-8). Before, the phase was added to the waveforms after a
  60 Hz simulation: the reader's ``angle_rad`` carried a frequency the generator's motor
  had not seen, and ``fit composite``, whose motor is driven by that angle, missed T'
  (0.217 [0.160, 0.272] s for 0.488; 0.396 [0.258, 0.559] at 60.00 Hz without the dip);
- ``harmonics``: 3rd and 5th harmonics, a share of the fundamental's nominal peak, on
  voltages (``(0.02, 0.015)`` by default) and currents (``(0.04, 0.03)``): the 3rd in
  zero sequence, the 5th in negative sequence, as a balanced distortion is;
- ``dc_offset``: the motor's decaying DC offset. At each voltage step the motor's
  instantaneous current cannot jump, so each phase carries the step of the motor's
  quasi-static current, with its sign reversed, decaying with the stator's time constant
  ``T_a = X' / (w Rs)`` (31 ms for :data:`MOTOR`).

The motor (:data:`MOTOR`): the third-order model of :mod:`independent_composite` with
``T' = 0.488 s`` (``Rs 0.02, Xs = Xr 0.12, Xm 3.0``: ``X' 0.2354, X 3.12``; ``H 0.8 s``);
it takes ``f_m = 0.42`` of the load.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from independent_composite import Sag, _motor_for_tp, simulate, truth
from waveform_composite import trajectory_samples, waveforms, write_comtrade_1999

__all__ = ["MOTOR", "SAG", "chain_trajectory", "system_phase", "write_chain_event"]

#: The issue's motor: T' 0.488 s, in the paper's third-order model.
MOTOR = _motor_for_tp(0.488, rs=0.02, xs=0.12, xm=3.0, h_s=0.8, name="feeder 0.488 s")

#: A 33% sag of six cycles, starting inside a cycle, with a -6 degree angle jump.
SAG = Sag(1.0123, 0.33, 0.1, 0.0, 0.0, math.radians(-6.0))


#: The dip's rise and decay time constants (s).
DIP_RISE_S, DIP_DECAY_S = 0.1, 0.8


def _dip_peak() -> float:
    # The shape's largest value, at u* = ln(1 + tau_d / tau_r) / (1 / tau_r).
    a, b = 1.0 / DIP_DECAY_S, 1.0 / DIP_RISE_S + 1.0 / DIP_DECAY_S
    u = math.log(b / a) / (b - a)
    return math.exp(-a * u) - math.exp(-b * u)


def system_phase(f_sys_hz: float, t_s: float, dip_hz: float, f0: float = 60.0):
    """The system's phase relative to the ``f0`` frame (rad), as a function of t (s).

    ``2 pi`` times the integral of the frequency deviation: ``(f_sys - f0) t`` plus the
    dip's (0 before ``t_s``, deepest ``-dip_hz``), in closed form: the dip's shape is
    ``e^{-a u} - e^{-b u}``, ``a = 1 / tau_d``, ``b = 1 / tau_r + 1 / tau_d``.
    """
    a, b = 1.0 / DIP_DECAY_S, 1.0 / DIP_RISE_S + 1.0 / DIP_DECAY_S
    scale = -dip_hz / _dip_peak()

    def phase(t: float) -> float:
        u = max(t - t_s, 0.0)
        dip = (1.0 - math.exp(-a * u)) / a - (1.0 - math.exp(-b * u)) / b
        return 2.0 * math.pi * ((f_sys_hz - f0) * t + scale * dip)

    return phase


def _motor_current(traj, t: float, v_base_kv: float, s_base_mva: float) -> complex:
    """The motor's RMS current phasor (A) at ``t`` (right-continuous at a step)."""
    v, d, _, _ = traj.point(t)
    pm, qm, _, _ = traj.motor_power(t)
    vph = v * v_base_kv * 1e3 / math.sqrt(3.0) * complex(math.cos(d), math.sin(d))
    return (complex(pm, qm) * traj.s_m * s_base_mva * 1e6 / (3.0 * vph)).conjugate()


def chain_trajectory(
    *,
    f_sys_hz: float = 59.98,
    dip_hz: float = 0.06,
    f_m: float = 0.42,
    sag: Sag = SAG,
    t_end_s: float = 4.05,
    f0: float = 60.0,
):
    """The event's noise-free trajectory (from -0.1 s), and the system's phase it sees.

    The motor sees the system's frequency and the dip: the phase is the trajectory's
    angle (:func:`simulate`'s ``angle_extra``), from the off-nominal steady state at the
    start, so the record holds no start-up transient.
    """
    phase = system_phase(f_sys_hz, sag.start_s, dip_hz, f0)
    traj = simulate(
        motor=MOTOR, t0=0.7, f_m=f_m, p0=0.8, q0=0.25, sags=(sag,),
        t_start_s=-0.1, t_end_s=t_end_s, f_hz=f0, angle_extra=phase,
    )  # fmt: skip
    return traj, phase


def write_chain_event(
    stem: str | Path,
    *,
    f_sys_hz: float = 59.98,
    angle_deg: float = -6.0,
    dip_hz: float = 0.06,
    harmonics: bool = True,
    dc_offset: bool = True,
    f_m: float = 0.42,
    t_end_s: float = 4.0,
    v_base_kv: float = 13.8,
    s_base_mva: float = 10.0,
    noise_v: float = 0.002,
    noise_i: float = 0.01,
    seed: int = 0,
    sag: Sag = SAG,
    v_harm: Sequence[float] = (0.02, 0.015),
    i_harm: Sequence[float] = (0.04, 0.03),
) -> tuple[Path, dict, object]:
    """Simulate the event and write it as a recorder's COMTRADE; return ``.cfg``, truth, trajectory.

    64 samples per nominal (60 Hz) cycle. Everything not named in the module's docstring
    is :func:`waveform_composite.write_event`'s: noise shares of the nominal peak, the
    integer quantisation, the C37.111-1999 ASCII pair.
    """
    f0 = 60.0
    rate = 64.0 * f0
    s = Sag(sag.start_s, sag.depth, sag.duration_s, sag.ramp_in_s, sag.ramp_out_s,
            math.radians(angle_deg))  # fmt: skip
    traj, phase = chain_trajectory(f_sys_hz=f_sys_hz, dip_hz=dip_hz, f_m=f_m, sag=s,
                                   t_end_s=t_end_s + 0.05)  # fmt: skip
    n = int(math.floor(t_end_s * rate + 1e-9))
    t = np.arange(n) / rate
    extra = np.array([phase(float(x)) for x in t])
    vdpq = trajectory_samples(traj, t)
    v, i = waveforms(vdpq, t, f_hz=f0, v_base_kv=v_base_kv, s_base_mva=s_base_mva)
    v_peak = math.sqrt(2.0) * v_base_kv * 1e3 / math.sqrt(3.0)
    i_peak = math.sqrt(2.0) * s_base_mva * 1e6 / (math.sqrt(3.0) * v_base_kv * 1e3)
    theta = 2.0 * math.pi * f0 * t + extra
    shifts = np.array([0.0, -2.0 * math.pi / 3.0, 2.0 * math.pi / 3.0])[:, None]
    if harmonics:
        for peak, h3, h5, x in ((v_peak, *v_harm, v), (i_peak, *i_harm, i)):
            x += peak * (h3 * np.cos(3.0 * (theta + shifts) + 0.3)
                         + h5 * np.cos(5.0 * (theta - shifts) - 0.7))  # fmt: skip
    if dc_offset:
        m = MOTOR
        t_a = m.xp / (2.0 * math.pi * f0 * m.rs)
        for t_step in (s.start_s, s.start_s + s.duration_s):
            before = _motor_current(traj, t_step - 1e-9, v_base_kv, s_base_mva)
            after = _motor_current(traj, t_step, v_base_kv, s_base_mva)
            # The current phasors carry the system's phase already (the trajectory's angle).
            ph = 2.0 * math.pi * f0 * t_step + shifts[:, 0]
            jump = math.sqrt(2.0) * (np.abs(after) * np.cos(ph + np.angle(after))
                                     - np.abs(before) * np.cos(ph + np.angle(before)))  # fmt: skip
            late = t >= t_step
            i[:, late] -= jump[:, None] * np.exp(-(t[late] - t_step) / t_a)
    rng = np.random.default_rng(seed)
    v = v + noise_v * v_peak * rng.standard_normal(v.shape)
    i = i + noise_i * i_peak * rng.standard_normal(i.shape)
    cfg = write_comtrade_1999(
        stem, t, v, i, rate_hz=rate, f_hz=f0,
        v_full_scale=1.5 * v_peak, i_full_scale=max(4.0 * i_peak, 1.2 * np.abs(i).max()),
        v_ratio=(13_800.0, 120.0),
    )  # fmt: skip
    out = truth(traj)
    out.update(v_base_kv=v_base_kv, s_base_mva=s_base_mva, rate_hz=rate)
    return cfg, out, traj
