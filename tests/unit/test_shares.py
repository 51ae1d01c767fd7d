"""The share-only steps of a model of parts (``fit/composite/shares.py``).

- the basis' sums give the compiled sums at the model's own shares (``event_basis``
  against ``event_sums``, random draws, white and AR(1), with the negative sequence);
- the steps' log-density is the problem's (``DesignProblem.collapsed``) at random states;
- the target in the weights carries the Dirichlet prior's Jacobian exactly (against
  ``PartsPrior.log_u`` and a numerical Jacobian of the map from the weights to the
  sampled coordinates);
- on a toy target whose posterior is known (uniform Dirichlet shares times a linear-
  Gaussian likelihood, the reference by importance sampling from the prior, computed
  apart from the steps' code), the steps' draws have its means and sds.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from loadbayes.fit.composite.design import DesignProblem
from loadbayes.fit.composite.shares import ShareMoves
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.part_priors import PartsPrior


def _kernel_events(angle: bool, negative: bool):
    # The events of test_parts_kernel.py: two sags (one deep) and a record with gaps.
    path = Path(__file__).with_name("test_parts_kernel.py")
    spec = importlib.util.spec_from_file_location("parts_kernel_events", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod._events(angle, negative)


CASES = [("cmld-lite", 0.0, True, True, "white"), ("cmld-lite", 1 / 60, False, False, "ar1"),
         ("slm", 1 / 60, True, True, "ar1"), ("cmld-lite", 0.0, True, True, "ar1")]  # fmt: skip


def _problem(name, window, angle, negative, noise):
    model = dynamic_model(name, f_hz=60.0, window_s=window, noise=noise)
    events = _kernel_events(angle, negative)
    problem = DesignProblem(model, events, model.default_prior(events))
    moves = problem.conditional_moves()
    moves = moves.moves[-1] if hasattr(moves, "moves") else moves
    assert isinstance(moves, ShareMoves)
    return problem, moves


def _states(problem, count, seed):
    mean, cov, _, _ = problem.prior.scale_free()
    rng = np.random.default_rng(seed)
    return [problem.prior.project(rng.multivariate_normal(mean, 0.3 * cov)) for _ in range(count)]


@pytest.mark.parametrize(("name", "window", "angle", "negative", "noise"), CASES)
def test_the_basis_gives_the_compiled_sums_at_the_models_shares(name, window, angle, negative,
                                                                 noise):  # fmt: skip
    problem, moves = _problem(name, window, angle, negative, noise)
    ar = noise == "ar1"
    checked = 0
    for u in _states(problem, 15, 0):
        theta = problem.theta(u)
        w = moves.weights(u)
        for ev in problem.events:
            want = problem.model.event_sums(ev, theta, ar=ar)
            basis = problem.model.event_basis(ev, theta, ar=ar)
            assert (want is None) == (basis is None)
            if want is None:
                continue
            got = moves.sums([basis], w, None if not ar else np.zeros(2))[0]
            plain = want[0] if ar else want
            for a, b in zip(plain, (got.ztz, got.zty, got.yty, got.n), strict=True):
                assert np.allclose(a, b, rtol=1e-9, atol=1e-9 * (1 + np.abs(a).max()))
            checked += 1
    assert checked >= 30


@pytest.mark.parametrize(("name", "window", "angle", "negative", "noise"), CASES)
def test_the_steps_density_is_the_problems(name, window, angle, negative, noise):
    # To 1e-9 of the data's own term (sum of tau_g y'y over channels and events): the
    # collapsed density is a difference of terms that size (measured: 1e-11 at most).
    problem, moves = _problem(name, window, angle, negative, noise)
    tau = np.array([1e4, 3e3, 10.0])[: problem.n_channels]
    rho = np.array([0.6, -0.3]) if noise == "ar1" else None
    for u in _states(problem, 10, 1):
        want, sums = problem.collapsed(u, tau, rho=rho)
        got = moves.log_density(u, tau, rho)
        scale = sum(float(tau @ s.yty) for s in sums)
        assert abs(got - want) <= 1e-9 * scale, (got, want)


def test_a_step_returns_the_problems_density_and_sums_at_its_new_state():
    problem, moves = _problem(*CASES[1])
    tau, rho = np.array([1e4, 3e3]), np.array([0.4, 0.2])
    u = _states(problem, 1, 2)[0]
    lp, sums = problem.collapsed(u, tau, rho=rho)
    rng = np.random.default_rng(0)
    u2, lp2, sums2 = moves(u, lp, sums, None, rng, tau=tau, rho=rho, adapting=True)
    share = [problem.model.theta_names.index(n) for n in problem.model.theta_names
             if n.startswith("lr_")]  # fmt: skip
    rest = np.setdiff1d(np.arange(u.size), share)
    assert not np.array_equal(u2[share], u[share]) and np.array_equal(u2[rest], u[rest])
    want, fresh = problem.collapsed(u2, tau, rho=rho)
    assert lp2 == pytest.approx(want, rel=1e-9)
    for a, b in zip(sums2, fresh, strict=True):
        assert np.allclose(a.ztz, b.ztz, rtol=1e-8, atol=1e-8)
    # Off (share_steps 0): no such steps at all.
    model = dynamic_model("cmld-lite", f_hz=60.0, share_steps=0)
    off = DesignProblem(model, problem.events, model.default_prior(problem.events))
    assert not isinstance(off.conditional_moves(), ShareMoves)
    assert not hasattr(off.conditional_moves(), "moves")


def test_the_weights_target_carries_the_dirichlet_jacobian():
    # log_u(u(w)) + log|du/dw| must be -2 log f_s plus a constant (the module docstring):
    # checked with a numerical Jacobian of u(w) over w's first K + 2 entries.
    problem, moves = _problem(*CASES[0])
    rng = np.random.default_rng(5)
    u0 = _states(problem, 1, 3)[0]
    nw = len(problem.model.parts) + 3
    values = []
    for _ in range(6):
        w = rng.dirichlet(np.ones(nw))
        u = moves.with_weights(u0, w)
        assert np.allclose(moves.weights(u), w, rtol=1e-12)

        def coords(free, u=u):
            full = np.append(free, 1.0 - free.sum())
            x = moves.with_weights(u, full)
            return x[np.r_[moves.f_index, moves.a_index]]

        jac = np.empty((nw - 1, nw - 1))
        for i in range(nw - 1):
            h = 1e-7 * w[i]
            up, dn = w[:-1].copy(), w[:-1].copy()
            up[i] += h
            dn[i] -= h
            jac[:, i] = (coords(up) - coords(dn)) / (2 * h)
        log_jac = np.linalg.slogdet(jac)[1]
        values.append(problem.prior.log_u(u) + log_jac + 2.0 * math.log(w[-3:].sum()))
    assert np.ptp(values) < 1e-5, values


class _Toy:
    """A linear-Gaussian model of shares alone: two dynamic parts and the static three."""

    parts = ("m", "d")
    theta_names = free_coordinates = ("x", "lr_m", "lr_d", "lr_a1", "lr_a2")
    scale_free = np.eye(5)
    beta_names = ("p0", "cq2", "cq1", "cq0")
    channel_names = ("p", "q")
    share_steps = 25

    def __init__(self, rng):
        n, m = 15, 8  # 5 weights and 3 fixed columns
        self.b = rng.normal(size=(2, n, m))
        self.b[0, :, 5:] = 0.0  # P has no fixed column
        self.w_true = np.array([0.2, 0.3, 0.1, 0.15, 0.25])
        self.y = np.stack([g @ _w_matrix(self.w_true) @ [1.0, 0.3, -0.2, 0.4] for g in self.b])
        self.y += rng.normal(0.0, 0.5, size=self.y.shape)

    def event_basis(self, event, theta, ar=False):
        b, y = self.b, self.y
        return (np.einsum("gna,gnb->gab", b, b), np.einsum("gna,gn->ga", b, y),
                np.einsum("gn,gn->g", y, y), np.full(2, float(y.shape[1])))  # fmt: skip


def _w_matrix(w):
    out = np.zeros((w.size + 3, 4))
    out[: w.size, 0] = w
    out[w.size :, 1:] = np.eye(3)
    return out


def _reference(toy, tau, m0, p0, draws, rng):
    # Importance sampling from the priors (f, a uniform on their simplexes), weighted by
    # the collapsed likelihood written out here with the explicit design Z_g = B_g W(w).
    f = rng.dirichlet(np.ones(3), draws)
    a = rng.dirichlet(np.ones(3), draws)
    w = np.concatenate([f[:, :2], f[:, 2:] * a], axis=1)
    big = np.zeros((draws, 8, 4))
    big[:, :5, 0] = w
    big[:, 5:, 1:] = np.eye(3)
    z = np.einsum("gna,dak->dgnk", toy.b, big)
    prec = np.diag(p0) + np.einsum("g,dgnk,dgnl->dkl", tau, z, z)
    h = p0 * m0 + np.einsum("g,dgnk,gn->dk", tau, z, toy.y)
    mu = np.linalg.solve(prec, h[..., None])[..., 0]
    logw = 0.5 * np.einsum("dk,dk->d", h, mu) - 0.5 * np.linalg.slogdet(prec)[1]
    weight = np.exp(logw - logw.max())
    weight /= weight.sum()
    mean = weight @ w
    sd = np.sqrt(weight @ (w - mean) ** 2)
    return mean, sd, 1.0 / float(np.sum(weight**2))


@pytest.mark.statistical
def test_the_steps_sample_a_known_posterior():
    # False alarm: 10 checks (5 means, 5 sds) at 4.5 combined standard errors each, about
    # 7e-5 in all; the run is deterministic (fixed seeds).
    rng = np.random.default_rng(11)
    toy = _Toy(rng)
    prior = PartsPrior(np.zeros(1), np.eye(1), ((1, 3), (3, 5)), np.full(4, 10.0),
                       positive=None)  # fmt: skip
    problem = DesignProblem(toy, [object()], prior)
    moves = problem.conditional_moves()
    assert isinstance(moves, ShareMoves)
    tau = np.array([4.0, 4.0])
    mean_ref, sd_ref, ess_ref = _reference(toy, tau, problem.m0, problem.p0, 400_000, rng)
    assert ess_ref > 5000  # the reference's own Monte Carlo error is small
    u = np.zeros(5)
    lp = problem.log_collapsed(moves.sums(moves.basis(u, False), moves.weights(u), None), u, tau)
    draws = []
    for it in range(6000):
        u, lp, _ = moves(u, lp, None, None, rng, tau=tau, adapting=it < 1000)
        if it >= 1000:
            draws.append(moves.weights(u))
    draws = np.array(draws)
    # Standard errors by batch means (50 batches of 100 iterations).
    batches = draws.reshape(50, -1, 5)
    se_mean = batches.mean(axis=1).std(axis=0, ddof=1) / math.sqrt(50)
    se_sd = batches.std(axis=1).std(axis=0, ddof=1) / math.sqrt(50)
    err_mean = np.sqrt(se_mean**2 + sd_ref**2 / ess_ref)
    err_sd = np.sqrt(se_sd**2 + sd_ref**2 / (2 * ess_ref))
    assert np.all(np.abs(draws.mean(axis=0) - mean_ref) < 4.5 * err_mean), (
        draws.mean(axis=0),
        mean_ref,
        err_mean,
    )
    assert np.all(np.abs(draws.std(axis=0) - sd_ref) < 4.5 * err_sd), (
        draws.std(axis=0),
        sd_ref,
        err_sd,
    )
    transfer, joint = moves.acceptance
    assert 0.1 < transfer < 0.6 and 0.1 < joint < 0.5
