"""The pooled model's conditionals against dense linear algebra."""

import numpy as np

from loadbayes.fleet import hierarchical as H


def _spd(rng, d):
    a = rng.standard_normal((d, d))
    return a @ a.T + d * np.eye(d)


def _regression(rng, ztz, ztr):
    """X'X and X'y of X = [1, z1, z2] whose shares see Z'Z = ztz and Z'r = ztr (P0 = 1)."""
    nb = ztz.shape[0]
    g3 = np.zeros((nb, 3, 3))
    g3[:, 1:, 1:] = ztz
    z1 = rng.standard_normal((nb, 2))
    g3[:, 0, 1:] = g3[:, 1:, 0] = z1
    g3[:, 0, 0] = 50.0
    xy = np.zeros((nb, 2, 3))
    xy[:, :, 1:] = ztr + z1[:, None, :]  # Z'y = Z'r + Z'1 with y = r + 1
    return g3, xy


def _factored(rng, ztz, ztr, tau, sig_inv, g3xy=None):
    """The factors and linear terms of the sweep at P0 = 1 (the kernels' inputs)."""
    nb, d = ztz.shape[0], sig_inv.shape[1]
    g3, xy = g3xy if g3xy is not None else _regression(rng, ztz, ztr)
    chol, u, ok = np.empty((nb, d, d)), np.empty((nb, d)), np.empty(nb, bool)
    H._factor(np.zeros(nb, np.int64), g3, xy, np.ones((nb, 2)), tau, sig_inv, chol, u, ok)
    return chol, u, ok


def test_collapsed_mu_terms_match_the_marginal_of_each_bus():
    rng = np.random.default_rng(0)
    nb, d = 5, 4
    ztz = np.stack([_spd(rng, 2) for _ in range(nb)])
    ztr = rng.standard_normal((nb, 2, 2))
    tau = rng.uniform(1, 5, (nb, 2))
    sig = _spd(rng, d)[None]
    sig_inv = np.linalg.inv(sig)
    prec = np.zeros((1, d, d))
    lin = np.zeros((1, d))
    H._mu_terms(np.zeros(nb, np.int64), *_factored(rng, ztz, ztr, tau, sig_inv), sig_inv, prec, lin)
    # theta_b integrated out: bus b is a Gaussian "observation" of mu with covariance
    # Sigma + J_b^-1 centred on J_b^-1 u_b.
    want_p = np.zeros((d, d))
    want_l = np.zeros(d)
    for b in range(nb):
        j = np.zeros((d, d))
        u = np.zeros(d)
        for c in range(2):
            j[2 * c : 2 * c + 2, 2 * c : 2 * c + 2] = tau[b, c] * ztz[b]
            u[2 * c : 2 * c + 2] = tau[b, c] * ztr[b, c]
        cov = sig[0] + np.linalg.inv(j)
        want_p += np.linalg.inv(cov)
        want_l += np.linalg.solve(cov, np.linalg.solve(j, u))
    np.testing.assert_allclose(prec[0], want_p, rtol=1e-9)
    np.testing.assert_allclose(lin[0], want_l, rtol=1e-9)


def test_bus_draw_has_the_conditional_mean_and_tau_the_gamma_rate():
    rng = np.random.default_rng(1)
    nb, d = 3, 4
    ztz = np.stack([_spd(rng, 2) for _ in range(nb)])
    ztr = rng.standard_normal((nb, 2, 2))
    theta_ls = np.einsum("bij,bcj->bci", np.linalg.inv(ztz), ztr)
    ssr_min = rng.uniform(0.1, 1, (nb, 2))
    tau = rng.uniform(1, 5, (nb, 2))
    sig_inv = np.linalg.inv(_spd(rng, d))[None]
    mu = rng.standard_normal((1, d))
    theta = np.zeros((nb, d))
    tau_in = tau.copy()
    g3, xy = _regression(rng, ztz, ztr)
    beta_ls = np.concatenate([np.ones((nb, 2, 1)), theta_ls], axis=2)  # (1, theta_ls)
    H._bus_sweep(np.zeros(nb, np.int64), *_factored(rng, ztz, ztr, tau, sig_inv, (g3, xy)),
                 (sig_inv[0] @ mu[0])[None], g3, xy, beta_ls, ssr_min,
                 np.ones((nb, 2), bool), np.full((nb, 2), 0.5), theta, np.ones((nb, 2)),
                 tau, np.zeros((nb, d)), np.zeros((nb, 2)), np.ones((nb, 2)))  # fmt: skip
    for b in range(nb):
        lm = sig_inv[0].copy()
        h = sig_inv[0] @ mu[0]
        for c in range(2):
            lm[2 * c : 2 * c + 2, 2 * c : 2 * c + 2] += tau_in[b, c] * ztz[b]
            h[2 * c : 2 * c + 2] += tau_in[b, c] * ztr[b, c]
        np.testing.assert_allclose(theta[b], np.linalg.solve(lm, h), rtol=1e-10)
        for c in range(2):
            e = theta[b, 2 * c : 2 * c + 2] - theta_ls[b, c]
            ssr = ssr_min[b, c] + e @ ztz[b] @ e
            assert tau[b, c] == np.float64(1.0 / (0.5 + 0.5 * ssr)) or np.isclose(
                tau[b, c], 1.0 / (0.5 + 0.5 * ssr), rtol=1e-12
            )


