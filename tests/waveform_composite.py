"""A recorder's COMTRADE file of an independent composite-load event: waveforms, not phasors.

The second yardstick of issue 21 ("including recordings that went through a recorder's
phasor estimation"). :mod:`independent_composite` (SciPy only) gives the continuous bus
trajectory ``V(t), delta(t), P(t), Q(t)`` of motor + ZIP; this module turns it into what
a disturbance recorder stores, with its own code (NumPy only; no loadbayes import, not
its simulators, its COMTRADE writer or ``recordings/synth.py``):

- balanced three-phase instantaneous waveforms sampled at ``rate_hz``::

      v_k(t) = sqrt(2) V_ph(t) cos(w t + delta(t) - 2 pi k / 3),   k = 0, 1, 2 (a, b, c)
      i_k(t) = sqrt(2) |I(t)|  cos(w t + angle I(t) - 2 pi k / 3),
      I(t)   = conj(S(t) / (3 V_ph(t) e^{j delta(t)})),   S = (P + jQ) S_base

  ``w = 2 pi f_hz`` (the system at its nominal frequency), ``V_ph = v V_base / sqrt 3``:
  the quasi-static (phasor-dynamics) waveform of the trajectory; no network transient,
  so no decaying DC offset in the currents;
- in volts and amperes (a 110 kV bus, a load of some tens of MVA), normal noise on every
  sample (a share of the nominal peak), quantised by the channel's multiplier;
- written as an IEEE C37.111-1999 ASCII ``.cfg`` + ``.dat`` pair, analog channels
  ``Va Vb Vc`` (V) and ``Ia Ib Ic`` (A) with phases ``A B C``, values on the primary side.

The truth (:func:`independent_composite.truth`) is returned with the file's bases, so a
fit's per-unit answers compare directly when the reader is given the same bases.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from independent_composite import Sag, simulate, truth

__all__ = [
    "DAT_MAX",
    "trajectory_samples",
    "waveforms",
    "window_means",
    "write_comtrade_1999",
    "write_event",
]

#: Largest magnitude of an ASCII sample value in C37.111-1999 (five digits).
DAT_MAX = 99999


def trajectory_samples(traj, t: np.ndarray) -> np.ndarray:
    """``V, delta, P, Q`` (per unit) of the noise-free trajectory at times ``t``, shape (4, n)."""
    out = np.empty((4, t.size))
    for k, tk in enumerate(t):
        out[:, k] = traj.point(float(tk))
    return out


def window_means(traj, centres: np.ndarray, window_s: float) -> np.ndarray:
    """Exact means of ``V, P, Q`` over ``[c - W/2, c + W/2]`` for each centre, shape (3, m).

    From the trajectory's quadrature states (``int V``, ``int P``, ``int Q``): the window
    model the composite fit reads a phasor sample as (docs/composite.md, "Phasor samples").
    """
    out = np.empty((3, len(centres)))
    for k, c in enumerate(centres):
        hi, lo = traj.state(c + 0.5 * window_s), traj.state(c - 0.5 * window_s)
        out[:, k] = (hi[3:6] - lo[3:6]) / window_s
    return out


def waveforms(
    vdpq: np.ndarray,
    t: np.ndarray,
    *,
    f_hz: float,
    v_base_kv: float,
    s_base_mva: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Phase voltages (V) and line currents (A), shape (3, n), from per-unit ``V, delta, P, Q``."""
    v, delta, p, q = vdpq
    vph = v * v_base_kv * 1e3 / math.sqrt(3.0) * np.exp(1j * delta)  # RMS phasor, V
    s = (p + 1j * q) * s_base_mva * 1e6  # three-phase VA
    iph = np.conj(s / (3.0 * vph))  # RMS phasor, A
    theta = 2.0 * math.pi * f_hz * t
    shifts = np.array([0.0, -2.0 * math.pi / 3.0, 2.0 * math.pi / 3.0])[:, None]
    va = math.sqrt(2.0) * np.abs(vph) * np.cos(theta + np.angle(vph) + shifts)
    ia = math.sqrt(2.0) * np.abs(iph) * np.cos(theta + np.angle(iph) + shifts)
    return va, ia


