"""Samplers and what they need: sufficient statistics, priors, conjugate Gibbs blocks."""
