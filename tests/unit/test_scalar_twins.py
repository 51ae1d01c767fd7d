"""The reference simulation's one-sample paths give the array paths' bits.

``models.motor.derivatives`` and ``cases.motor_sim.Disturbance`` answer an ODE solver's
one-time calls in Python floats (NumPy's cost on 0-d arrays was most of a simulation's
time). Each is a second writing of its array path; these tests hold the two equal to the
bit, so that a change to one and not the other fails here.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.motor_sim import MOTORS, Disturbance, sag
from loadbayes.models.motor import derivatives


@pytest.mark.parametrize("name", sorted(MOTORS))
def test_one_sample_derivatives_are_the_array_paths(name):
    params = MOTORS[name]
    rng = np.random.default_rng(0)
    states = np.vstack([rng.normal(0.0, 0.5, 200), rng.normal(0.8, 0.3, 200),
                        rng.uniform(0.0, 1.1, 200)])  # fmt: skip
    ud, uq = rng.normal(0.9, 0.2, 200), rng.normal(0.1, 0.2, 200)
    for t0 in (0.0, 0.6, 1.3):
        whole = derivatives(states, ud, uq, params, t0=t0)
        one = np.column_stack([derivatives(states[:, k], float(ud[k]), float(uq[k]), params,
                                           t0=t0) for k in range(200)])  # fmt: skip
        np.testing.assert_array_equal(one, whole)


def test_one_time_of_a_profile_is_the_array_paths():
    steps = Disturbance(np.array([0.0, 0.1, 0.1, 0.3, 0.45, 0.45, 1.0]),
                        np.array([1.0, 1.0, 0.6, 0.7, 0.7, 1.02, 1.02]))  # fmt: skip
    rng = np.random.default_rng(1)
    for profile in (steps, sag(0.3, 0.1, 0.2, 0.05)):
        knots = profile.t_knots
        times = np.concatenate([knots, rng.uniform(-0.5, 1.5, 300), [-np.inf, np.inf]])
        for f in (profile, profile.left_limit):
            whole = f(times)
            one = np.array([f(float(t)) for t in times])
            np.testing.assert_array_equal(one, whole)
