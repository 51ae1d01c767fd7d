"""GridDyn events for fits: noise added by the caller's seed, and files `fit composite` reads.

:func:`griddyn_events` runs (or reads from the cache) one GridDyn CMLD case per depth and
adds independent normal noise to P and Q (sd ``noise * hypot(p0, q0)``, the convention of
the package's own simulator) and optionally to V; :func:`write_events_csv` writes one CSV
per event with the columns ``loadbayes fit composite`` reads (t_s, v, p, q, angle_rad;
per unit, 60 Hz: pass ``--f-hz 60``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from loadbayes.cases.griddyn.cases import DEPTHS, Cmld, run_case


def griddyn_events(
    depths=(DEPTHS["shallow"], DEPTHS["medium"]),
    seed_noise: int | None = 0,
    *,
    noise: float = 0.01,
    noise_v: float = 0.0,
    cmld: Cmld | None = None,
    rate_hz: float = 60.0,
) -> tuple[list[pd.DataFrame], dict]:
    """One frame per depth (t_s, v, angle_rad, p, q) with noise, and the truth.

    ``seed_noise=None`` or ``noise=0``: the runs as GridDyn wrote them. The truth is
    :meth:`cases.Cmld.truth` plus ``events`` (each run's ``truth['event']``) and the noise.
    """
    cmld = cmld or Cmld()
    rng = np.random.default_rng(seed_noise) if seed_noise is not None else None
    frames, events, truth = [], [], {}
    for depth in depths:
        frame, truth = run_case(cmld, depth, rate_hz=rate_hz)
        frame = frame.copy()
        if rng is not None and (noise > 0 or noise_v > 0):
            sd = noise * float(np.hypot(truth["event"]["p0"], truth["event"]["q0"]))
            frame["p"] += rng.normal(0.0, sd, len(frame))
            frame["q"] += rng.normal(0.0, sd, len(frame))
            frame["v"] += rng.normal(0.0, noise_v, len(frame))
        frames.append(frame)
        events.append(truth.pop("event"))
    truth = truth | {"events": events, "noise": noise, "noise_v": noise_v, "seed_noise": seed_noise}
    return frames, truth


def write_events_csv(
    frames: list[pd.DataFrame], directory: Path, stem: str = "griddyn"
) -> list[Path]:
    """One CSV per event in ``directory``; refuses to overwrite an existing file."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, frame in enumerate(frames, start=1):
        path = directory / f"{stem}_{i}.csv"
        with path.open("x") as handle:
            frame[["t_s", "v", "p", "q", "angle_rad"]].to_csv(handle, index=False)
        paths.append(path)
    return paths
