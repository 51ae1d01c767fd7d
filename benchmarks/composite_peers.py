"""A peer of the composite fit: NumPyro NUTS with the motor's ODE solved by diffrax.

The same posterior as ``fit_composite(CompositeModel(steps=False, window_s=0), ...)`` on
an event without an angle (and as bench_composite's emcee): the motor in the scale-free
coordinates ``u`` (with ``T0 = 1``: the likelihood does not depend on it), prior
``MultivariateNormal(mean_u, cov_u)`` from ``CompositePrior.scale_free()``; the seven
linear coefficients with their normal priors (``P_m0 = f_m p0`` restricted to be positive:
a half-normal, the same density up to a constant, sampled as ``log P_m0``); ``tau_p,
tau_q`` Gamma(shape, rate) as the package's, sampled as their logs. The voltage is read as
the straight line between samples (``diffrax.LinearInterpolation``); the motor starts
from its steady state at ``V_0`` (the first root of the torque balance up from
``s = 0``, found by bisection and finished by one Newton step so that its gradient is
the implicit function's). The ODE is solved by ``Tsit5`` with a PID controller (rtol
1e-6, atol 1e-9, the tolerance of bench_composite's ``solve_ivp``), stepping on every
sample (the voltage's kinks), all in float64.

NUTS gets the package's own start and scale: the 14 coordinates are whitened by the
Laplace approximation of the package's NLS (its estimate and covariance; ``log tau`` with
variance ``2 / n``), so that the sampler sees ``z = L^-1 (x - x_NLS)``, roughly a standard
normal, and adapts a diagonal mass matrix on top of it.

Only the bench environment has JAX (``make .venv-bench/.installed``: the ``bench``
extra).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

__all__ = ["emcee_log_density", "laplace", "log_density", "nuts_diffrax"]


def emcee_log_density(ev: Any, prior: Any, f_hz: float = 60.0, motor: str = "solve_ivp"):
    """emcee's log-posterior (NumPy) of ``x = (u, beta_1..7, log tau_p, log tau_q)``.

    The density of :func:`log_density` in emcee's coordinates (``P_m0`` itself, held
    positive). ``motor="solve_ivp"``: the motor integrated by ``scipy.integrate.solve_ivp``
    (DOP853, rtol 1e-6, atol 1e-9, adaptive steps) inside each call; ``"kernel"``: by the
    package's compiled RK4 kernel (which agrees with DOP853 to 1e-4 p.u.), cheap enough
    to run emcee long enough to measure its autocorrelation time, a property of the
    posterior and the stretch move, not of the ODE solver.
    """
    from scipy.integrate import solve_ivp

    from loadbayes.fit.composite.problem import theta_of
    from loadbayes.models.composite import design, motor_response
    from loadbayes.models.motor import MotorParams, currents, derivatives, power
    from loadbayes.models.motor import steady_state as ss

    mean_u, cov_u, _, _ = prior.scale_free()
    prec_u = np.linalg.inv(cov_u)
    sd_u = np.sqrt(np.diag(cov_u))

    def by_solve_ivp(u):
        rs, xp, dx, tp, h, t0 = np.exp(theta_of(u, 0.0))
        x = xp + dx
        xm = math.sqrt(x * dx)
        m = MotorParams(rs=rs, xs=x - xm, xm=xm, rr=x / (2 * math.pi * f_hz * tp), xr=x - xm,
                        h_s=h, f_hz=f_hz)  # fmt: skip
        try:
            op = ss(m, v_pu=ev.v0, t0=t0)
        except ValueError:
            return None

        def rhs(tt, y):
            return derivatives(y, np.interp(tt, ev.t, ev.v), 0.0, m, t0=t0)

        # Adaptive steps (no max_step): the cheapest honest use of solve_ivp here.
        sol = solve_ivp(rhs, (ev.t[0], ev.t[-1]), op.state, "DOP853", ev.t, rtol=1e-6,
                        atol=1e-9)  # fmt: skip
        if not sol.success:
            return None
        i_d, iq = currents(ev.v, 0.0, sol.y[0], sol.y[1], m)
        return power(ev.v, 0.0, i_d, iq)

    def by_kernel(u):
        return motor_response(ev, theta_of(u, 0.0), f_hz=f_hz)

    motor_pq = by_solve_ivp if motor == "solve_ivp" else by_kernel

    def logp(x):
        u, beta, ltau = x[:5], x[5:12], x[12:]
        if beta[6] <= 0 or np.any(np.abs(u - mean_u) > 8 * sd_u):
            return -np.inf
        r = motor_pq(u)
        if r is None:
            return -np.inf
        zp, zq = design(ev, *r)
        tau = np.exp(ltau)
        out = -0.5 * (u - mean_u) @ prec_u @ (u - mean_u)
        out += -0.5 * float(np.sum((beta / prior.beta_sd) ** 2))
        for g, (z, y) in enumerate(((zp, ev.p), (zq, ev.q))):
            res = y - z @ beta
            out += 0.5 * y.size * ltau[g] - 0.5 * tau[g] * float(res @ res)
        # Gamma(shape, rate) on tau, written on log tau (Jacobian tau).
        out += float(np.sum(prior.tau_shape * ltau - prior.tau_rate * tau))
        return out

    return logp


def log_density(ev: Any, prior: Any, f_hz: float = 60.0):
    """The joint log-posterior (JAX) of ``x = (u, beta_1..6, log P_m0, log tau_p,
    log tau_q)``, up to a constant; -inf where the motor has no steady state."""
    import diffrax
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    mean_u, cov_u, _, _ = prior.scale_free()
    wb = 2.0 * math.pi * f_hz
    ts = jnp.asarray(ev.t, dtype=jnp.float64)
    v = jnp.asarray(ev.v, dtype=jnp.float64)
    xv = v / ev.v0
    x2 = xv * xv
    mu_u = jnp.asarray(mean_u)
    prec_u = jnp.asarray(np.linalg.inv(cov_u))
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

    def motor_pq(u, adjoint):
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
            adjoint=adjoint,
        )
        e = sol.ys[:, 0] + 1j * sol.ys[:, 1]
        i = (v - e) / z
        sm = v * jnp.conj(i)
        good = ok & (sol.result == diffrax.RESULTS.successful)
        return jnp.real(sm), jnp.imag(sm), jnp.where(good, 1.0, 0.0)

    # The gradient by forward mode: five tangents (u) pushed through one solve each
    # (vmapped), then the Jacobian-vector products of the cotangents. Reverse mode
    # through the solver's checkpoints cost 10x a density evaluation on the 10 s event
    # (54 ms against 5 ms); this is NUTS's cheapest gradient.
    @jax.custom_vjp
    def motor(u):
        return motor_pq(u, diffrax.ForwardMode())

    def motor_fwd(u):
        def one(t):
            return jax.jvp(lambda w: motor_pq(w, diffrax.ForwardMode()), (u,), (t,))

        prim, tang = jax.vmap(one)(jnp.eye(5))
        return (prim[0][0], prim[1][0], prim[2][0]), (tang[0], tang[1])

    def motor_bwd(res, ct):
        jp, jq = res
        return (jp @ ct[0] + jq @ ct[1],)

    motor.defvjp(motor_fwd, motor_bwd)

    def logp(x):
        u, b, log_pm0, ltau = x[:5], x[5:11], x[11], x[12:14]
        pm0, tau = jnp.exp(log_pm0), jnp.exp(ltau)
        d = u - mu_u
        out = -0.5 * d @ prec_u @ d
        out += -0.5 * jnp.sum((b / sd[:6]) ** 2)
        out += -0.5 * (pm0 / sd[6]) ** 2 + log_pm0  # half-normal, Jacobian of exp
        out += jnp.sum(prior.tau_shape * ltau - prior.tau_rate * tau)  # Gamma, Jacobian
        pm, qm, good = motor(u)
        good = good > 0.5
        pm_ = jnp.where(good, pm, 1.0)
        qm_ = jnp.where(good, qm, 0.0)
        mu_p = b[0] * x2 + b[1] * xv + b[2] + pm0 * pm_ / pm_[0]
        mu_q = b[3] * x2 + b[4] * xv + b[5] + pm0 * (qm_ - qm_[0] * x2) / pm_[0]
        for g, (y, mu) in enumerate(((p_obs, mu_p), (q_obs, mu_q))):
            r = y - mu
            out += 0.5 * n * ltau[g] - 0.5 * tau[g] * (r @ r)
        return jnp.where(good, out, -jnp.inf)

    return logp


def laplace(start: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Centre and covariance of the 14 coordinates from the package's NLS result.

    ``start``: ``NLSResult`` of one event with ``steps=False`` (``u`` 5, ``betas[0]`` 7,
    ``cov`` over both, ``sigma`` 2); ``n`` samples per channel. ``log P_m0``'s row and
    column are the NLS's scaled by ``1 / P_m0`` (the delta method), ``log tau`` gets
    variance ``2 / n`` (the Gamma-Normal posterior's), independent of the rest.
    """
    beta = np.asarray(start.betas[0], float)
    pm0 = max(float(beta[6]), 1e-6)
    centre = np.concatenate(
        [start.u[:5], beta[:6], [math.log(pm0)], np.log(1.0 / np.asarray(start.sigma) ** 2)]
    )
    jac = np.eye(12)
    jac[11, 11] = 1.0 / pm0
    cov = np.zeros((14, 14))
    cov[:12, :12] = jac @ np.asarray(start.cov)[:12, :12] @ jac.T
    cov[12:, 12:] = np.eye(2) * 2.0 / n
    return centre, cov


