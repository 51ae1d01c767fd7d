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
    #: Six block steps per iteration in a run whose burn-in is 4,000 or more (the
    #: defaults' and longer; ``sampler.BLOCK_STEPS_MIN_BURN``): the chains' slowest
    #: coordinates (the motors' Rs, H and shares) diffuse along one flat, connected
    #: ridge, and a block step (about 0.2 ms) is what moves them (docs/composite.md, "Why
    #: cmld-lite's chains do not mix: one ridge, not modes").
    block_steps: ClassVar[int] = 6
    motors: tuple[str, ...] = ("a", "b")
    feeder: bool = True
    motor_d: bool = True
    electronics: bool = True
