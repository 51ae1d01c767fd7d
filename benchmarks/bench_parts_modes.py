"""Benchmark: are a ``cmld-lite`` fit's chains in separate modes, or on one ridge (issue 36)?

Reads a fit written by ``loadbayes fit composite ... --netcdf FIT.nc`` and the events it
was fitted to, and prints, per chain:

- the 5 %, 50 % and 95 % quantiles of the slow coordinates (the feeder's X, the motors'
  T', Rs and X', the shares) and the noise precisions' medians;
- the joint log density (the collapsed density with the precisions' gamma prior) at 40
  of the chain's draws: at its own precisions, at every chain's median precisions, and
  maximised over the precisions;
- with ``--nls``, the penalised least squares started from the chain's median: where it
  ends and its density there (the same end from every chain: one optimum).

docs/composite.md, "Why cmld-lite's chains do not mix: one ridge, not modes", has what it
printed on the real record's first fault.

Run: ``python benchmarks/bench_parts_modes.py FIT.nc EVENTS.csv [--f-hz 50] [--nls]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import optimize

from loadbayes.export.partsload import rebuild_model
from loadbayes.fit.composite.design import DesignProblem
from loadbayes.measurements.events import read_events
from loadbayes.posterior import Posterior

SHOW = ("log_x_fd", "log_t_prime_a", "log_t_prime_b", "log_rs_t0_a", "log_x_prime_t0_a",
        "log_rs_t0_b", "lr_m_a", "lr_m_b")  # fmt: skip
SHARES = ("f_m_a", "f_m_b", "f_motors", "f_s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fit")
    ap.add_argument("events", nargs="+")
    ap.add_argument("--f-hz", type=float, default=50.0)
    ap.add_argument("--nls", action="store_true")
    a = ap.parse_args()
    post = Posterior.from_netcdf(a.fit)
    model = rebuild_model(post.settings)
    events = read_events(list(a.events), f_hz=a.f_hz)
    prob = DesignProblem(model, events, model.default_prior(events))
    names = model.theta_names
    theta = np.stack([np.asarray(post.draws[n]) for n in names], -1)  # (chains, draws, d)
    taus = [n for n in ("tau_p", "tau_q", "tau_i2") if n in post.draws]
    tau = np.stack([np.asarray(post.draws[n]) for n in taus], -1)
    a0, b0 = prob.prior.tau_shape, prob.prior.tau_rate

    def joint(u, t):
        s = prob.sums(u)
        if s is None:
            return -np.inf
        return prob.log_collapsed(s, u, t) + float(np.sum((a0 - 1) * np.log(t) - b0 * t))

    def profiled(u):
        x0 = np.log(np.median(tau.reshape(-1, len(taus)), 0))
        r = optimize.minimize(lambda lt: -joint(u, np.exp(lt)), x0, method="Nelder-Mead",
                              options={"xatol": 1e-3, "fatol": 1e-3, "maxiter": 2000})  # fmt: skip
        return -r.fun

    chains = theta.shape[0]
    for k in range(chains):
        cols = []
        for n in (*SHOW, *SHARES):
            if n in post.draws:
                q = np.quantile(np.asarray(post.draws[n])[k], [0.05, 0.5, 0.95])
                cols.append(f"{n} {q[1]:.3f} [{q[0]:.2f}, {q[2]:.2f}]")
        cols += [f"{n} {np.median(tau[k, :, j]):.4g}" for j, n in enumerate(taus)]
        print(f"chain {k}: " + "  ".join(cols))
    rng = np.random.default_rng(0)
    pick = rng.choice(theta.shape[1], 40, replace=False)
    med_tau = np.median(tau, axis=1)
    print("joint log density, median of 40 draws: own tau | at each chain's median tau | "
          "maximised over tau")  # fmt: skip
    for k in range(chains):
        us = [prob.prior.from_theta(theta[k, i]) for i in pick]
        own = np.median([joint(u, tau[k, i]) for u, i in zip(us, pick, strict=True)])
        cross = [np.median([joint(u, med_tau[j]) for u in us]) for j in range(chains)]
        prof = np.median([profiled(u) for u in us])
        print(f"chain {k}: {own:.1f} | " + " ".join(f"{c:.1f}" for c in cross) + f" | {prof:.1f}")
    if a.nls:
        from loadbayes.fit.composite.nls import nls

        for k in range(chains):
            m = prob.prior.from_theta(np.median(theta[k], axis=0))
            r = nls(prob, starts=[m])
            th = prob.theta(r.u)
            ends = " ".join(f"{n}={th[names.index(n)]:.3f}" for n in SHOW)
            print(f"least squares from chain {k}'s median: cost {r.cost:.2f}, joint log "
                  f"density maximised over tau {profiled(r.u):.2f}, {ends}")  # fmt: skip


if __name__ == "__main__":
    main()
