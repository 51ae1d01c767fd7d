"""Issue 35's recorder chain, measured: COMTRADE -> read comtrade -> events -> fit composite.

The event (tests/recorder_chain.py, SciPy and NumPy only): a 13.8 kV feeder, a motor of
T' 0.488 s taking f_m 0.42 of a motor + ZIP load, a 33% sag of six cycles with a -6
degree angle jump; the system at 59.98 Hz with a 60 mHz dip after the sag; 3rd and 5th
harmonics; the motor's decaying DC offset on the currents at both steps (stator time
constant 31 ms); 64 samples per cycle, noise on every sample, C37.111-1999 ASCII. It
goes through the CLI as a user's record does.

What the chain did to T' before the reader's offset estimate was changed (2 chains x
6,000 draws, seed 0; the same noise in every run):

- the whole chain: f_m 0.438 [0.407, 0.477] (covered), T' 0.130 [0.112, 0.147] s for
  0.488 (the issue's 0.110 [0.104, 0.117]);
- everything but the offset: T' 0.207 [0.155, 0.272] s; none of it (a plain 60 Hz sag
  without harmonics, angle jump, dip or offset): 0.369 [0.192, 0.594] s, covered;
- the offset alone: T' 0.139 [0.101, 0.190] s. Taking one switch off the whole chain
  leaves T' at 0.131 (harmonics), 0.136 (60.00 Hz), 0.149 (angle jump), 0.157 s (dip).

The reader's rows held the trajectory's one-cycle window means to their noise (sd 0.0010
in P and Q) in every row but the steps' straddling ones, with the harmonics, at 59.98
Hz, through the dip and the angle jump; with the offset, the three rows after each step
were off in P by -0.015, -0.009, -0.009 (the sag) and +0.026, +0.017, +0.011 (the
recovery), 9 to 26 noise sd. That was the mimic filter on a moving phasor: ``y = x +
tau dx/dt`` turns a phasor ``X(t)`` into ``(1 + j w tau) X + tau X'``, so the filtered
phasor is off by ``tau X' / (1 + j w tau)`` (about ``X' / (j w)``, whatever tau): the
motor's current recovering after the step (time constant about ``T' X' / X``, 37 ms
here) was read, turned by 90 degrees, into P. A fast decay of P after each step is what
a small T' explains.

Now (``recordings/phasor_fit.py``): the offset is fitted over two cycles as a
non-rotating exponential in the current's space vector, beside a moving phasor and the
harmonics, and taken out of the samples; the row is the plain fit of what is left.
Measured on this event: the rows after the sag within 1.9 noise sd (P -0.6, +0.6, -0.7,
+0.2; Q -1.9, -1.2, -0.9, -0.3 sd), after the recovery within 2.4 (P +1.4, +0.8,
+1.6, +0.7, +2.4; Q +1.2, +1.8, +0.9, +0.2, +0.5); the worst kept row 2.5, 2.7, 3.6
sd in V, P, Q (before: 2.5, 24.8, 10.3). Over 20 seeds the cleaned rows' mean errors are
within 1.3 sd and their sd 0.6-1.2 times the rows' far from the steps, as without the
offset (0.5-1.1; the mimic filter's: means -16 to +22 sd, sd 1.3-6.8 times). The
fourth row after the sag, whose next cycle crosses the recovery, keeps its plain phasor
(its two-cycle fit would hold a step): Q -2.8 sd on average, the offset's remainder.

Through the fit (2 x 6,000 draws, seed 0): f_m 0.455 [0.417, 0.491] (covered), T' 0.217
[0.160, 0.272] s, as without the offset (0.207 [0.155, 0.272]): the offset no longer
moves T'. What still does is the frequency path, which is the generator's: its motor
does not see the 59.98 Hz nor the dip that the waveforms (and the rows' ``angle_rad``,
with which ``fit composite`` drives its motor) carry (tests/recorder_chain.py). At
60.00 Hz without the dip (harmonics, angle jump and offset kept): T' 0.396 [0.258,
0.559] s, f_m 0.422 [0.379, 0.469], both covered (0.383 [0.259, 0.573] without the
offset); the dip alone (at 60.00 Hz) leaves T' 0.240 [0.172, 0.306], the 59.98 Hz alone
0.333 [0.227, 0.452]; with ``angle_rad`` and ``f`` dropped
from the whole chain's event (the angle jump lost with them): T' 0.238 [0.204, 0.283].
The fit test stays a strict xfail until the generator's motor sees the frequency.

False alarms: the rows' bound (6 noise sd on a row) is crossed by noise with probability
below 1e-6 per row. The strict xfail records the measured miss; its passing would say
that the chain changed (strict: then the xfail must go).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from recorder_chain import SAG, write_chain_event
from waveform_composite import window_means

pytestmark = [
    pytest.mark.integration,
    pytest.mark.statistical,
    pytest.mark.usefixtures("no_cost_probe"),
]

V_BASE_KV, S_BASE_MVA, F0 = 13.8, 10.0, 60.0
STEPS = (SAG.start_s, SAG.start_s + SAG.duration_s)
FIT = ("--draws", 6000, "--burn", 1500, "--chains", 2, "--seed", 0)


def cli(*args):
    res = CliRunner().invoke(main, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """The whole chain's event, and the same event without the motor's offset, read."""
    folder = tmp_path_factory.mktemp("chain")
    out = {}
    for name, offset in (("whole", True), ("no_offset", False)):
        cfg, truth, traj = write_chain_event(folder / name, dc_offset=offset)
        csv = folder / f"{name}.csv"
        cli("read", "comtrade", cfg, "--out", csv, "--v-base", V_BASE_KV,
            "--s-base", S_BASE_MVA, "--quiet")  # fmt: skip
        out[name] = (csv, truth, traj)
    return out


def row_errors(csv, traj):
    """The rows' V, P, Q minus the window means; which rows count; the noise sd."""
    rows = pd.read_csv(csv)
    t = rows["t_s"].to_numpy()
    err = np.vstack([rows[c].to_numpy() for c in ("v", "p", "q")])
    err = err - window_means(traj, t, 1.0 / F0)
    keep = ~rows["straddle"].to_numpy(dtype=bool)
    far = np.all([np.abs(t - ts) > 3.0 / F0 for ts in STEPS], axis=0)
    return err, keep, err[:, keep & far].std(axis=1)