def nuts_diffrax(
    ev: Any,
    prior: Any,
    start: Any,
    *,
    f_hz: float = 60.0,
    warmup: int = 1000,
    draws: int = 1000,
    chains: int = 2,
    target_accept: float = 0.9,
    max_tree_depth: int = 10,
    seed: int = 0,
) -> dict[str, Any]:
    """Run NUTS on the whitened posterior and return its draws and times.

    ``start``: the package's ``NLSResult`` on this event (``steps=False``), whose
    Laplace approximation whitens the coordinates (:func:`laplace`); every chain starts
    at its centre, jittered by 0.1 of its scale. Each chain warms up ``warmup``
    iterations (step size and a diagonal mass matrix on the whitened coordinates) and
    keeps ``draws``; chains run in parallel when JAX has a device per chain (the CPU
    split by ``XLA_FLAGS=--xla_force_host_platform_device_count``), else one after the
    other.

    Returns
    -------
    dict
        ``u`` (chain, draw, 5), ``beta`` (chain, draw, 7), ``tau`` (chain, draw, 2),
        ``wall_s`` and ``cpu_s`` (all chains, warm-up included, the compilation measured
        by a one-iteration run of its own subtracted), ``warmup_wall_s``,
        ``sampling_wall_s`` and ``sampling_cpu_s`` (the kept draws' phase alone),
        ``compile_s``,
        ``grads_per_iteration`` (mean leapfrog steps per kept iteration), ``divergences``,
        ``chain_method``, ``accept_prob`` (mean over kept iterations), ``step_size``.
    """
    import jax
    import jax.numpy as jnp
    from numpyro.infer import MCMC, NUTS

    logp = log_density(ev, prior, f_hz)
    centre, cov = laplace(start, ev.n)
    root = np.linalg.cholesky(cov)
    c_j, l_j = jnp.asarray(centre), jnp.asarray(root)

    def potential(z):
        return -logp(c_j + l_j @ z)

    kernel = NUTS(
        potential_fn=potential,
        target_accept_prob=target_accept,
        max_tree_depth=max_tree_depth,
    )
    rng = np.random.default_rng(seed)
    z0 = jnp.asarray(0.1 * rng.standard_normal((chains, 14)))
    method = "parallel" if jax.local_device_count() >= chains else "sequential"
    fields = ("num_steps", "diverging", "accept_prob", "adapt_state.step_size")

    def mcmc(n_warmup, n_draws):
        return MCMC(kernel, num_warmup=n_warmup, num_samples=n_draws, num_chains=chains,
                    chain_method=method, progress_bar=False)  # fmt: skip

    def phases(m, key, say=False):
        # Warm-up and sampling timed apart (wall and this process's CPU seconds).
        t, c = time.perf_counter(), time.process_time()
        m.warmup(key, init_params=z0, extra_fields=fields, collect_warmup=say)
        jax.block_until_ready(m.post_warmup_state)  # JAX returns before it has computed
        t1, c1 = time.perf_counter(), time.process_time()
        if say:  # the warm-up's cost per gradient, before the draws (a run cut short)
            grads = int(np.asarray(m.get_extra_fields()["num_steps"]).sum())
            print(f"NUTS warm-up: {m.num_warmup} iterations x {chains} chains, {grads} "
                  f"gradients, {t1 - t:.1f} s wall, {c1 - c:.1f} CPU s", flush=True)  # fmt: skip
        m.run(m.post_warmup_state.rng_key, extra_fields=fields)
        # Waited for as the warm-up is: MCMC.run returned before computing its draws, and
        # the draws' phase came out at 1.3 CPU s for 26,000 gradients (0 s, less the
        # one-iteration run's compilation, on the GridDyn event).
        jax.block_until_ready(m.last_state)
        t2, c2 = time.perf_counter(), time.process_time()
        return np.array([t1 - t, c1 - c, t2 - t1, c2 - c1])

    # JAX compiles each phase once per MCMC object: a one-iteration run of each phase
    # measures that, and it is subtracted from the timed run's phases (the compilation
    # could hit a cache the second time: then NUTS is charged less than it spent).
    comp = phases(mcmc(1, 1), jax.random.PRNGKey(seed))
    m = mcmc(warmup, draws)
    warm_s, warm_cpu, samp_s, samp_cpu = np.maximum(
        phases(m, jax.random.PRNGKey(seed + 1), say=True) - comp, 0.0
    )
    z = np.asarray(m.get_samples(group_by_chain=True))  # (chain, draw, 14)
    x = centre + z @ root.T
    extra = m.get_extra_fields(group_by_chain=True)
    beta = np.concatenate([x[..., 5:11], np.exp(x[..., 11:12])], -1)
    return {
        "u": x[..., :5],
        "beta": beta,
        "tau": np.exp(x[..., 12:14]),
        "wall_s": float(warm_s + samp_s),
        "cpu_s": float(warm_cpu + samp_cpu),
        "warmup_wall_s": float(warm_s),
        "sampling_wall_s": float(samp_s),
        "sampling_cpu_s": float(samp_cpu),
        "compile_s": float(comp[0] + comp[2]),
        "grads_per_iteration": float(np.mean(np.asarray(extra["num_steps"]))),
        "divergences": int(np.asarray(extra["diverging"]).sum()),
        "accept_prob": float(np.mean(np.asarray(extra["accept_prob"]))),
        "step_size": float(np.mean(np.asarray(extra["adapt_state.step_size"]))),
        "chain_method": method,
    }
