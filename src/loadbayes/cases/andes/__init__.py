"""Events simulated in ANDES.

``sim`` and ``grid`` (events at a load bus), ``compare`` (ANDES's motor against the
package's own reference).
"""