def test_rows_hold_the_window_means_through_frequency_harmonics_and_angle(chain):
    """Without the offset, every non-straddling row is its window mean to 6 noise sd."""
    csv, _, traj = chain["no_offset"]
    err, keep, sd = row_errors(csv, traj)
    assert np.all(sd < 0.0015), sd  # 0.10-0.12% of the base in P and Q (measured)
    worst = np.max(np.abs(err[:, keep]) / sd[:, None], axis=1)
    assert np.all(worst < 6.0), dict(zip("vpq", worst.round(1), strict=True))


def test_rows_after_the_steps_hold_the_window_means_with_the_offset(chain):
    """With the motor's decaying offset, the rows after the steps are their window means."""
    csv, _, traj = chain["whole"]
    err, keep, sd = row_errors(csv, traj)
    worst = np.max(np.abs(err[:, keep]) / sd[:, None], axis=1)
    assert np.all(worst < 6.0), dict(zip("vpq", worst.round(1), strict=True))


@pytest.mark.xfail(
    strict=True,
    reason="T' 0.217 [0.160, 0.272] s for 0.488 through read -> events -> fit (2 x 6,000 "
    "draws, seed 0; f_m 0.455 [0.417, 0.491] covered; measured): the generator's motor does "
    "not see the 59.98 Hz and the dip the rows' angle carries (0.396 [0.258, 0.559] at 60 Hz)",
)
def test_fit_composite_covers_t_prime_through_the_chain(chain, tmp_path):
    csv, truth, _ = chain["whole"]
    cli("events", csv, "--out", tmp_path / "ev", "--quiet")
    out = tmp_path / "fit.json"
    cli("fit", "composite", tmp_path / "ev" / "event_001.csv", "--json", out,
        "--quiet", *FIT)  # fmt: skip
    par = json.loads(out.read_text())["parameters"]["t_prime_s"]
    assert par["hdi_low"] <= truth["t_prime_s"] <= par["hdi_high"], par
