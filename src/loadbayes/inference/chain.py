"""The Metropolis-within-Gibbs driver: one chain's iterations, its kept draws, its statistics.

(Not :mod:`loadbayes.inference.mwg`, which is the power-law model's sampler.)

A sampler in two halves, as numpyro's ``MCMC`` driver with ``HMCGibbs(gibbs_fn=...)``:

- **the model's side** is its conditional updates as one callable,
  ``step(state, rng, iteration) -> state``, where ``state`` is whatever the model carries
  from one iteration to the next (a block move's :class:`~loadbayes.inference.moves.base.
  BlockState` among it), and ``record(state) -> {field: value}``, the values a kept
  iteration stores;
- **the driver**, :class:`Chain`, owns the rest: the iteration count, burn-in and thinning
  (:func:`is_kept`, the one rule), the storage of the named fields into arrays allocated
  before each run (:class:`Field`: shape and dtype; optionally streamed to a sink in
  blocks of rows, so a long chain holds one block), the stop flag
  (:func:`~loadbayes.core.parallel.check_stop` every iteration), a progress callback, the
  sample statistics by name (``stats()``, e.g. acceptance rates) and a chain continued for
  more iterations: a run in rounds gives the draws of one run of the same length (the
  state and the generator carry over);
- a **deadline** (a time budget): past it, the rest of the burn-in is skipped (the moves
  freeze where they are) and the chain stops once it holds ``min_kept`` kept draws. A
  chain that stopped there says so (:attr:`Chain.cut`, the iterations not run); one whose
  deadline never passed runs exactly the draws of a chain without one.

Chains run through :func:`loadbayes.core.parallel.run_chains`, each on its own generator
(:func:`~loadbayes.core.parallel.chain_generators`). The driver draws no random numbers:
every draw is the model's, in its order, so moving a loop onto the driver keeps its draws.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from loadbayes.core.parallel import check_stop

__all__ = ["PROGRESS_EVERY_S", "Chain", "Field", "Sink", "is_kept", "kept_count"]

S = TypeVar("S")

#: Seconds between two progress reports of one chain.
PROGRESS_EVERY_S = 0.2

#: ``sink(start, buffers, count)``: the first ``count`` rows of each streamed field's
#: buffer are the kept draws ``start .. start + count - 1`` of the run.
Sink = Callable[[int, dict[str, np.ndarray], int], None]


def is_kept(iteration: int, burn: int, thin: int) -> bool:
    """Whether an iteration's draws are kept: past the burn-in, at the thinning."""
    return iteration >= burn and (iteration - burn) % thin == 0


