"""Block moves for Metropolis-within-Gibbs: physics-free, one per file, on one contract.

:class:`~loadbayes.inference.moves.base.BlockMove` is the contract (a move takes and
returns a :class:`~loadbayes.inference.moves.base.BlockState`); :data:`MOVES` names
the moves a sampler offers (a new move is one file here plus one line in it).
"""

from __future__ import annotations

from loadbayes.inference.moves.adaptive_metropolis import AdaptiveMetropolis
from loadbayes.inference.moves.base import (
    BlockMove,
    BlockState,
    LogDensity,
    RunningCovariance,
    scaled_eigenvectors,
)
from loadbayes.inference.moves.factor_slice import FactorSlice
from loadbayes.inference.moves.sheared import ShearedAM

__all__ = [
    "MOVES",
    "AdaptiveMetropolis",
    "BlockMove",
    "BlockState",
    "FactorSlice",
    "LogDensity",
    "RunningCovariance",
    "ShearedAM",
    "scaled_eigenvectors",
]

#: The moves by name (all physics-free, same ``step`` contract).
MOVES: dict[str, type[BlockMove]] = {
    "am": AdaptiveMetropolis,
    "shear": ShearedAM,
    "slice": FactorSlice,
}
