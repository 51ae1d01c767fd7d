"""Test systems and scenario generators: the IEEE 33-bus feeder, the simulated motor."""
