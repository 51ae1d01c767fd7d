"""Synthetic three-phase recordings with a known ZIP load behind them, and a COMTRADE writer.

Used by the tests (every revision and data format the reader supports) and handy for
checking a whole chain (read -> events -> fit) on data whose answer is known.

The load: positive-sequence voltage magnitude ``V(t)`` (p.u.), a ZIP load
``P = p0 (a1 x^2 + a2 x + a3)``, ``Q = q0 (a4 x^2 + a5 x + a6)`` with ``x = V / v0``, and
per phase ``I = conj(S / 3 / V_phase)``. Waveforms are ``sqrt(2) |X| cos(theta + angle)``
with ``theta`` the integral of ``2 pi f(t)``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from loadbayes.io.atomic import atomic_write

__all__ = ["sag_profile", "zip_waveforms", "write_comtrade"]


def sag_profile(
    t_s: np.ndarray,
    sags: Sequence[tuple[float, float, float]],
    *,
    ramp_s: float = 0.02,
    recovery_s: float | None = None,
) -> np.ndarray:
    """A voltage magnitude (p.u.) of 1 with rectangular sags with short linear ramps.

    Parameters
    ----------
    t_s : numpy.ndarray
        Times (s).
    sags : sequence of (start_s, duration_s, depth_pu)
        Each sag takes the voltage from 1 down to ``1 - depth_pu``.
    ramp_s : float, default 0.02
        Ramp time into each sag (s).
    recovery_s : float, optional
        Ramp time out of each sag (s); ``ramp_s`` by default. A slow recovery sweeps the
        voltage through every level of the sag, which is what separates the Z, I and P
        shares.

    Returns
    -------
    numpy.ndarray
        V(t), per unit.
    """
    t = np.asarray(t_s, dtype=float)
    v = np.ones_like(t)
    for start, dur, depth in sags:
        up = np.clip((t - start) / ramp_s, 0.0, 1.0)
        down = np.clip((t - start - dur) / (recovery_s or ramp_s), 0.0, 1.0)
        v -= depth * (up - down)
    return v


def zip_waveforms(
    t_s: np.ndarray,
    v_pu: np.ndarray,
    coefs: Sequence[float],
    *,
    p0: float = 1.0,
    q0: float = 0.4,
    v0: float = 1.0,
    v_base: float = 230e3 / math.sqrt(3),
    s_base: float = 100e6,
    f_hz: float | np.ndarray = 50.0,
    harmonics: Sequence[tuple[int, float]] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """Phase voltages and currents of a ZIP load fed at a given voltage magnitude.

    Parameters
    ----------
    t_s : numpy.ndarray
        Sample times (s), shape (n,).
    v_pu : numpy.ndarray
        Positive-sequence voltage magnitude (p.u. of ``v_base``), shape (n,).
    coefs : sequence of 6 floats
        ``a1..a6``.
    p0, q0 : float
        Load P, Q (p.u. of ``s_base``) at ``V = v0``.
    v0 : float
        ZIP reference voltage (p.u.).
    v_base : float
        Phase-to-neutral RMS voltage base (V); default 230 kV line to line.
    s_base : float
        Three-phase power base (VA); default 100 MVA.
    f_hz : float or numpy.ndarray
        Frequency (Hz), constant or per sample.
    harmonics : sequence of (order, fraction)
        Voltage harmonics added to every phase (relative to the fundamental); the
        current carries the same relative harmonics.

    Returns
    -------
    v, i : numpy.ndarray
        Shaped (3, n), volts and amperes.
    """
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(v_pu, dtype=float) / v0
    a1, a2, a3, a4, a5, a6 = coefs
    p = p0 * (a1 * x**2 + a2 * x + a3) * s_base
    q = q0 * (a4 * x**2 + a5 * x + a6) * s_base
    vmag = np.asarray(v_pu, dtype=float) * v_base
    imag = np.hypot(p, q) / (3 * vmag)
    phi = np.arctan2(q, p)  # current lags voltage by phi
    f = np.broadcast_to(np.asarray(f_hz, dtype=float), t.shape)
    dt = np.diff(t, prepend=t[0])
    theta = 2 * np.pi * np.cumsum(f * dt)
    v = np.empty((3, t.size))
    i = np.empty((3, t.size))
    for k in range(3):
        th = theta - 2 * np.pi * k / 3
        v[k] = np.sqrt(2) * vmag * np.cos(th)
        i[k] = np.sqrt(2) * imag * np.cos(th - phi)
        for order, frac in harmonics:
            v[k] += np.sqrt(2) * vmag * frac * np.cos(order * th)
            i[k] += np.sqrt(2) * imag * frac * np.cos(order * (th - phi))
    return v, i


def write_comtrade(
    stem: str | os.PathLike[str],
    t_s: np.ndarray,
    v: np.ndarray,
    i: np.ndarray,
    *,
    revision: str = "1999",
    fmt: str = "ASCII",
    f_nominal: float = 50.0,
    ratio: tuple[float, float] | None = None,
    names: Sequence[str] = ("VA", "VB", "VC", "IA", "IB", "IC"),
    rates: Sequence[tuple[float, int]] | None = None,
    force: bool = False,
) -> tuple[Path, Path]:
    """Write three-phase waveforms as a COMTRADE ``.cfg``/``.dat`` pair.

    Parameters
    ----------
    stem : str or os.PathLike
        Path without suffix; ``stem.cfg`` and ``stem.dat`` are written.
    t_s : numpy.ndarray
        Uniform sample times (s), shape (n,).
    v, i : numpy.ndarray
        Phase voltages (V) and currents (A), shape (3, n).
    revision : {"1991", "1999", "2013"}
        Standard revision.
    fmt : {"ASCII", "BINARY", "BINARY32", "FLOAT32"}
        Data format (BINARY32 and FLOAT32 are 2013 formats).
    f_nominal : float
        Line frequency written in the ``.cfg``.
    ratio : (float, float), optional
        (primary, secondary) of the voltage transformer: the voltages are then written as
        secondary values (``PS = S``), the currents as primary. 1999 and 2013 only.
    names : sequence of 6 str
        Channel names.
    rates : sequence of (float, int), optional
        The ``.cfg``'s sampling-rate segments (rate in Hz, last sample); ``t_s`` must
        follow them. Default: one rate, from ``t_s``.
    force : bool
        Overwrite existing files.

    Returns
    -------
    cfg, dat : pathlib.Path
        The files written.
    """
    t = np.asarray(t_s, dtype=float)
    n = t.size
    rate = 1.0 / float(np.median(np.diff(t)))
    vals = np.vstack([v, i]).astype(float)
    pors = ["P"] * 6
    prim_sec = [(1.0, 1.0)] * 6
    if ratio is not None:
        if revision == "1991":
            raise ValueError("the 1991 revision has no transformer ratio")
        vals[:3] = vals[:3] * ratio[1] / ratio[0]
        pors[:3] = ["S"] * 3
        prim_sec[:3] = [ratio] * 3
    units = ["kV"] * 3 + ["A"] * 3
    vals[:3] /= 1e3  # voltages written in kV, to exercise the unit scaling
    if fmt == "FLOAT32":
        a = np.ones(6)
        raw = vals.astype(np.float32)
    else:
        top = {"BINARY": 32000.0, "BINARY32": 2.0e9, "ASCII": 1.0e9}[fmt]
        a = np.maximum(np.abs(vals).max(axis=1), 1e-12) / top
        raw = np.round(vals / a[:, None])
    lines = []
    if revision == "1991":
        lines.append("loadbayes synthetic,recorder 1")
    else:
        lines.append(f"loadbayes synthetic,recorder 1,{revision}")
    lines.append("6,6A,0D")
    for k in range(6):
        ph = "ABC"[k % 3]
        fields = [str(k + 1), names[k], ph, "", units[k], f"{a[k]:.12g}", "0", "0",
                  "-2147483648", "2147483647"]  # fmt: skip
        if revision != "1991":
            fields += [f"{prim_sec[k][0]:g}", f"{prim_sec[k][1]:g}", pors[k]]
        lines.append(",".join(fields))
    segs = list(rates) if rates is not None else [(rate, n)]
    lines += [f"{f_nominal:g}", str(len(segs))] + [f"{r:.12g},{e}" for r, e in segs]
    stamp = "01/02/2024,10:00:00.000000"
    lines += [stamp, stamp, fmt]
    if revision != "1991":
        lines.append("1")
    if revision == "2013":
        lines += ["+0h00,+0h00", "0,0"]
    stem = Path(stem)
    cfg, dat = stem.with_suffix(".cfg"), stem.with_suffix(".dat")
    stamps = np.round(t * 1e6).astype(np.int64)
    with atomic_write(cfg, force=force, mode="w") as fh:
        fh.write("\r\n".join(lines) + "\r\n")
    if fmt == "ASCII":
        body = np.column_stack([np.arange(1, n + 1), stamps, raw.T.astype(np.int64)])
        with atomic_write(dat, force=force, mode="w") as fh:
            np.savetxt(fh, body, fmt="%d", delimiter=",", newline="\r\n")
    else:
        kind = {"BINARY": "<i2", "BINARY32": "<i4", "FLOAT32": "<f4"}[fmt]
        rec = np.dtype([("n", "<u4"), ("t", "<u4"), ("x", kind, (6,))])
        body = np.empty(n, rec)
        body["n"] = np.arange(1, n + 1)
        body["t"] = stamps
        body["x"] = raw.T
        with atomic_write(dat, force=force, mode="wb") as fh:
            fh.write(body.tobytes())
    return cfg, dat
