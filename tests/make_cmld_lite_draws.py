"""Make ``tests/data/cmld_lite_draws.nc`` (and ``--short``: ``cmld_lite_short_draws.nc``).

``cmld_lite_draws.nc`` is the predict tests' frozen cmld-lite posterior.

The data are the package's not: one 15 % sag from the tests' SciPy feeder simulator
(``feeder_generator.simulate``: a ZIP load and one motor behind a feeder, 50 Hz), 0.5 %
noise (seed 3). The fit is ``cmld-lite`` at 50 Hz, one chain of 6,000 iterations (the
first 4,000 burn-in, seed 5), its 2,000 draws thinned to every 13th: 154 draws.

Why frozen: the predict tests (``tests/integration/test_predict_collapse.py``,
``test_predict_chains.py``, ``test_predict.py``, ``test_export_planning.py``) ask what
``predict`` does with a fit of parts, not what the fit is. They used to fit in the
session (one chain of 300), and a short chain's path follows the last bits of the
machine's arithmetic: on a machine without AVX-512 its draws were other draws, 40 % of
them had no operating point once the tests made the feeder six times bigger, and five
tests that counted collapses failed there and passed on the machine they were written on.
Frozen draws are the same everywhere; ``predict`` is deterministic given them.

``cmld_lite_short_draws.nc`` is the session fit the tests used before: one chain of
300 iterations (150 burn-in, the same data and seeds), as a machine without AVX-512
fitted it. Its chain had not left the wild region of the static Q (shares of
``x^2, x, 1`` like -9.4, 20.1, -9.7), where the feeder loop's sweeps fail to settle at
deep sags: ``tests/integration/test_predict_march.py`` needs such draws for the march.

Run from the repository's root: ``.venv/bin/python tests/make_cmld_lite_draws.py
[--short]`` (about 2 min; 1 min). The tests' numbers were measured on the files as
committed; another machine's arithmetic makes other short-chain draws.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "data" / "cmld_lite_draws.nc"
OUT_SHORT = HERE / "data" / "cmld_lite_short_draws.nc"
THIN = 13


def main(short: bool = False) -> None:
    sys.path.insert(0, str(HERE))
    from feeder_generator import simulate
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.measurements.record import EventRecord
    from loadbayes.models.dynamic import dynamic_model

    rng = np.random.default_rng(3)
    t, v, d, p, q, _ = simulate(sag=0.15)
    noise = 0.005 * np.hypot(p[0], q[0])
    ev = EventRecord(t, v, p + rng.normal(0, noise, t.size), q + rng.normal(0, noise, t.size),
                     d, "sag 0.15")  # fmt: skip
    if short:
        sampler, thin, out = SamplerSettings(draws=300, burn=150, chains=1, seed=5), 1, OUT_SHORT
    else:
        sampler, thin, out = SamplerSettings(draws=6000, burn=4000, chains=1, seed=5), THIN, OUT
    post = fit_composite(dynamic_model("cmld-lite", f_hz=50.0), [ev], sampler=sampler).posterior
    for name, x in list(post.draws.items()):
        post.draws[name] = np.asarray(x)[:, ::thin].copy()
    post.to_netcdf(out, force=True)
    print(f"{out}: {np.asarray(post.draws['log_x_fd']).shape[1]} draws")


if __name__ == "__main__":
    main(short="--short" in sys.argv[1:])
