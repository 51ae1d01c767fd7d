"""Fleets of buses: per-bus and pooled (hierarchical) ZIP fits over many loads at once."""
