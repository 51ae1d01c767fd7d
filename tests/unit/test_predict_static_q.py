"""``predict`` plays the static Q's terms of the fitted event that went lowest."""

from __future__ import annotations

import numpy as np

from loadbayes.fit.composite.predict_scope import static_q_terms


def _cover(*v_min):
    return {"events": [{"event": f"sag {k}", "v_min": v} for k, v in enumerate(v_min)]}


def test_the_deepest_fitted_events_terms_are_played():
    values = {"": (-16.0, 31.0, -14.0), "_e1": (0.5, 0.3, 0.2), "_e2": (0.1, 0.1, 0.1)}
    draws = {
        n + sfx: np.full(4, x)
        for sfx, xs in values.items()
        for n, x in zip(("cq2", "cq1", "cq0"), xs, strict=True)
    }
    terms, name = static_q_terms(draws, _cover(0.85, 0.62, 0.71))
    assert name == "sag 1" and terms.shape == (4, 3)
    assert np.allclose(terms[0], [0.5, 0.3, 0.2])
    # Event 0 the deepest (or one event): event 0's, as before.
    terms, name = static_q_terms(draws, _cover(0.6, 0.62, 0.71))
    assert name == "sag 0" and np.allclose(terms[0], [-16.0, 31.0, -14.0])
    terms, _ = static_q_terms({k: draws[k] for k in ("cq2", "cq1", "cq0")}, _cover(0.9))
    assert np.allclose(terms[:, 0], -16.0)
