"""Figures of fits.

``fit`` (the panels of a fit's figures, ``--plot`` and the report) and ``composite`` (a
composite fit against its events), ``validation`` (a composite fit against held-out
events).

:func:`plot_result` is :meth:`loadbayes.posterior.Posterior.plot`'s figure.
"""

from __future__ import annotations

from typing import Any

__all__ = ["plot_result"]


def plot_result(post: Any, *, hdi_prob: float = 0.95, seed: int = 0) -> Any:
    """The figure of a fit: a composite's fit to its recordings, else :func:`plot_fit`."""
    if post.model == "composite":
        from loadbayes.fit.composite.predictive import events_of, fault_times, predictive_band
        from loadbayes.plots.composite import plot_composite_fit

        events = events_of(post)
        if events:
            torque = post.settings.get("torque", [1.0, 0.0, 0.0])
            fixed = (1.0, 0.0, 0.0) if isinstance(torque, str) else tuple(torque)
            f_hz = float(post.settings.get("f_hz", 60.0))
            bands = predictive_band(post, events, f_hz=f_hz, torque=fixed, prob=hdi_prob,
                                    seed=seed)  # fmt: skip
            return plot_composite_fit(post, events, bands, fault_times(post, events))
    from loadbayes.plots.fit import plot_fit

    return plot_fit(post, hdi_prob=hdi_prob)
