"""The SciPy reference's start for the motor kernel's tests: steady while the voltage turns.

The kernel starts its motor in the steady state at the speed the record's angle turns at
over its steady start (``motor_kernel.start_speed``); its tests' SciPy references reach
that state independently, by running the model on the rotation for 30 s. That run costs
seconds of CPU (a Python right-hand side at rtol 1e-11) and depends only on the motor and
the start (V_0, the angle's start and slope), so it is made once per start: the tests
that differ only after the start (the depths of a sag) share it.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy.integrate import solve_ivp

from loadbayes.models.motor import derivatives, steady_state

__all__ = ["turning_start"]


def turning_start(m, t, v, delta, t0):
    """The state at ``t[0]``: steady with the voltage turning as the angle starts to.

    The kernel's rule (``motor_kernel.start_speed``): the angle's least-squares slope over
    the first 0.2 s before V leaves ``V_0`` by 0.005, none below 1 mHz. Reached here
    independently, by running the SciPy model 30 s on that rotation from the nominal
    steady state.
    """
    keep = np.cumprod((t - t[0] <= 0.2) & (np.abs(v - v[0]) <= 0.005)).astype(bool)
    slope = np.polyfit(t[keep] - t[0], delta[keep] - delta[0], 1)[0]
    slope = 0.0 if abs(slope) < 2 * np.pi * 1e-3 else slope
    return np.array(_settled(m, float(v[0]), float(delta[0]), float(slope), float(t0)))


@cache
def _settled(m, v0: float, delta0: float, slope: float, t0: float) -> tuple[float, ...]:
    """The motor ``m`` (a frozen dataclass) run 30 s on ``V_0`` turning at ``slope``."""

    def rhs(tt, y):
        dd = delta0 + slope * tt
        return derivatives(y, v0 * np.cos(dd), v0 * np.sin(dd), m, t0=t0)

    op = steady_state(m, v_pu=v0, t0=t0)
    sol = solve_ivp(rhs, (-30.0, 0.0), op.state, method="DOP853", rtol=1e-11, atol=1e-13)
    assert sol.success
    return tuple(sol.y[:, -1].tolist())
