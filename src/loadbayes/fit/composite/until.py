"""Run the composite chains until they converge, or a time budget runs out.

The default composite fit does not stop at a fixed number of iterations: after the
first ``draws`` iterations it checks every reported quantity (R-hat below
:data:`~loadbayes.diagnostics.RHAT_MAX` and bulk ESS at least
:data:`~loadbayes.diagnostics.ESS_MIN`) and, if one falls short, runs every chain on by
the number of iterations the slowest quantity's ESS says it needs (kept draws grow
linearly with ESS), as long as the time budget allows. When the budget runs out first,
the fit says so in a warning, with the R-hat and ESS reached. docs/composite.md, "How
long it runs".

The moves are frozen after burn-in, so the extended chains are ordinary Markov chains
from a fixed kernel: the kept draws of a run extended by ``n`` are those of one run of
``draws + n`` iterations (the same seed, the same draws). Where the budget stops the run
depends on the machine's speed, so an unconverged run's length is not reproducible; a
converged one's is.

The budget holds from the first iteration, not only between rounds: the sampler gets its
deadline (:meth:`UntilConverged.deadline`) and, past it, ends the burn-in and stops the
chains with what they drew (``fit.composite.sampler``). Then the run is shorter than
asked and its draws depend on the machine's load: :meth:`UntilConverged.warning` says so
in words, and the JSON (:meth:`UntilConverged.record`) keeps ``stopped_by_budget`` and the
iterations the budget cut. A run the budget never binds draws what the seed says.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from loadbayes.diagnostics import ESS_MIN, RHAT_MAX

__all__ = ["DEFAULT_MAX_SECONDS", "UntilConverged", "estimate_seconds"]

#: The default time budget of a composite fit's sampling (s): a few minutes.
DEFAULT_MAX_SECONDS = 300.0
#: An extension is at least this share of the kept draws so far (no creeping rounds).
_MIN_GROWTH = 0.25
#: ... and at most this multiple of them: the ESS rate of a short run is uncertain, and
#: mostly low (its first draws still mixing): issue 21's 60/s event read ESS 133 from
#: 12,000 kept, ran on 3.5 times as long and ended at ESS 1,231 (76.7 s); doubling at
#: most, it stopped at 30,000 kept, ESS 452, in 25.8 s.
_MAX_GROWTH = 1.0
#: Aim this far above the ESS target (the rate estimated from a run is noisy).
_MARGIN = 1.15
#: Plan an extension to use at most this share of the time left: the time per iteration
#: is the previous round's, and a busier machine in the next one overran the budget.
_TIME_SHARE = 0.85


#: Iterations of the probe's first round: half of them burn-in, so that its moves adapt
#: as the chains' will (an unadapted walk's proposals leave the support and are rejected
#: without a motor solve, at four times the chains' pace).
PROBE_FIRST = 64
#: Each further round of the probe lasts about this long (s), at least PROBE_ROUND
#: iterations: rounds of a few milliseconds measured the scheduler of a loaded machine.
PROBE_ROUND_S, PROBE_ROUND = 0.25, 24
#: The probe's rounds at most, and its wall time at most (s).
PROBE_ROUNDS, PROBE_SECONDS = 10, 8.0
#: Two successive rounds' paces within this factor of each other: the cost has settled.
PROBE_SETTLED = 1.5


def estimate_seconds(probe: Callable[[int, Callable], object], draws: int, rounds: int) -> float:
    """The wall time of ``rounds`` rounds of chains of ``draws`` iterations, from a probe.

    ``probe(n, extend)`` runs one round of the chains (as many as run at once, on as many
    threads) for ``n`` iterations, then asks ``extend`` for more, as the sampler does.
    The probe runs rounds (:data:`PROBE_ROUND_S` each) until two successive ones go at
    about the same pace (:data:`PROBE_SETTLED`). The settled pace is the chains' cost
    per iteration; what the earlier rounds took beyond it (setting the chains up, their
    first iterations far from the posterior: with bounded shares each took up to a tenth
    of a second in the truncated draw's rejection loop) is paid once per chain. The
    estimate of 12 iterations extrapolated (issue 40) read that start-up as the pace:
    "about 3 h 19 min" for a run of 10 minutes.
    """
    spent: list[tuple[float, int]] = []  # (seconds, iterations) of each round
    t0 = last = time.perf_counter()
    ahead = PROBE_FIRST

    def pace(k: int) -> float:
        return spent[k][0] / spent[k][1]

    def extend(_results) -> int:
        nonlocal last, ahead
        now = time.perf_counter()
        spent.append((now - last, ahead))
        last = now
        settled = len(spent) >= 2 and spent[-1][0] >= 0.8 * PROBE_ROUND_S
        if settled and max(pace(-1), pace(-2)) <= PROBE_SETTLED * min(pace(-1), pace(-2)):
            return 0
        if len(spent) >= PROBE_ROUNDS or now - t0 > PROBE_SECONDS:
            return 0
        if sum(n for _, n in spent) >= draws:  # never a longer throw-away than the run
            return 0
        ahead = max(PROBE_ROUND, math.ceil(PROBE_ROUND_S / max(pace(-1), 1e-9)))
        return ahead

    probe(PROBE_FIRST, extend)
    per = min(pace(-1), pace(-2)) if len(spent) >= 2 else pace(-1)
    start_up = sum(max(s - per * n, 0.0) for s, n in spent)
    return rounds * (start_up + per * draws)


@dataclass
class UntilConverged:
    """The ``extend`` policy of :func:`loadbayes.fit.composite.sampler.sample`.

    Parameters
    ----------
    quantities : callable
        ``quantities(results) -> {name: (chain, draw) array}``: the reported quantities
        of the chains' results so far (the ones judged).
    max_seconds : float
        Budget for the whole sampling, from :meth:`start` (s).
    thin : int
        The run's thinning (iterations per kept draw).
    announce : callable, optional
        ``announce(iterations, seconds, state)``: told before each extension (the
        iterations of all chains, the estimated time, the current R-hat/ESS text).
    """

    quantities: Callable[[Sequence], dict[str, np.ndarray]]
    max_seconds: float = DEFAULT_MAX_SECONDS
    thin: int = 1
    announce: Callable[[int, float, str], None] | None = None
    rounds: list[dict] = field(default_factory=list)
    t_start: float = field(default_factory=time.perf_counter)
    _t_round: float = field(default_factory=time.perf_counter)
    _iterations: int = 0
    stopped_by_budget: bool = False
    #: Iterations per chain the deadline cut inside a round (0: it never bound there),
    #: and the iterations per chain asked (the first round's and every extension's).
    cut_iterations: int = 0
    asked_iterations: int = 0
    #: The names the last check read: every varying reported quantity.
    watched: list[str] = field(default_factory=list)

    def start(self, first_iterations: int) -> None:
        """Start the clock at the first round of ``first_iterations`` per chain."""
        self.t_start = self._t_round = time.perf_counter()
        self._iterations = self.asked_iterations = int(first_iterations)

    def deadline(self) -> float:
        """The :func:`time.perf_counter` time the budget ends (the sampler's deadline)."""
        return self.t_start + self.max_seconds

    def note_cut(self, results: Sequence) -> None:
        """Record whether the deadline cut the chains (their ``cut``)."""
        cut = max(int(getattr(r, "cut", 0)) for r in results)
        if cut:
            self.stopped_by_budget = True
            self.cut_iterations = cut

    def state(self, results: Sequence) -> tuple[float, float, str]:
        """``(max R-hat, min bulk ESS, which quantities fall short)`` of ``results``."""
        from loadbayes.core.convergence import summarize

        named = self.quantities(results)
        names = [n for n, x in named.items() if np.all(np.isfinite(x)) and np.ptp(x) > 0]
        self.watched = names
        if not names:
            return 1.0, math.inf, ""
        s = summarize(np.stack([named[n] for n in names]), tail=False)
        rhat, ess = s["r_hat"], s["ess_bulk"]
        rhat = np.where(np.isfinite(rhat), rhat, 1.0)
        short = [
            f"{n} (R-hat {r:.3f}, ESS {e:.0f})"
            for n, r, e in zip(names, rhat, ess, strict=True)
            if not (r < RHAT_MAX and e >= ESS_MIN)
        ]
        return (
            float(np.max(rhat)),
            float(np.min(ess)),
            ", ".join(short[:4]) + (f" and {len(short) - 4} more" if len(short) > 4 else ""),
        )

    def __call__(self, results: Sequence) -> int:
        """How many more iterations every chain runs (0: converged, or out of time)."""
        now = time.perf_counter()
        round_s = now - self._t_round
        per_iteration = round_s / max(self._iterations, 1)
        rhat, ess, short = self.state(results)
        kept = results[0].theta.shape[0]
        elapsed = now - self.t_start
        self.rounds.append(
            {"kept": int(kept), "r_hat_max": rhat, "ess_bulk_min": ess, "elapsed_s": elapsed}
        )
        if not short:
            return 0
        # Bulk ESS grows about linearly with the kept draws; R-hat short of the mark with
        # enough ESS still needs more draws: half as many again.
        growth = 0.5 if ess >= ESS_MIN else _MARGIN * ESS_MIN / max(ess, 1.0) - 1.0
        growth = min(max(growth, _MIN_GROWTH), _MAX_GROWTH)
        more = math.ceil(kept * growth) * self.thin
        left = self.max_seconds - elapsed
        affordable = int(_TIME_SHARE * left / per_iteration) if per_iteration > 0 else more
        if affordable < max(1, math.ceil(_MIN_GROWTH * kept * self.thin)):
            self.stopped_by_budget = True
            return 0
        more = min(more, affordable)
        if self.announce is not None:
            self.announce(more * len(results), more * per_iteration, short)
        self._t_round, self._iterations = time.perf_counter(), more
        self.asked_iterations += more
        return more

    def warning(self, results: Sequence) -> str | None:
        """The plain-words warning when the budget ended the run unconverged."""
        if not self.stopped_by_budget:
            return None
        _, _, short = self.state(results)
        if self.cut_iterations:
            kept = results[0].theta.shape[0]
            return (
                f"the time budget of {self.max_seconds:g} s bound: the chains stopped "
                f"{self.cut_iterations} iterations short of the {self.asked_iterations} asked "
                f"per chain ({kept} draws kept per chain), so this run "
                "is shorter than asked and its numbers depend on the machine's speed (the "
                "same seed gives other draws on a busier machine)"
                + (
                    f"; {short} fall short of R-hat < {RHAT_MAX} and bulk ESS >= {ESS_MIN}: "
                    "these results are not converged"
                    if short
                    else ""
                )
                + ": give a larger --max-seconds (max_seconds=...) to run it in full"
            )
        return (
            f"the time budget of {self.max_seconds:g} s ran out before the chains converged "
            f"(R-hat < {RHAT_MAX} and bulk ESS >= {ESS_MIN} for every reported quantity): "
            f"{short} fall short; these results are not converged: give a larger "
            "--max-seconds (max_seconds=...), or more --draws"
        )

    def record(self) -> dict:
        """What the JSON's settings keep about the run's length."""
        return {
            "rule": f"R-hat < {RHAT_MAX} and bulk ESS >= {ESS_MIN} for every reported quantity",
            "max_seconds": self.max_seconds,
            "rounds": self.rounds,
            "stopped_by_budget": self.stopped_by_budget,
            # The quantities the rule read (a constant one, as fixed torque shares, is not).
            "watched": list(self.watched),
            # Only when the budget cut a round (a run it never binds keeps its JSON).
            **(
                {
                    "cut_iterations_per_chain": self.cut_iterations,
                    "asked_iterations_per_chain": self.asked_iterations,
                }
                if self.cut_iterations
                else {}
            ),
        }
