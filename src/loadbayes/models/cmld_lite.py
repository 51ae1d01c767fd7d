"""``cmld-lite``: the WECC composite load's parts a fault record can speak to.

Behind the series impedance of the substation transformer and the feeder: motor A
(compressors: constant torque, low inertia), motor B (fans and pumps: torque rising with
speed squared, more inertia), motor D (single-phase air conditioners: the WECC
performance model that stalls), power electronics (constant power that trips between
``Vd1`` and ``Vd2``) and the static ZIP part with its capacitors: the parts of the WECC
composite load model (CMLDBLU2 / CMPLDW) less motor C, the substation's tap changer and
the feeder's shunt split, which a fault record of a fraction of a second does not
separate. Built from parts by :class:`~loadbayes.models.parts_model.PartsModel`;
``loadbayes export --to psse`` writes it as a CMLDBLU2 record with every fraction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from loadbayes.models.parts_model import PartsModel

__all__ = ["CmldLite"]


@dataclass(frozen=True)
class CmldLite(PartsModel):
    """Feeder, motors A and B, motor D, electronics, static part: the ``cmld-lite`` model."""

    name: ClassVar[str] = "cmld-lite"
    #: Twelve block steps per iteration in a run whose burn-in is 4,000 or more (the
    #: defaults' and longer; ``sampler.BLOCK_STEPS_MIN_BURN``): the chains' slowest
    #: coordinates (the motors' Rs, H and shares) diffuse along one flat, connected
    #: ridge, and a block step (about 0.5 ms) is what moves them (docs/composite.md, "Why
    #: cmld-lite's chains do not mix: one ridge, not modes"). One of them jumps, on
    #: average (the pooled t's jumps are accepted about 1 in 400 times: the walk is what
    #: crosses the ridge); and a first round of 10,000 iterations, then on until
    #: converged (``driver.parts_defaults``). Measured together against 6 steps, 35 % of
    #: them jumps, 16,000: docs/composite.md, "Twelve block steps".
    block_steps: ClassVar[int] = 12
    jumps_per_iteration: ClassVar[float | None] = 1.0
    first_round: ClassVar[int] = 10_000
    motors: tuple[str, ...] = ("a", "b")
    feeder: bool = True
    motor_d: bool = True
    electronics: bool = True
