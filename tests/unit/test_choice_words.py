"""The model choice's words when the fits it compares have not converged.

``fit/composite/choice``: a held-out ELPD difference's standard error is the data's,
given the draws; where the two best models' chains have not mixed, the scores move with
the chains (on the real record the choice flipped between seeds with "ahead by" either
way), and the words must not call the choice settled. Draws written here with NumPy.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from loadbayes.fit.composite.choice import _words, _worst_rhat


def _fit(draws):
    return SimpleNamespace(posterior=SimpleNamespace(draws=draws))


def test_worst_rhat_reads_every_scalar_draw_of_every_fit():
    rng = np.random.default_rng(7)
    mixed = rng.standard_normal((2, 2000))
    split = mixed + np.array([[0.0], [3.0]])  # two chains in two places
    const = np.full((2, 2000), 0.5)  # a fixed quantity: no R-hat, skipped
    vector = rng.standard_normal((2, 2000, 3))  # per-event draws: not a scalar, skipped
    good = _fit({"a": mixed, "c": const, "v": vector})
    assert _worst_rhat([good]) < 1.01
    assert _worst_rhat([good, _fit({"b": split})]) > 1.5
    assert _worst_rhat([_fit({"a": mixed[:1]})]) is None  # one chain: not judged (JSON null)


def _rows(r_hat_best, r_hat_second, gap=300.0, se=120.0):
    return [
        {"model": "slm", "elpd": 500.0, "d_elpd": 0.0, "se_d_elpd": 0.0, "r_hat": r_hat_best},
        {"model": "cmld-lite", "elpd": 500.0 - gap, "d_elpd": -gap, "se_d_elpd": se,
         "r_hat": r_hat_second},
        {"model": "zip+motor", "elpd": -900.0, "d_elpd": -1400.0, "se_d_elpd": 600.0,
         "r_hat": 3.0},  # third and unconverged: does not decide between the first two
    ]  # fmt: skip


def test_a_converged_difference_past_two_se_is_said_settled():
    words = _words(_rows(1.005, 1.008))
    assert words.startswith("slm predicts the held-out events best (ELPD 500.0)")
    assert ", ahead of cmld-lite by 300.0 (SE 120.0)" in words
    assert "converged" not in words


def test_unconverged_chains_do_not_settle_the_choice():
    words = _words(_rows(1.005, 1.84))
    assert "ahead of" not in words
    assert "cmld-lite is behind by 300.0 (SE 120.0)" in words
    assert "chains of cmld-lite have not converged (R-hat up to 1.84)" in words
    assert "do not settle the choice" in words
    both = _words(_rows(1.95, 1.84))
    assert "chains of slm and cmld-lite have not converged (R-hat up to 1.95)" in both


def test_one_chain_keeps_the_data_s_verdict():
    assert ", ahead of cmld-lite" in _words(_rows(None, None))
    assert "the data do not settle" in _words(_rows(None, None, gap=100.0))
