"""Load models (physics only): ZIP, exponential, induction motor, composite."""