def write_comtrade_1999(
    stem: str | Path,
    t: np.ndarray,
    v: np.ndarray,
    i: np.ndarray,
    *,
    rate_hz: float,
    f_hz: float,
    v_full_scale: float,
    i_full_scale: float,
    v_ratio: tuple[float, float] = (110_000.0, 100.0),
    i_ratio: tuple[float, float] = (600.0, 1.0),
) -> Path:
    """Write ``stem.cfg`` and ``stem.dat`` (C37.111-1999, ASCII); return the ``.cfg``.

    Values are stored as integers ``raw`` with ``value = a raw + b`` (``b = 0``), ``a`` the
    full scale over :data:`DAT_MAX`; the time stamps are whole microseconds
    (``timemult`` 1). Values are primary (``PS = P``): the ratio fields are informative.
    """
    stem = Path(stem)
    n = t.size
    a_v, a_i = v_full_scale / DAT_MAX, i_full_scale / DAT_MAX
    raw = np.vstack([np.rint(v / a_v), np.rint(i / a_i)])
    if np.any(np.abs(raw) > DAT_MAX):
        raise ValueError("a sample exceeds the channel's full scale")
    lines = ["WAVE_110KV,independent_recorder,1999", "6,6A,0D"]
    for k, ph in enumerate("ABC"):
        lines.append(
            f"{k + 1},V{ph.lower()},{ph},BUS110,V,{a_v:.9e},0,0,{-DAT_MAX},{DAT_MAX},"
            f"{v_ratio[0]:g},{v_ratio[1]:g},P"
        )
    for k, ph in enumerate("ABC"):
        lines.append(
            f"{k + 4},I{ph.lower()},{ph},FEEDER1,A,{a_i:.9e},0,0,{-DAT_MAX},{DAT_MAX},"
            f"{i_ratio[0]:g},{i_ratio[1]:g},P"
        )
    lines += [
        f"{f_hz:g}",
        "1",
        f"{rate_hz:g},{n}",
        "24/11/2026,00:00:00.000000",
        "24/11/2026,00:00:00.500000",
        "ASCII",
        "1",
    ]
    cfg = stem.with_suffix(".cfg")
    cfg.write_text("\r\n".join(lines) + "\r\n", encoding="ascii")
    stamps = np.rint((t - t[0]) * 1e6).astype(np.int64)
    table = np.column_stack([np.arange(1, n + 1), stamps, raw.T.astype(np.int64)])
    with open(stem.with_suffix(".dat"), "w", encoding="ascii", newline="") as fh:
        np.savetxt(fh, table, fmt="%d", delimiter=",", newline="\r\n")
    return cfg


def write_event(
    stem: str | Path,
    *,
    rate_hz: float | None = None,
    f_hz: float = 60.0,
    t_end_s: float = 2.5,
    v_base_kv: float = 110.0,
    s_base_mva: float = 40.0,
    noise_v: float = 0.002,
    noise_i: float = 0.01,
    seed: int = 0,
    motor: str = "small_fast",
    f_m: float = 0.4,
    t0: float = 0.7,
    p0: float = 0.8,
    q0: float = 0.25,
    shares: Sequence[float] = (0.3, 0.3, 0.4, 0.4, 0.3, 0.3),
    sags: Sequence[Sag] = (Sag(0.5123, 0.35, 0.15, 0.0, 0.0),),
) -> tuple[Path, dict, object]:
    """Simulate an event and write it as a recorder's COMTRADE; return ``.cfg``, truth, trajectory.

    Parameters
    ----------
    stem : str or Path
        Path of the files without suffix.
    rate_hz : float, optional
        Waveform sampling rate; default 64 samples per cycle of ``f_hz``.
    f_hz : float
        System (and motor base) frequency.
    t_end_s : float
        Length of the record; the first sample is at 0, the trajectory's time origin.
    v_base_kv, s_base_mva : float
        Line-to-line voltage and three-phase power that are 1 per unit.
    noise_v, noise_i : float
        Sd of the normal noise on each voltage and current sample, as a share of the
        nominal peak (``sqrt 2`` times the base phase voltage, the base current).
    seed : int
        Seed of the noise.
    motor, f_m, t0, p0, q0, shares, sags
        The event (:func:`independent_composite.simulate`).

    Returns
    -------
    (Path, dict, Trajectory)
        The ``.cfg``; the truth, with ``v_base_kv``, ``s_base_mva``, ``rate_hz`` added; the
        noise-free trajectory (for :func:`window_means`).
    """
    rate = 64.0 * f_hz if rate_hz is None else float(rate_hz)
    traj = simulate(
        motor=motor, t0=t0, f_m=f_m, p0=p0, q0=q0, shares=shares, sags=sags,
        t_start_s=-0.1, t_end_s=t_end_s + 0.05, f_hz=f_hz,
    )  # fmt: skip
    n = int(math.floor(t_end_s * rate + 1e-9))
    t = np.arange(n) / rate
    v, i = waveforms(
        trajectory_samples(traj, t), t, f_hz=f_hz, v_base_kv=v_base_kv, s_base_mva=s_base_mva
    )
    v_peak = math.sqrt(2.0) * v_base_kv * 1e3 / math.sqrt(3.0)
    i_peak = math.sqrt(2.0) * s_base_mva * 1e6 / (math.sqrt(3.0) * v_base_kv * 1e3)
    rng = np.random.default_rng(seed)
    v = v + noise_v * v_peak * rng.standard_normal(v.shape)
    i = i + noise_i * i_peak * rng.standard_normal(i.shape)
    cfg = write_comtrade_1999(
        stem, t, v, i, rate_hz=rate, f_hz=f_hz,
        v_full_scale=1.5 * v_peak, i_full_scale=max(4.0 * i_peak, 1.2 * np.abs(i).max()),
    )  # fmt: skip
    out = truth(traj)
    out.update(v_base_kv=v_base_kv, s_base_mva=s_base_mva, rate_hz=rate)
    return cfg, out, traj
