"""A peer of the composite fit: NumPyro NUTS with the motor's ODE solved by diffrax.

The same posterior as ``fit_composite(CompositeModel(steps=False), ...)`` (and as bench_composite's
emcee): the motor in the scale-free coordinates ``u`` (with ``T0 = 1``: the likelihood
does not depend on it), prior ``MultivariateNormal(mean_u, cov_u)`` from
``CompositePrior.scale_free()``; the seven linear coefficients with their normal priors
(``P_m0 = f_m p0`` restricted to be positive: a half-normal, the same density up to a
constant); ``tau_p, tau_q`` Gamma(shape, rate) as the package's. The voltage is read as
the straight line between samples (``diffrax.LinearInterpolation``); the motor starts
from its steady state at ``V_0`` (the first root of the torque balance up from
``s = 0``, found by bisection and finished by one Newton step so that its gradient is
the implicit function's). The ODE is solved by ``Tsit5`` with a PID controller (rtol
1e-6, atol 1e-9, the tolerance of bench_composite's ``solve_ivp``), stepping on every
sample (the voltage's kinks), all in float64.

Only the bench environment has JAX (``make .venv-bench/.installed``: the ``bench``
extra).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

__all__ = ["nuts_diffrax"]


def _model_fn(ev: Any, prior: Any, f_hz: float = 60.0):
    import diffrax
    import jax
    import jax.numpy as jnp
    import numpyro
    import numpyro.distributions as dist

    jax.config.update("jax_enable_x64", True)
    mean_u, cov_u, _, _ = prior.scale_free()
    wb = 2.0 * math.pi * f_hz
    ts = jnp.asarray(ev.t, dtype=jnp.float64)
    v = jnp.asarray(ev.v, dtype=jnp.float64)
    x = v / ev.v0
    p_obs, q_obs = jnp.asarray(ev.p), jnp.asarray(ev.q)
    v_in = diffrax.LinearInterpolation(ts=ts, ys=v)
    sd = jnp.asarray(prior.beta_sd, dtype=jnp.float64)
    v0 = float(ev.v0)
    n = int(ts.size)
    dt0 = float(ev.t[1] - ev.t[0])

    def flux(s, rs, xp, dx, tp, volt):
        z = rs + 1j * xp
        return 1j * dx * volt / (z * (1.0 + 1j * wb * tp * s) + 1j * dx)

    def gap(s, rs, xp, dx, tp):
        e = flux(s, rs, xp, dx, tp, v0)
        i = (v0 - e) / (rs + 1j * xp)
        return jnp.real(e * jnp.conj(i)) - (1.0 - s) ** 2  # T0 = 1, A = 1

    grid = jnp.concatenate([jnp.geomspace(1e-6, 0.05, 200), jnp.linspace(0.05, 1.0, 200)[1:]])

    def slip(rs, xp, dx, tp):
        # The first upward crossing on the grid, refined by bisection without gradients,
        # then one Newton step that carries the implicit-function gradient.
        sg = jax.lax.stop_gradient
        g = jax.vmap(lambda s: gap(s, sg(rs), sg(xp), sg(dx), sg(tp)))(grid)
        up = (g[:-1] < 0) & (g[1:] >= 0)
        k = jnp.argmax(up)
        ok = jnp.any(up)

        def bisect(_, ab):
            a, b = ab
            m = 0.5 * (a + b)
            neg = gap(m, sg(rs), sg(xp), sg(dx), sg(tp)) < 0
            return jnp.where(neg, m, a), jnp.where(neg, b, m)

        a, b = jax.lax.fori_loop(0, 60, bisect, (grid[k], grid[k + 1]))
        s = sg(0.5 * (a + b))
        ds = jax.grad(gap)(s, rs, xp, dx, tp)
        return s - gap(s, rs, xp, dx, tp) / ds, ok

    def motor_pq(u):
        rs, xp, dx, tp, h = (jnp.exp(u[i]) for i in range(5))
        s, ok = slip(rs, xp, dx, tp)
        e0 = flux(s, rs, xp, dx, tp, v0)
        z = rs + 1j * xp

        def rhs(t, y, args):
            ed, eq, w = y
            i = (v_in.evaluate(t) - (ed + 1j * eq)) / z
            id_, iq = jnp.real(i), jnp.imag(i)
            ded = -(ed + dx * iq) / tp - wb * (w - 1.0) * eq
            deq = -(eq - dx * id_) / tp + wb * (w - 1.0) * ed
            dw = (ed * id_ + eq * iq - w * w) / (2.0 * h)
            return jnp.stack([ded, deq, dw])

        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(rhs),
            diffrax.Tsit5(),
            t0=ts[0],
            t1=ts[-1],
            dt0=dt0,
            y0=jnp.stack([jnp.real(e0), jnp.imag(e0), 1.0 - s]),
            saveat=diffrax.SaveAt(ts=ts),
            stepsize_controller=diffrax.ClipStepSizeController(
                diffrax.PIDController(rtol=1e-6, atol=1e-9), step_ts=ts
            ),
            max_steps=16 * n + 1000,
            throw=False,
        )
        e = sol.ys[:, 0] + 1j * sol.ys[:, 1]
        i = (v - e) / z
        sm = v * jnp.conj(i)
        good = ok & (sol.result == diffrax.RESULTS.successful)
        return jnp.real(sm), jnp.imag(sm), good

    def model():
        u = numpyro.sample("u", dist.MultivariateNormal(jnp.asarray(mean_u), jnp.asarray(cov_u)))
        b = numpyro.sample("beta", dist.Normal(jnp.zeros(6), sd[:6]))
        pm0 = numpyro.sample("p_m0", dist.HalfNormal(sd[6]))
        tau = numpyro.sample("tau", dist.Gamma(prior.tau_shape, prior.tau_rate).expand([2]))
        pm, qm, good = motor_pq(u)
        numpyro.factor("valid", jnp.where(good, 0.0, -jnp.inf))
        pm_ = jnp.where(good, pm, 1.0)
        mu_p = b[0] * x * x + b[1] * x + b[2] + pm0 * pm_ / pm_[0]
        mu_q = b[3] * x * x + b[4] * x + b[5] + pm0 * (qm - qm[0] * x * x) / pm_[0]
        numpyro.sample("p", dist.Normal(mu_p, 1.0 / jnp.sqrt(tau[0])), obs=p_obs)
        numpyro.sample("q", dist.Normal(mu_q, 1.0 / jnp.sqrt(tau[1])), obs=q_obs)

    return model


def nuts_diffrax(
    ev: Any,
    prior: Any,
    start: dict[str, np.ndarray],
    *,
    warmup: int = 300,
    draws: int = 300,
    chains: int = 2,
    seconds: float = math.inf,
    seed: int = 0,
) -> dict[str, Any]:
    """Run NUTS (chains one after the other) and return its draws and times.

    ``start``: ``u`` (5), ``beta`` (7), ``tau`` (2) of the NLS start (the package's and
    emcee's start too). Each chain warms up ``warmup`` iterations and keeps ``draws``.

    Returns
    -------
    dict
        ``u`` (chain, draw, 5), ``beta`` (chain, draw, 7), ``tau`` (chain, draw, 2),
        ``wall_s`` (all chains, warm-up included, the compilation measured by a
        one-iteration run of its own subtracted), ``compile_s``, ``grads_per_iteration``
        (mean leapfrog steps per kept iteration), ``divergences``.
    """
    import jax
    from numpyro.infer import MCMC, NUTS, init_to_value

    model = _model_fn(ev, prior)
    init = {
        "u": np.asarray(start["u"], float),
        "beta": np.asarray(start["beta"][:6], float),
        "p_m0": float(max(start["beta"][6], 1e-6)),
        "tau": np.asarray(start["tau"], float),
    }
    # Tree depth at most 6 (63 leapfrog steps): each gradient solves the ODE (~0.08 s on
    # the 10 s event), so an unbounded early-adaptation tree would take minutes.
    kernel = NUTS(
        model,
        init_strategy=init_to_value(values=init),
        target_accept_prob=0.8,
        max_tree_depth=6,
    )
    t = time.perf_counter()
    MCMC(kernel, num_warmup=1, num_samples=1, progress_bar=False).run(jax.random.PRNGKey(seed))
    compile_s = time.perf_counter() - t
    m = MCMC(
        kernel,
        num_warmup=warmup,
        num_samples=draws,
        num_chains=chains,
        chain_method="sequential",
        progress_bar=False,
    )
    t = time.perf_counter()
    m.run(jax.random.PRNGKey(seed + 1), extra_fields=("num_steps", "diverging"))
    wall = time.perf_counter() - t - compile_s
    g = m.get_samples(group_by_chain=True)
    extra = m.get_extra_fields(group_by_chain=True)
    beta = np.concatenate([np.asarray(g["beta"]), np.asarray(g["p_m0"])[..., None]], -1)
    return {
        "u": np.asarray(g["u"]),
        "beta": beta,
        "tau": np.asarray(g["tau"]),
        "wall_s": wall,
        "compile_s": compile_s,
        "grads_per_iteration": float(np.mean(np.asarray(extra["num_steps"]))),
        "divergences": int(np.asarray(extra["diverging"]).sum()),
    }
