"""The motor study's settings and result: the paper's tables, the fits, ``ImStudy``.

Every other module of :mod:`loadbayes.studies.im_paper` reads these; this one imports
none of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.models.motor import COEFFICIENT_NAMES, MotorParams
from loadbayes.posterior import Posterior

#: The paper's Table I: (real value, estimated mean, error %). Not physical (docs/paper.md,
#: slip 7): b1, b2, b3 must be negative for any motor under the paper's definitions.
PAPER_TABLE1: dict[str, tuple[float, float, float]] = {
    "b1": (0.0077, 0.007683, 0.22),
    "b2": (0.018, 0.01824, 1.33),
    "b3": (25.0, 24.8, 0.8),
    "ab": (0.20, 0.211, 5.5),
    "ac": (0.80, 0.813, 1.63),
}
#: The paper's Table III: (GS, LS, KF, real value).
PAPER_TABLE3: dict[str, tuple[float, float, float, float]] = {
    "b1": (0.007683, 0.0076, 0.0077, 0.0077),
    "b2": (0.01824, 0.1375, 0.0185, 0.018),
    "b3": (24.8, 18.0, 34.0, 25.0),
    "ab": (0.211, 2.06, 1.8, 0.2),
    "ac": (0.813, 4.04, 3.0, 0.8),
}
PHYSICAL = ("rs", "xp", "x", "tp_s", "h_s", "xs", "xm", "xr", "rr")
METHODS = {
    "gs": "GS (modelled currents)",
    "ls": "LS (modelled currents)",
    "gs_measured": "GS (paper's form)",
    "ls_measured": "LS (paper's form)",
    "kf_measured": "KF (paper's form)",
}
EIV_MOTOR = "small_industrial"
FULL = {"draws": 40_000, "burn": 5_000, "chains": 4}
QUICK = {"draws": 4_000, "burn": 1_000, "chains": 2}
#: ``reproduce all --smoke``: a check of the pipeline, not a result.
SMOKE = {"draws": 600, "burn": 200, "chains": 2}
_MARK = "loadbayes:section im"


@dataclass
class MotorRun:
    """One motor: its parameters, the simulated record, and the five fits."""

    name: str
    params: MotorParams
    data: pd.DataFrame
    fits: dict[str, Posterior]
    summaries: dict[str, pd.DataFrame] = field(default_factory=dict)

    @property
    def truth(self) -> dict[str, float]:
        """True coefficients and physical parameters."""
        out = dict(self.params.coefficients())
        p = self.params
        out.update(rs=p.rs, xp=p.xp, x=p.x, tp_s=p.tp_s, h_s=p.h_s)
        out.update(xs=p.xs, xm=p.xm, xr=p.xr, rr=p.rr)
        return out

    def summary(self, method: str) -> pd.DataFrame:
        """ArviZ summary (95% HDI) of one fit, cached."""
        if method not in self.summaries:
            names = [*COEFFICIENT_NAMES, *PHYSICAL]
            self.summaries[method] = self.fits[method].summary(hdi_prob=0.95, var_names=names)
        return self.summaries[method]

    def estimate(self, method: str, name: str) -> float:
        """Point estimate: the posterior mean, or the exact LS / KF estimate."""
        post = self.fits[method]
        if "estimate" in post.settings:
            return float(post.settings["estimate"][name])
        return float(np.nanmean(post.draws[name]))


@dataclass
class ImStudy:
    """Everything the study computed."""

    settings: dict[str, Any]
    runs: dict[str, MotorRun]
    eiv: pd.DataFrame


def _err(est: float, true: float) -> float:
    # Signed relative to the truth: negative means smaller in magnitude (toward zero).
    return 100.0 * (est / true - 1.0)