def test_inverse_wishart_draws_have_the_right_mean():
    # 20,000 draws: the sample mean of each entry is within 5 standard errors of
    # Psi / (nu - d - 1) (false alarm below 1e-5 per entry; fixed seed).
    rng = np.random.default_rng(2)
    d, nu = 2, 9.0
    psi = np.array([[0.5, 0.1], [0.1, 0.3]])
    draws = np.stack([H._draw_sigma(rng, np.array([nu]), psi[None])[0][0] for _ in range(20_000)])
    want = psi / (nu - d - 1)
    se = draws.std(axis=0) / np.sqrt(draws.shape[0])
    assert np.all(np.abs(draws.mean(axis=0) - want) < 5 * se)


def test_auto_nominal_power_becomes_each_bus_own_per_unit_exactly():
    """With --p0/--q0 auto the pooled model uses r = P / P0_hat - 1 per bus (P0_hat by LS)."""
    from loadbayes.core.stats import gram_of
    from loadbayes.fleet.stats import FleetStats
    from loadbayes.models.zip import ZIPModel

    rng = np.random.default_rng(7)
    auto, known, levels = ZIPModel(p0="auto", q0="auto"), [], []
    grams, lo, hi = [], [], []
    for scale in (3.0, 0.2):
        v = rng.uniform(0.9, 1.1, 300)
        x = v
        p = scale * (0.3 * x**2 + 0.2 * x + 0.5) + rng.normal(0, 0.01 * scale, v.size)
        q = scale * 0.4 * (0.5 * x**2 + 0.1 * x + 0.4) + rng.normal(0, 0.01, v.size)
        g = gram_of(auto.rows({"v": v, "p": p, "q": q}), auto.gram_columns)
        grams.append(g.matrix)
        lo.append(g.col_min)
        hi.append(g.col_max)
        design = np.column_stack([np.ones_like(x), (x - 1) * (x + 1), x - 1])
        lp = np.linalg.lstsq(design, p, rcond=None)[0][0]
        lq = np.linalg.lstsq(design, q, rcond=None)[0][0]
        levels.append((lp, lq))
        one = ZIPModel(p0=lp, q0=lq)
        known.append(gram_of(one.rows({"v": v, "p": p, "q": q}), one.gram_columns))
    stats = FleetStats(
        auto.gram_columns, np.array(["a", "b"], dtype=object), np.array([None, None]),
        np.stack(grams), np.array([300, 300]), np.stack(lo), np.stack(hi),
        np.array([False, False]),
    )  # fmt: skip
    out, notes = H._known_nominal(stats, auto)
    assert out.names == known[0].names
    for b in range(2):
        np.testing.assert_allclose(out.gram[b], known[b].matrix, rtol=1e-9, atol=1e-9)
        assert f"p0 = {levels[b][0]:.6g}" in notes[b][0]


def _scale_tries_dense(gen, psi0, nu0, v, sigma, sig_inv, a, b, tries=2, step=0.25):
    """The scale move's tries in the matrix form the compiled kernel replaced."""
    ncls = sigma.shape[0]
    eye = np.eye(v.size)[None]
    vv = np.outer(v, v)
    total = np.ones(ncls)
    for _ in range(tries):
        logc = step * gen.standard_normal(ncls)
        logu = np.log(gen.random(ncls))
        c = np.exp(logc)
        k = c - 1.0
        ci = eye + (1.0 / c - 1.0)[:, None, None] * vv[None]
        new_inv = ci @ sig_inv @ ci
        dtr = np.einsum("cij,cji->c", psi0, new_inv - sig_inv)
        take = logu < -0.5 * k * k * a + k * b - nu0 * logc - 0.5 * dtr
        cm = eye + np.where(take, k, 0.0)[:, None, None] * vv[None]
        sigma = cm @ sigma @ cm
        sig_inv = np.where(take[:, None, None], new_inv, sig_inv)
        b = np.where(take, c * (b - k * a), b)
        a = np.where(take, c * c * a, a)
        total = np.where(take, total * c, total)
    return sigma, sig_inv, total


