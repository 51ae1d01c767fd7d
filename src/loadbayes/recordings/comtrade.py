"""Read COMTRADE recordings (IEEE C37.111 1991, 1999, 2013): validated, then scaled.

The ``.dat`` samples are decoded by the ``comtrade`` package (PyPI, 0.2): it reads the
1991, 1999 and 2013 revisions and the four data formats (ASCII, BINARY, BINARY32,
FLOAT32), vectorised with NumPy. Checked in its source before choosing it, it does not:

- apply the primary/secondary ratio (values come out in the channel's own ``P``/``S``
  side); this module scales them (:func:`read_comtrade`, ``side=``);
- locate errors: a malformed ``.cfg`` raises a bare ``ValueError`` with no line, and an
  unknown revision is only a warning;
- notice a truncated binary ``.dat``: it reads the whole records present and leaves the
  rest of the preallocated arrays at zero, silently;
- keep times in double precision unless asked (``use_double_precision``).

So the ``.cfg`` is parsed first, line by line, with every field checked
(:mod:`~loadbayes.recordings.comtrade_cfg`), and the ``.dat`` is checked against it
(file present, record count, binary record size, ASCII field count) before the package
reads it. Any problem is a
:class:`~loadbayes.io.errors.DataError` naming the file and the line (``.cfg``), line
(ASCII ``.dat``) or record (binary ``.dat``). Units ``V``/``kV``/``A``/``kA`` (and
``mV``, ``MV``, ``mA``) are converted to volts and amperes.

What a real recorder file adds, and how it is read:

- **Text encoding**: the ``.cfg`` is decoded as given (``encoding=``) or detected
  (UTF-8, GB18030 when the text holds CJK characters, else Latin-1).
- **Channels** are chosen by name, by 1-based number, or by bay (``bay=``: the three
  phase channels whose bay field ``ccbm`` or name holds the text). A bay without voltage
  channels (a transformer's currents) takes the first three-phase voltage of the file,
  the bus's, and says so in ``Waveforms.channels``.
- **Several sample rates** (the ``.cfg``'s rate table): each run of samples is a
  :class:`Segment`, ``"waveform"`` when it holds 8 or more samples per nominal cycle,
  ``"amplitude"`` otherwise (a recorder's slow segments hold one magnitude per phase and
  cycle, not waveform samples: :mod:`~loadbayes.recordings.record` keeps them as
  magnitudes and invents no P or Q from them).
- **Time**: the ``.dat`` time stamps (times ``timemult``) are used when they increase
  strictly in a few runs of even spacing that put the voltage at its nominal frequency,
  even where the rate table disagrees (its runs are then told from the stamps, and the
  note names the table's lines); the rate table's nominal times otherwise; neither, and
  the record is refused. The stamps are the recorder's
  clock for each sample, and frequency-tracking recorders sample a fixed number of times
  per *actual* cycle, which the nominal rate table cannot say; the largest difference
  between the two is kept in ``Waveforms.clock_note``.
- **Per-channel skews** (microseconds) are returned in ``Waveforms.skew_s`` and applied
  by the phasor estimator (a skew of s seconds turns a phasor by 2 pi f0 s).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loadbayes.io.errors import DataError
from loadbayes.recordings.comtrade_cfg import AnalogChannel, CfgInfo, parse_cfg
from loadbayes.recordings.comtrade_channels import (
    dead_channels,
    missing_note,
    pick_channels,
    scale_channel,
)
from loadbayes.recordings.comtrade_dat import (
    Segment,
    check_dat,
    declared_bytes,
    find_dat,
    kind_by_signal,
    load_samples,
    sample_times,
    segments_of,
    stamp_segments,
    stamps_problem,
)

__all__ = ["AnalogChannel", "CfgInfo", "Segment", "Waveforms", "parse_cfg", "read_comtrade"]


@dataclass(frozen=True)
class Waveforms:
    """Three-phase voltage and current waveforms in volts and amperes.

    Parameters
    ----------
    t_s : numpy.ndarray
        Sample times (s) from the first sample, shape (n,).
    v, i : numpy.ndarray
        Phase-to-neutral voltages and line currents, shape (3, n), phases a, b, c.
    f_nominal : float
        Nominal frequency (Hz) from the ``.cfg``.
    rate_hz : float
        Sampling rate (Hz).
    start : str
        First-sample time stamp as written in the ``.cfg``.
    channels : dict of str to str
        Which channels were used (``"va"`` -> channel name ...).
    uniform : bool
        Whether the samples are evenly spaced at ``rate_hz`` (records with several
        rates, or time stamps only, are not: resample them with
        :func:`loadbayes.recordings.phasors.to_cycle_grid`).
    segments : tuple of Segment
        The runs of samples at one rate (one segment for a one-rate file).
    skew_s : numpy.ndarray or None
        Per-channel time skews (s), shape (2, 3): voltages, currents.
    station, trigger, encoding : str
        Station name, trigger time stamp and the ``.cfg``'s text encoding.
    clock_note : str
        Which times were used (time stamps or rate table) and how far they disagree.
    choice : str
        How the channels were chosen (named, by bay, found by unit and phase).
    notes : tuple of str
        What else was decided reading the file (content after the declared samples
        ignored, a current phase that is zero throughout, ...), in plain words.
    """

    t_s: np.ndarray
    v: np.ndarray
    i: np.ndarray
    f_nominal: float
    rate_hz: float
    start: str
    channels: dict[str, str]
    uniform: bool = True
    segments: tuple[Segment, ...] = ()
    skew_s: np.ndarray | None = None
    station: str = ""
    trigger: str = ""
    encoding: str = ""
    clock_note: str = ""
    choice: str = ""
    notes: tuple[str, ...] = ()


def read_comtrade(
    cfg_path: str | os.PathLike[str],
    *,
    voltage: list[str] | None = None,
    current: list[str] | None = None,
    bay: str | None = None,
    side: str = "primary",
    encoding: str | None = None,
) -> Waveforms:
    """Read three-phase voltages and currents from a COMTRADE record.

    Parameters
    ----------
    cfg_path : str or os.PathLike
        The ``.cfg``; the ``.dat`` beside it has the same stem.
    voltage, current : list of str, optional
        Names (``ch_id``) or 1-based numbers of the phase a, b, c channels. By default
        they are found from the unit (V or A, with a k/M/m prefix) and the phase field or
        name suffix (A/B/C, R/S/T, L1/L2/L3); several current sets need ``bay``.
    bay : str, optional
        Take the three phase channels of the bay whose ``ccbm`` field or channel name
        holds this text; a bay without voltages takes the first three-phase voltage.
    side : {"primary", "secondary"}
        Scale the values to the transformer's primary or secondary side with the
        ``.cfg``'s ratio (1999 and later).
    encoding : str, optional
        The ``.cfg``'s text encoding; detected by default.

    Returns
    -------
    Waveforms
        Times and phase waveforms (V, A), as sampled (see ``Waveforms.uniform`` and
        ``Waveforms.segments``).

    Raises
    ------
    DataError
        For a malformed ``.cfg`` (with its line), a missing or short ``.dat``, a
        missing sample in a channel used, or times that do not increase.
    """
    if side not in ("primary", "secondary"):
        raise ValueError(f"side must be 'primary' or 'secondary', not {side!r}")
    cfg = Path(cfg_path)
    info = parse_cfg(cfg, encoding=encoding)
    dat = find_dat(cfg, info.path)
    if dat is None:
        raise DataError(f"data file {cfg.with_suffix('.dat').name} not found beside it", info.path)
    if info.n_samples < 2:
        raise DataError(
            f"line {info.lines['rates'] + len(info.rates)}: {info.n_samples} sample declared; "
            "a record needs at least two cycles",
            info.path,
        )
    check_dat(info, dat)
    vch, vhow = pick_channels(info, voltage, "voltage", bay)
    ich, ihow = pick_channels(info, current, "current", bay)
    raw, extra = declared_bytes(info, dat)
    notes = []
    if extra:
        notes.append(
            f"{dat.name}: {extra} bytes after the {info.n_samples} samples the .cfg declares "
            "were not read"
        )
    t, analog = load_samples(info, cfg, dat, raw)
    t = t[: info.n_samples]
    dt = np.diff(t)
    if not np.all(dt > 0):
        k = int(np.argmax(dt <= 0))
        raise DataError(
            f"sample {k + 2}: sample times are not increasing (is the data file type "
            f"{info.format} on line {info.lines['format']} of {cfg.name} right?)",
            str(dat),
        )
    t, clock, other = sample_times(info, raw, t)
    del raw
    dt = np.diff(t)
    segments = segments_of(info, t)
    # One rate: the .cfg's rate is exact (the times are rounded to the time base).
    # Several rates, or time stamps only (rate 0): sampled unevenly, resampled later.
    one_rate = len(info.rates) == 1 and info.rates[0][0] > 0
    rate = info.rates[0][0] if one_rate else float(1.0 / np.median(dt))
    uniform = one_rate or bool(np.max(np.abs(dt * rate - 1.0)) < 0.01)

    def stack(chans):
        out = []
        for ch in chans:
            idx = info.analog.index(ch)
            vals = analog[idx][: info.n_samples]
            bad = np.flatnonzero(~np.isfinite(vals))
            if bad.size and math.isfinite(ch.a * 2.0**31 + ch.b):
                raise DataError(
                    f"channel {ch.name!r}, sample {bad[0] + 1}: {missing_note(info, ch)}", str(dat)
                )
            with np.errstate(over="ignore", invalid="ignore"):
                scaled = scale_channel(ch, vals, side, info.path)
            if not np.all(np.isfinite(scaled)):
                raise DataError(
                    f"line {ch.line}: channel {ch.name!r}: its values overflow when scaled "
                    f"(multiplier a = {ch.a:g}, ratio {ch.primary:g}/{ch.secondary:g})",
                    info.path,
                )
            out.append(scaled)
        return np.vstack(out)

    v_arr, i_arr = stack(vch), stack(ich)
    if other is not None:
        t, clock, by_stamps = kind_by_signal(info, t, other, v_arr[0])
        if by_stamps:  # the stamps, not the table: their own rate and their own runs
            dt = np.diff(t)
            rate = float(1.0 / np.median(dt))
            uniform = bool(np.max(np.abs(dt * rate - 1.0)) < 0.01)
            segments = stamp_segments(t, info.f_nominal)
    elif not all(r > 0 for r, _ in info.rates):  # stamps alone: they must be usable
        problem = stamps_problem(t, v_arr[0], info.f_nominal)
        if problem:
            raise DataError(
                f"line {info.lines['rates'] + 1}: rate 0: a record timed by the .dat's stamps "
                f"alone, and these are implausible time stamps: {problem}",
                info.path,
            )
    notes += dead_channels(vch, v_arr, ich, i_arr, info.path, str(dat))
    names = {f"v{p}": ch.name for p, ch in zip("abc", vch, strict=True)}
    names.update({f"i{p}": ch.name for p, ch in zip("abc", ich, strict=True)})
    return Waveforms(
        t_s=t - t[0],
        v=v_arr,
        i=i_arr,
        f_nominal=info.f_nominal,
        rate_hz=rate,
        uniform=uniform,
        start=info.start,
        channels=names,
        segments=segments,
        skew_s=np.array([[ch.skew * 1e-6 for ch in vch], [ch.skew * 1e-6 for ch in ich]]),
        station=info.station,
        trigger=info.trigger,
        encoding=info.encoding,
        clock_note=clock,
        choice=f"voltages: {vhow}; currents: {ihow}",
        notes=tuple(notes),
    )
