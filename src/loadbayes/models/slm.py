"""``slm``: the synthesis load model of Chinese practice, a ZIP and one motor behind a feeder.

The static ZIP part and one lumped three-phase motor (the ``slm`` motor class of
:mod:`loadbayes.models.part_priors`) behind the series impedance ``Rd + jXd`` of the
substation transformer and the distribution network (China's "综合负荷模型" SLM: the
practice of the China Electric Power Research Institute's load modelling, with the
network's impedance between the bus and the load). Built from parts by
:class:`~loadbayes.models.parts_model.PartsModel`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from loadbayes.models.parts_model import PartsModel

__all__ = ["SynthesisLoad"]


@dataclass(frozen=True)
class SynthesisLoad(PartsModel):
    """ZIP + one motor behind ``Rd + jXd``: the ``slm`` model."""

    name: ClassVar[str] = "slm"
    motors: tuple[str, ...] = ("slm",)
    feeder: bool = True
    motor_d: bool = False
    electronics: bool = False
