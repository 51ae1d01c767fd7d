"""``cmld-lite`` on GridDyn's WECC composite load (CMLDBLU1): the shares two faults show.

Issue 36, Checks: "Fit the shallow and medium events: the total motor share and the
static shares are covered by their 95% intervals, and every share is physical." The
data are GridDyn's (loadbayes.cases.griddyn, the harness's default load: motors A 0.15 and B
0.10, motor D 0.15, electronics 0.15, static 0.45, behind a transformer with a fixed
1.05 tap and a feeder): the 13% and 25% sags at the measured bus, one-cycle window means
at 60/s, 0.5% noise on P and Q (noise seed 0), from 0.1 s before the fault to 0.4 s after
it (30 rows each; the fault lasts 0.1 s), fitted jointly by ``cmld-lite`` (f 60 Hz,
``window_s`` 1/60) at 4000 draws, 2000 burn-in, 2 chains, seed 0. No loadbayes code makes
the data. Skips (saying why) where GridDyn is not installed.

**What is compared.** GridDyn's fractions are of the CMLD's P at its load end (behind
the transformer and the feeder: 0.955 p.u. before the fault, against 0.990 at the
measured bus; ``truth['event']['feeder_end']`` is the harness's record of that end, and
the test checks that its first P is the composite's own initial P). ``cmld-lite``'s
shares are of its load bus's P, the bus behind its series impedance, i.e. the same end:
``f_motors`` (motors A and B together) is compared with ``three_phase_motor_share``
(0.25) and ``f_s`` with ``fractions['static']`` (0.45), as they are. (On the measured
bus's P the motors' share would be 0.25 x 0.955 / 0.990 = 0.241.)

**Measured** (this seed, with the sampler's share-only steps, ``fit/composite/shares.py``,
and each motor's X' held in 0.04-0.65 on its own base, ``part_priors.X_PRIME_RANGE``;
re-measured on the commit that re-applied the limits, main having moved since they were
first measured (the motor's turning start among other changes): R-hat 1.82 for
``f_motors``, 1.35 for ``f_s``, 1.06 for ``f_el``, 1.83 for ``f_m_b``; the motors' X'
and the feeder's at R-hat 2.0-2.1, so the chains have not converged at these draws, and
the fit says so in its warnings):

========== ======= ================ ===================================
quantity   truth   95% interval     result
========== ======= ================ ===================================
f_motors   0.25    [0.214, 0.293]   covered (asserted)
f_s        0.45    [0.223, 0.615]   covered (asserted)
f_m_a      0.15    [0.131, 0.205]   covered (not asserted)
f_m_b      0.10    [0.026, 0.126]   covered (not asserted)
f_d        0.15    [0.097, 0.439]   covered (not asserted)
f_el       0.15    [0.001, 0.364]   covered (not asserted)
x_fd       0.101   [0.054, 0.172]   covered (load base; not asserted)
========== ======= ================ ===================================

Without the X' limits (the same seed and commit otherwise): ``f_motors`` [0.214, 0.267]
(R-hat 1.39), ``f_s`` [0.253, 0.621] (1.01), ``f_m_a`` [0.132, 0.206], ``f_m_b`` [0.026,
0.093] (missed), ``f_d`` [0.080, 0.306], ``f_el`` [0.001, 0.380], ``x_fd`` [0.103, 0.172]
(missed, by 0.002), motor A's X' [0.036, 0.129] (below the limit) at R-hat 2.57. (At
the commit that first applied the limits it was the other way: ``x_fd`` [0.078, 0.167]
covered without them, [0.066, 0.074] missed with them.) The missing tap (below) makes
the fit's ``x_fd`` no reading of the true impedance either way (docs/composite.md, "X'
held in its published range").

Without the share-only steps (``share_steps=0``, the draws of before, measured on the
same commit) ``f_s`` was [0.267, 0.426], missed (the assertion was a strict xfail), at
R-hat 1.94 (``f_d`` 2.22, ``f_el`` 1.55, ``a3`` 1.84): the split of the constant power
was a ridge of the shares that the joint move crawled along (an earlier commit read
``f_s`` [0.229, 0.405], ``f_d`` [0.320, 0.434]). The numbers below, from before those
steps, say how far the data and the priors place that split.

Over ten runs (noise seeds 0-7, sampler seeds 0-4, 4000 draws) ``f_motors`` was covered
10 times and ``f_s`` 6 (one of them within 0.01 of its end); ``f_d`` 7 (the three misses
above the truth, all with noise seed 0) and ``f_el`` 4 (the six misses below it). The
non-motor P is found (``f_s + f_d + f_el`` about 0.74 against 0.75), its split is not.
What was measured about why (noise and sampler seed 0, 4000 draws):

- These sags do not separate constant-power loads: motor D above its stall, the
  electronics above Vd1 and the static part's constant-P share (``f_s a3``) all draw
  close to constant P. The data fix the static Z and I shares (``f_s a1``, ``f_s a2``)
  and the constant-P total; along what is left, the uniform Dirichlet priors of the
  shares, conditioned on those three (a Monte Carlo of the priors), put ``f_s`` at
  0.35 [0.27, 0.63], its floor being the Z and I shares (0.27): the prior alone pulls it
  low, and the fit does not say that this split is the prior's.
- The data pull further: on a GridDyn load with no motor D (``Cmld(f_d=0)``, static
  0.60) ``cmld-lite`` finds ``f_d`` 0.21 [0.14, 0.28] and ``f_s`` 0.39 [0.33, 0.50]; with
  motor D's Q curves made flat (``kq1 = kq2 = 0``) still ``f_d`` 0.17 [0.10, 0.29]. Its
  model of motor D takes up something of GridDyn's load that is not motor D.
- ``cmld-lite`` has no transformer tap, and motor D's break voltage and the
  electronics' trip are absolute voltages. At the true impedance (0.096 system p.u.) its
  load bus would sit at 0.922 p.u. where GridDyn's load end, raised by the 1.05 tap, is
  at 0.973; the fit lowers the series X to 0.045 (load base), lifting its load bus to
  0.955. With those thresholds scaled by 0.922 / 0.973, as a tap would, ``x_fd`` (0.092
  [0.080, 0.105]), the load end's ``p0`` (0.954 [0.949, 0.959]) and ``f_el`` ([0.03,
  0.17]) are covered, but not ``f_s`` ([0.228, 0.396]) nor ``f_d`` ([0.275, 0.424]).

False-alarm rate: with calibrated 95% intervals, 5% for each of the two coverage
assertions (the motors' share, the static share; the shares' bounds cannot fail: they lie
on their simplex). The run is deterministic (fixed seeds). The intervals come from
unconverged chains (R-hat above), so the coverage is not yet a calibrated one.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.griddyn import cases
from loadbayes.cases.griddyn.events import griddyn_events
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model

_REASON = cases.skip_reason()
pytestmark = [
    pytest.mark.statistical,
    pytest.mark.skipif(_REASON is not None, reason=_REASON or ""),
]

NOISE = 0.005
BEFORE_S, AFTER_S = 0.1, 0.4
DRAWS, BURN, CHAINS, SEED = 4000, 2000, 2, 0
SHARES = ("f_m_a", "f_m_b", "f_d", "f_el", "f_s", "f_motors", "a1", "a2", "a3")


def _interval(x) -> tuple[float, float]:
    lo, hi = np.quantile(np.asarray(x), [0.025, 0.975])
    return float(lo), float(hi)


@pytest.fixture(scope="module")
def fitted():
    depths = (cases.DEPTHS["shallow"], cases.DEPTHS["medium"])
    frames, truth = griddyn_events(depths, seed_noise=0, noise=NOISE, rate_hz=60.0)
    events = []
    for k, (frame, ev) in enumerate(zip(frames, truth["events"], strict=True)):
        t_fault = ev["t_fault_s"]
        w = frame[(frame.t_s >= t_fault - BEFORE_S) & (frame.t_s <= t_fault + AFTER_S)]
        events.append(
            EventRecord(
                w.t_s.to_numpy() - w.t_s.iloc[0], w.v.to_numpy(), w.p.to_numpy(),
                w.q.to_numpy(), w.angle_rad.to_numpy(), f"griddyn_{k}",
            )
        )  # fmt: skip
    model = dynamic_model("cmld-lite", f_hz=60.0, window_s=1.0 / 60.0)
    fit = fit_composite(
        model, events, sampler=SamplerSettings(draws=DRAWS, burn=BURN, chains=CHAINS, seed=SEED)
    )
    return fit, truth, events


def test_the_fractions_are_of_the_load_end_p(fitted):
    # The base of GridDyn's fractions: the composite's P at its load end, which the
    # harness records as `feeder_end`; the model's shares are of its load bus, that end.
    _, truth, events = fitted
    for ev, rec in zip(truth["events"], events, strict=True):
        p_end = ev["initial_state"]["loads"][cases.CMLD_LOAD][0]
        assert ev["feeder_end"]["p"][0] == pytest.approx(p_end, rel=1e-3)
        assert p_end < 0.97 * ev["p0"]  # the series losses: not the measured bus's P
        assert rec.n == 30 and rec.t[-1] == pytest.approx(BEFORE_S + AFTER_S - 1 / 60, abs=0.02)


def test_the_three_phase_motor_share_is_covered_and_every_share_is_physical(fitted):
    fit, truth, _ = fitted
    d = fit.posterior.draws
    for name in SHARES:
        x = np.asarray(d[name])
        assert np.all((x >= 0) & (x <= 1)), name
    parts = sum(np.asarray(d[n]) for n in ("f_m_a", "f_m_b", "f_d", "f_el", "f_s"))
    assert np.allclose(parts, 1.0)
    lo, hi = _interval(d["f_motors"])
    assert lo <= truth["three_phase_motor_share"] <= hi, (lo, hi)


def test_the_static_share_is_covered(fitted):
    fit, truth, _ = fitted
    lo, hi = _interval(fit.posterior.draws["f_s"])
    assert lo <= truth["fractions"]["static"] <= hi, (lo, hi)