def kept_count(start: int, end: int, burn: int, thin: int) -> int:
    """How many of the iterations ``start .. end - 1`` are kept (:func:`is_kept`)."""
    first = burn if start <= burn else burn + -(-(start - burn) // thin) * thin
    return len(range(first, end, thin))


@dataclass(frozen=True)
class Field:
    """A kept quantity: its shape per draw, its dtype, and whether it is streamed."""

    shape: tuple[int, ...] = ()
    dtype: Any = np.float64
    #: Streamed to the chain's sink in blocks of rows (the chain holds one block).
    streamed: bool = False


class Chain(Generic[S]):
    """One chain of a Metropolis-within-Gibbs sampler: the driver of the module notes.

    Parameters
    ----------
    step : callable
        ``step(state, rng, iteration) -> state``: the model's conditional updates, one
        iteration (None for a model that runs only :meth:`run_batched`).
    state : any
        The starting state.
    rng : numpy.random.Generator
        The chain's generator (only ``step`` draws from it).
    fields : mapping
        Name -> :class:`Field` (or a shape tuple) of every kept quantity.
    record : callable
        ``record(state) -> {name: value}`` at a kept iteration, every field (None with
        :meth:`run_batched` only, where the compiled loop stores them).
    burn, thin : int
        Burn-in iterations (counted from the chain's first) and thinning.
    stats : callable, optional
        ``stats() -> {name: value}``: the sample statistics (acceptance and the like).
    stop : threading.Event, optional
        The chains' stop flag.
    progress : callable, optional
        Called with a number of iterations just done, about every ``progress_every``
        seconds and at the end of each run.
    block, sink : optional
        With a sink, the streamed fields are held ``block`` rows at a time and handed to
        ``sink`` (:data:`Sink`) when a block fills and at the end of the run.
    deadline : float, optional
        A :func:`time.perf_counter` time after which the chain ends its burn-in and stops
        (module notes), keeping at least ``min_kept`` draws.
    min_kept : int
        Kept draws a chain stopped by its deadline still makes (a posterior to build).
    """

    def __init__(
        self,
        step: Callable[[S, np.random.Generator, int], S] | None,
        state: S,
        rng: np.random.Generator,
        *,
        fields: Mapping[str, Field | tuple[int, ...]],
        record: Callable[[S], Mapping[str, Any]] | None,
        burn: int,
        thin: int = 1,
        stats: Callable[[], dict[str, Any]] | None = None,
        stop: threading.Event | None = None,
        progress: Callable[[int], None] | None = None,
        progress_every: float = PROGRESS_EVERY_S,
        block: int | None = None,
        sink: Sink | None = None,
        deadline: float | None = None,
        min_kept: int = 0,
    ) -> None:
        self.step, self.state, self.rng = step, state, rng
        self.fields = {k: f if isinstance(f, Field) else Field(tuple(f)) for k, f in fields.items()}
        self.record, self._stats = record, stats
        self.burn, self.thin = int(burn), int(thin)
        self.stop, self.progress, self.progress_every = stop, progress, progress_every
        self.block, self.sink = block, sink
        self.deadline, self.min_kept = deadline, int(min_kept)
        #: Iterations run so far (the next one's number), skipped ones included.
        self.iteration = 0
        #: Iterations the deadline cut: burn-in skipped, or draws not run.
        self.cut = 0
        self._runs: dict[str, list[np.ndarray]] = {k: [] for k in self.fields}

    def run(self, iterations: int) -> None:
        """Run ``iterations`` more iterations, storing the kept ones' fields."""
        start, end = self.iteration, self.iteration + int(iterations)
        burn, thin = self.burn, self.thin
        kept = kept_count(start, end, burn, thin)
        streamed = self.sink is not None
        rows = min(kept, self.block) if streamed and self.block else kept
        bufs = {
            k: np.empty(((rows if streamed and f.streamed else kept), *f.shape), f.dtype)
            for k, f in self.fields.items()
        }
        names = list(bufs)
        live = {k: bufs[k] for k in names if streamed and self.fields[k].streamed}
        step, record, rng, state = self.step, self.record, self.rng, self.state
        assert step is not None and record is not None, "a batched-only chain: run_batched"
        j, it, clock = 0, start, [start, time.perf_counter()]
        while True:
            it, go = self._gate(it, end, clock)
            if not go:
                break
            state = step(state, rng, it)
            if it >= burn and (it - burn) % thin == 0:  # is_kept, inlined
                values = record(state)
                r = j % rows if live else j
                for k in names:
                    bufs[k][r if k in live else j] = values[k]
                j += 1
                if live and (r == rows - 1 or j == kept):
                    self.sink(j - r - 1, live, r + 1)  # type: ignore[misc]
            it += 1
        if live and j < kept and j % rows:  # stopped by the deadline mid-block
            self.sink(j - j % rows, live, j % rows)  # type: ignore[misc]
        if self.progress is not None:
            self.progress(it - clock[0])
        self.state, self.iteration = state, end
        for k in names:
            if k not in live:
                self._runs[k].append(bufs[k][:j] if j < kept else bufs[k])

    def _gate(self, it: int, end: int, clock: list) -> tuple[int, bool]:
        # Before iteration ``it`` of a run ending at ``end``: the stop flag, the deadline
        # (the module notes: the burn-in ends, or the run does), the progress (``clock``:
        # the iteration and time of the last report). Returns the iteration to run next
        # and whether to run it (False: the run ends there).
        while it < end:
            check_stop(self.stop)
            now = time.perf_counter()
            if self.deadline is not None and now > self.deadline:
                after = self._past_deadline(it, end)
                if after is None:
                    return it, False
                if after != it:
                    it = after
                    continue
            if self.progress is not None and now - clock[1] > self.progress_every:
                self.progress(it - clock[0])
                clock[0], clock[1] = it, now
            return it, True
        return it, False

    def _past_deadline(self, it: int, end: int) -> int | None:
        # The deadline rule (the module notes), at iteration ``it`` of a run ending at
        # ``end``: the burn-in ends here (the iteration the draws start at), the chain
        # stops (None: it holds min_kept kept draws), or it goes on (``it``).
        burn, thin = self.burn, self.thin
        if it < burn:
            skip = min(burn, end) - it
            self.cut += skip
            return it + skip
        if kept_count(0, it, burn, thin) >= self.min_kept:
            self.cut += end - it
            return None
        return it

    def run_batched(
        self,
        iterations: int,
        batch: int,
        step_batch: Callable[[S, np.random.Generator, int, int, dict[str, np.ndarray], int], S],
    ) -> None:
        """Run ``iterations`` more iterations, ``batch`` at a time, through a compiled loop.

        For a model whose iterations run in a compiled kernel (a Python call per iteration
        would cost more than the iteration): ``step_batch(state, rng, start, count,
        buffers, kept0) -> state`` runs iterations ``start .. start + count - 1`` and
        writes the fields of each kept one (:func:`is_kept`) into ``buffers[name][k -
        kept0]``, ``k`` its index among the chain's kept draws. The driver still owns the
        arrays (allocated here for the run, every field in memory), the count, the stop
        flag, the progress and the deadline (:meth:`run`'s rule), looked at between
        batches.
        """
        start, end = self.iteration, self.iteration + int(iterations)
        burn, thin = self.burn, self.thin
        kept0 = kept_count(0, start, burn, thin)
        kept = kept_count(start, end, burn, thin)
        bufs = {k: np.empty((kept, *f.shape), f.dtype) for k, f in self.fields.items()}
        state, it, clock = self.state, start, [start, time.perf_counter()]
        while True:
            it, go = self._gate(it, end, clock)
            if not go:
                break
            m = min(batch, end - it)
            state = step_batch(state, self.rng, it, m, bufs, kept0)
            it += m
        if self.progress is not None:
            self.progress(it - clock[0])
        self.state, self.iteration = state, end
        j = kept_count(start, it, burn, thin)
        for k, buf in bufs.items():
            self._runs[k].append(buf[:j] if j < kept else buf)

    def draws(self) -> dict[str, np.ndarray]:
        """Every run's kept draws of each field kept in memory, (kept, *shape)."""
        return {
            k: runs[0] if len(runs) == 1 else np.concatenate(runs, axis=0)
            for k, runs in self._runs.items()
            if runs
        }

    def sample_stats(self) -> dict[str, Any]:
        """The sample statistics by name (empty when the model gave none)."""
        return {} if self._stats is None else dict(self._stats())
