"""Geweke's "getting it right" test of a Gibbs kernel (Geweke, 2004).

Two simulators of the joint distribution ``p(theta, y)`` of parameters and data:

marginal-conditional
    independent draws: ``theta ~ p(theta)``, then ``y ~ p(y | theta)``;
successive-conditional
    a chain that alternates one sweep of the kernel under test, ``theta' ~ K(. | theta,
    y)``, with a fresh data set ``y' ~ p(y | theta')``.

If the kernel leaves ``p(theta | y)`` invariant, the chain's stationary distribution is
the joint, so every test function ``g(theta, y)`` has the same mean under both. A
wrong conditional (say a sign in one term) moves the successive-conditional chain off the
joint, which the comparison of means detects even when each posterior looks plausible.

The mean of the successive-conditional chain is autocorrelated: its standard error comes
from the effective sample size (ArviZ ``mcse``, several chains). Each test function gives
a z-score; the check fails when any ``|z|`` exceeds the two-sided Bonferroni threshold for
the declared false-alarm rate.

Each recorded pair is ``(theta_{t+1}, y_t)``: the parameters just drawn by the kernel from
the data they were drawn given. Under a correct kernel that pair is a draw from the joint,
and cross moments such as ``a_j (Z'r)_j`` test that the kernel responds to the data the
right way (a pair ``(theta_t, y_t)`` would only test the marginal of ``theta``).

The sampler reads data only through ``Z'Z, Z'r, r'r, n``: with the design ``Z`` fixed,
a fresh data set is a fresh ``r``, and each step costs one kernel sweep.

References
----------
Geweke (2004), "Getting it right: joint distribution tests of posterior simulators",
JASA 99(467), 799-804.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import RegressionStats

__all__ = [
    "GEWEKE_PRIOR",
    "GewekeResult",
    "Kernel",
    "gibbs_kernel",
    "joint_functions",
    "run_geweke",
    "sweep_from",
    "zip_design",
]

#: ``kernel(stats, prior, coef, tau, seed) -> (coef, tau)``: one sweep from a state.
Kernel = Callable[[RegressionStats, BlockPrior, np.ndarray, float, int], tuple[np.ndarray, float]]


# ------------------------------------------------------------- one sweep from a state
def _has_state_init() -> bool:
    """Whether ``sample_block`` takes ``init=(coef, tau)`` (the hook this module needs)."""
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.inference.gibbs import sample_block

    st = RegressionStats(np.eye(1), np.zeros(1), 1.0, 3)
    try:
        init: Any = (np.zeros(1), 1.0)
        one = SamplerSettings(chains=1, draws=1, burn=0, init=init, seed=0)
        sample_block(st, BlockPrior.weak(1), settings=one)
    except (TypeError, ValueError):
        return False
    return True


class _StartFrom:
    """Until ``sample_block`` takes ``init=(coef, tau)``: start its chains at a set state.

    While installed (a ``with`` block), ``loadbayes.inference.gibbs._initial``, which
    turns ``init`` into each chain's starting ``(tau, coef)``, returns the state held
    here instead. Not thread-safe: nothing else may sample in this process meanwhile.
    """

    def __init__(self) -> None:
        self.coef = np.zeros(0)
        self.tau = 1.0

    @contextlib.contextmanager
    def installed(self) -> Iterator[_StartFrom]:
        global _ACTIVE
        from loadbayes.inference import gibbs

        original = gibbs._initial

        def initial(stats, prior, gen, init, b_ls, ssr_min):  # the signature of _initial
            return float(self.tau), np.array(self.coef, dtype=float)

        gibbs._initial = initial
        _ACTIVE = self
        try:
            yield self
        finally:
            gibbs._initial = original
            _ACTIVE = None


_ACTIVE: _StartFrom | None = None


@contextlib.contextmanager
def _state_init() -> Iterator[None]:
    """Make :func:`sweep_from` work: nothing if the hook exists, else :class:`_StartFrom`."""
    if _has_state_init():
        yield
    else:
        with _StartFrom().installed():
            yield


def sweep_from(
    stats: RegressionStats,
    prior: BlockPrior,
    coef: np.ndarray,
    tau: float,
    *,
    scheme: str,
    seed: int,
) -> tuple[np.ndarray, float]:
    """One sweep of ``sample_block``'s kernel from ``(coef, tau)``: ``draws=1, burn=0``.

    Passes ``init=(coef, tau)``; inside :func:`run_geweke` on a ``sample_block`` that
    does not take it yet, the stand-in :class:`_StartFrom` supplies the state instead.
    """
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.inference.gibbs import sample_block

    init: Any = (coef, tau)
    if _ACTIVE is not None:
        _ACTIVE.coef, _ACTIVE.tau, init = coef, tau, "prior"
    one = SamplerSettings(chains=1, draws=1, burn=0, init=init, seed=seed)
    res = sample_block(stats, prior, scheme=scheme, settings=one)
    return res.coef[0, 0].copy(), float(res.tau[0, 0])


def gibbs_kernel(scheme: str) -> Kernel:
    """The kernel of :func:`~loadbayes.inference.gibbs.sample_block` for ``scheme``."""

    def kernel(stats, prior, coef, tau, seed):
        return sweep_from(stats, prior, coef, tau, scheme=scheme, seed=seed)

    kernel.__name__ = f"gibbs_{scheme}"
    return kernel


# ------------------------------------------------------------------ the ZIP problem
#: Prior of the Geweke runs: a1 ~ N(0.4, 0.5^2), a2 ~ N(0.3, 0.5^2), tau ~ Gamma(4, 1)
#: (noise sd near 0.5). With 20 samples the data carry about as much information as the
#: prior, so the successive-conditional chain moves over the whole prior quickly.
GEWEKE_PRIOR = BlockPrior(mean=[0.4, 0.3], precision=[4.0, 4.0], shape=4.0, rate=1.0)


def zip_design(n: int = 20, band: tuple[float, float] = (0.4, 1.6), seed: int = 3) -> np.ndarray:
    """A fixed ZIP design ``Z = [x^2 - 1, x - 1]`` on ``n`` voltages uniform on ``band``."""
    x = np.sort(np.random.default_rng(seed).uniform(band[0], band[1], n))
    return np.column_stack([(x - 1.0) * (x + 1.0), x - 1.0])


# ------------------------------------------------------------------ test functions
def joint_functions(
    coef: np.ndarray, tau: np.ndarray, ztr: np.ndarray, rtr: np.ndarray, ztz: np.ndarray, n: int
) -> dict[str, np.ndarray]:
    """The compared functions ``g(theta, y)``, vectorised over the first axis.

    First and second moments of the coefficients and of ``tau``, and three that join the
    parameters to the data: ``a_j (Z'r)_j / n`` and ``tau SSR(a) / n`` (whose mean is 1
    under the joint).
    """
    k = coef.shape[1]
    out: dict[str, np.ndarray] = {}
    for j in range(k):
        out[f"a{j + 1}"] = coef[:, j]
        out[f"a{j + 1}^2"] = coef[:, j] ** 2
    for i in range(k):
        for j in range(i + 1, k):
            out[f"a{i + 1}*a{j + 1}"] = coef[:, i] * coef[:, j]
    out["tau"] = tau
    out["tau^2"] = tau**2
    out["log tau"] = np.log(tau)
    for j in range(k):
        out[f"a{j + 1}*(Z'r){j + 1}/n"] = coef[:, j] * ztr[:, j] / n
    quad = np.einsum("ij,jk,ik->i", coef, ztz, coef)
    out["tau*SSR/n"] = tau * (rtr - 2 * np.einsum("ij,ij->i", coef, ztr) + quad) / n
    return out


# ------------------------------------------------------------------------ the test
@dataclass
class GewekeResult:
    """Means of each test function under both simulators, and their z-scores.

    Attributes
    ----------
    name : str
        Kernel tested.
    table : dict
        Per function: ``marginal``, ``successive`` (means), ``se`` (standard error of
        their difference) and ``z``.
    steps, chains, marginal_draws : int
        Sizes of the two simulations.
    alpha : float
        Declared false-alarm rate of the whole check (Bonferroni over the functions).
    seconds : float
        Wall time.
    """

    name: str
    table: dict[str, dict[str, float]]
    steps: int
    chains: int
    marginal_draws: int
    alpha: float
    seconds: float

    @property
    def threshold(self) -> float:
        """Two-sided Bonferroni threshold on ``|z|``."""
        return float(stats.norm.isf(self.alpha / (2 * len(self.table))))

    @property
    def max_abs_z(self) -> float:
        """Largest ``|z|`` over the test functions."""
        return max(abs(r["z"]) for r in self.table.values())

    def passes(self) -> bool:
        """True when no ``|z|`` exceeds :attr:`threshold`."""
        return self.max_abs_z <= self.threshold

    def to_dict(self) -> dict[str, Any]:
        """Plain summary for the validation report."""
        return {
            "name": self.name,
            "steps_per_chain": self.steps,
            "chains": self.chains,
            "marginal_draws": self.marginal_draws,
            "alpha": self.alpha,
            "threshold_abs_z": self.threshold,
            "max_abs_z": self.max_abs_z,
            "passes": self.passes(),
            "seconds": round(self.seconds, 2),
            "functions": self.table,
        }


def _draw_prior(prior: BlockPrior, rng: np.random.Generator, size: int):
    tau = rng.gamma(prior.shape, 1.0 / prior.rate, size)
    chol = np.linalg.cholesky(np.linalg.inv(prior.precision))
    z = rng.standard_normal((size, prior.k)) @ chol.T
    scale = 1.0 / np.sqrt(tau)[:, None] if prior.conjugate else 1.0
    return prior.mean + z * scale, tau


def _data(z: np.ndarray, coef: np.ndarray, tau: np.ndarray, rng: np.random.Generator):
    """Fresh data given each row of ``coef``: ``(Z'r, r'r)`` per row."""
    r = coef @ z.T + rng.standard_normal((coef.shape[0], z.shape[0])) / np.sqrt(tau)[:, None]
    return r @ z, np.einsum("ij,ij->i", r, r)


def run_geweke(
    kernel: Kernel,
    prior: BlockPrior,
    design: np.ndarray,
    *,
    steps: int,
    chains: int = 4,
    marginal_draws: int = 100_000,
    seed: int,
    alpha: float = 1e-3,
    name: str | None = None,
) -> GewekeResult:
    """Compare the marginal-conditional and successive-conditional simulators.

    Parameters
    ----------
    kernel : Kernel
        One sweep ``(stats, prior, coef, tau, seed) -> (coef, tau)``, e.g.
        :func:`gibbs_kernel` or a deliberately broken wrapper of it.
    prior : BlockPrior
        Proper prior of the block (it is simulated from).
    design : ndarray, shape (n, k)
        Fixed design ``Z``; the data are ``r = Z a + e``, ``e ~ N(0, 1/tau)``.
    steps : int
        Successive-conditional steps per chain.
    chains : int
        Independent successive-conditional chains (each started from the prior).
    marginal_draws : int
        Independent draws of the marginal-conditional simulator.
    seed : int
        Root seed.
    alpha : float
        False-alarm rate of the whole check for a correct kernel.
    name : str, optional
        Label (default: the kernel's scheme).

    Returns
    -------
    GewekeResult
    """
    t0 = time.perf_counter()
    z = np.asarray(design, dtype=float)
    n, k = z.shape
    ztz = z.T @ z
    s_mc, s_sc = np.random.SeedSequence(seed).spawn(2)

    rng = np.random.default_rng(s_mc)
    coef, tau = _draw_prior(prior, rng, marginal_draws)
    ztr, rtr = _data(z, coef, tau, rng)
    g_mc = joint_functions(coef, tau, ztr, rtr, ztz, n)

    rec_coef = np.empty((chains, steps, k))
    rec_tau = np.empty((chains, steps))
    rec_ztr = np.empty((chains, steps, k))
    rec_rtr = np.empty((chains, steps))
    with _state_init():
        for c, s_chain in enumerate(s_sc.spawn(chains)):
            rng = np.random.default_rng(s_chain)
            seeds = rng.integers(0, 2**63, steps)
            b, t = _draw_prior(prior, rng, 1)
            b, t = b[0], float(t[0])
            for i in range(steps):
                d_ztr, d_rtr = _data(z, b[None, :], np.array([t]), rng)
                st = RegressionStats(ztz, d_ztr[0], float(d_rtr[0]), n)
                b, t = kernel(st, prior, b, t, int(seeds[i]))
                rec_coef[c, i], rec_tau[c, i] = b, t
                rec_ztr[c, i], rec_rtr[c, i] = d_ztr[0], d_rtr[0]

    flat = chains * steps
    g_sc = joint_functions(
        rec_coef.reshape(flat, k),
        rec_tau.reshape(flat),
        rec_ztr.reshape(flat, k),
        rec_rtr.reshape(flat),
        ztz,
        n,
    )

    from loadbayes.posterior import import_arviz

    az = import_arviz()
    table = {}
    for key, mc in g_mc.items():
        sc = g_sc[key].reshape(chains, steps)
        se_sc = float(np.asarray(az.mcse(sc, method="mean")).reshape(-1)[0])
        se = float(np.sqrt(se_sc**2 + mc.var(ddof=1) / mc.size))
        diff = float(sc.mean() - mc.mean())
        table[key] = {
            "marginal": float(mc.mean()),
            "successive": float(sc.mean()),
            "se": se,
            "z": diff / se if se > 0 else (0.0 if diff == 0 else np.inf),
        }
    return GewekeResult(
        name or getattr(kernel, "__name__", "kernel"),
        table,
        steps,
        chains,
        marginal_draws,
        alpha,
        time.perf_counter() - t0,
    )
