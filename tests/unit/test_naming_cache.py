"""The named draws' cache of the motor's steady P, Q: the same names, fewer solves.

A run until converged names every draw after each round; with the fit's cache a later
call on the same chains, extended, solves only the new draws (fit/composite/naming.py).
"""

from __future__ import annotations

import numpy as np

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite import naming
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.models.composite_prior import CompositePrior


def _draws(rng, problem, chains, n):
    mean = np.asarray(problem.prior.theta_mean, dtype=float)
    theta = mean + 0.1 * rng.standard_normal((chains, n, mean.size))
    betas = rng.normal(0.3, 0.1, (chains, n, len(problem.events), 7))
    tau = rng.uniform(1e3, 2e3, (chains, n, 2))
    return theta, betas, tau


def test_a_cached_naming_of_extended_chains_solves_only_the_new_draws(monkeypatch):
    evs = [simulate_event("small_industrial", depth=d, t_end_s=1.0, fs=60.0, seed=s)[0]
           for d, s in ((0.3, 1), (0.2, 2))]  # fmt: skip
    problem = CompositeProblem(evs, CompositePrior.default(evs), window_s=0)
    rng = np.random.default_rng(0)
    theta, betas, tau = _draws(rng, problem, 3, 500)
    solved = []
    inner = naming._steady_pq_into

    def counted(e, *args):
        solved.append(e.shape[0])
        return inner(e, *args)

    monkeypatch.setattr(naming, "_steady_pq_into", counted)
    plain = naming.named_draws(problem, theta, betas, tau)
    assert solved == [1500]
    cache: dict = {}
    for n in (200, 350, 500, 500):  # three rounds, then the final naming
        got = naming.named_draws(problem, theta[:, :n], betas[:, :n], tau[:, :n], cache=cache)
    assert solved[1:] == [600, 450, 450, 0]  # each round's new draws, and none again
    assert got.keys() == plain.keys()
    for name, value in plain.items():
        np.testing.assert_array_equal(got[name], value, err_msg=name)


def test_other_chains_or_fewer_draws_are_solved_afresh(monkeypatch):
    evs = [simulate_event("small_industrial", depth=0.3, t_end_s=1.0, fs=60.0, seed=1)[0]]
    problem = CompositeProblem(evs, CompositePrior.default(evs), window_s=0)
    rng = np.random.default_rng(1)
    theta, betas, tau = _draws(rng, problem, 2, 300)
    cache: dict = {}
    naming.named_draws(problem, theta, betas, tau, cache=cache)
    other = theta.copy()
    other[1, 10, 0] += 1e-3  # a chain that is not the one named before
    for th in (other, theta[:, :200]):  # another chain's head; a run cut shorter
        got = naming.named_draws(problem, th, betas[:, : th.shape[1]], tau[:, : th.shape[1]],
                                 cache=cache)  # fmt: skip
        want = naming.named_draws(problem, th, betas[:, : th.shape[1]], tau[:, : th.shape[1]])
        for name, value in want.items():
            np.testing.assert_array_equal(got[name], value, err_msg=name)
