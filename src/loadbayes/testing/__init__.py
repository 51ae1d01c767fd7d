"""Generic checks of a sampler against its own model: SBC and Geweke's getting-it-right.

They know nothing of load models: a case gives a prior draw, data from it and the
sampler's draws. The statistical test tier and the calibration study use them.
"""