def test_compiled_scale_tries_match_the_matrix_form():
    # The same normals and uniforms (drawn in the matrix form's order) must give the same
    # accepted scalings and the same Sigma and Sigma^-1 to rounding, for classes that
    # accept and classes that refuse (A, B drawn so that both happen). Each class has its
    # own Psi0 (the learned scales, HierPrior.spread_scale).
    from loadbayes.fleet.hier_kernels import _scale_tries

    rng = np.random.default_rng(3)
    ncls, d = 7, 4
    psi0 = np.stack([_spd(rng, d) * 0.01 * (1 + c) for c in range(ncls)])
    accepted = 0
    for trial in range(40):
        sigma = np.stack([_spd(rng, d) * 0.01 for _ in range(ncls)])
        sig_inv = np.linalg.inv(sigma)
        v = rng.standard_normal(d)
        v /= np.linalg.norm(v)
        a = rng.uniform(0.0, 50.0, ncls)
        b = rng.normal(0.0, 5.0, ncls)
        want = _scale_tries_dense(np.random.default_rng(trial), psi0, 6.0, v, sigma, sig_inv, a, b)
        gen = np.random.default_rng(trial)
        z, uni = np.empty((2, ncls)), np.empty((2, ncls))
        for r in range(2):
            z[r] = gen.standard_normal(ncls)
            uni[r] = gen.random(ncls)
        got_s, got_i, total = sigma.copy(), sig_inv.copy(), np.ones(ncls)
        _scale_tries(psi0, 6.0, v, 0.25, got_s, got_i, a.copy(), b.copy(), z, uni, total)
        np.testing.assert_allclose(total, want[2], rtol=1e-13)
        np.testing.assert_allclose(got_s, want[0], rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(got_i, want[1], rtol=1e-10, atol=1e-10)
        accepted += int(np.sum(total != 1.0))
    assert 0 < accepted < 40 * ncls


def test_compiled_mu_and_sigma_draws_match_the_dense_formulas():
    # The same variates through the compiled kernels and through numpy's linear algebra.
    rng = np.random.default_rng(4)
    ncls, d = 3, 4
    s0_inv, m0 = np.eye(d) / 100.0, rng.standard_normal(d)
    prec = np.stack([_spd(rng, d) for _ in range(ncls)])
    lin = rng.standard_normal((ncls, d))
    mu = H._draw_mu(np.random.default_rng(9), s0_inv, s0_inv @ m0, prec, lin)
    z = np.random.default_rng(9).standard_normal((ncls, d))
    p = s0_inv[None] + 0.5 * (prec + np.swapaxes(prec, 1, 2))
    lo = np.linalg.cholesky(p)
    want = np.linalg.solve(p, (s0_inv @ m0 + lin)[..., None])[..., 0]
    want += np.linalg.solve(np.swapaxes(lo, 1, 2), z[..., None])[..., 0]
    np.testing.assert_allclose(mu, want, rtol=1e-10, atol=1e-12)

    psi = np.stack([_spd(rng, d) for _ in range(ncls)])
    nu = np.array([7.0, 9.0, 30.0])
    sigma, sig_inv = H._draw_sigma(np.random.default_rng(5), nu, psi)
    g = np.random.default_rng(5)
    chi = g.chisquare(nu[:, None] - np.arange(d)[None, :])
    a = np.tril(g.standard_normal((ncls, d, d)), -1)
    a[:, np.arange(d), np.arange(d)] = np.sqrt(chi)
    ca = np.linalg.cholesky(np.linalg.inv(psi)) @ a
    want_inv = ca @ np.swapaxes(ca, 1, 2)
    np.testing.assert_allclose(sig_inv, want_inv, rtol=1e-10)
    np.testing.assert_allclose(sigma, np.linalg.inv(want_inv), rtol=1e-9)
    np.testing.assert_allclose(sigma @ sig_inv, np.broadcast_to(np.eye(d), sigma.shape), atol=1e-9)
