"""Issue 40's pooled fleet: buses that differ 25-fold in relative noise and in size.

The generator is written here (not loadbayes.fleet.generate, nor the study's): three
classes, each bus's (a1, a2, a4, a5) its class mix plus N(0, spread^2), P0 log-uniform in
0.3-8 MW (unknown to the fit), Q0 0.2-0.6 P0, 60-1,500 rows, a +/-2-4% voltage swing,
and a fixed 10 kW (kvar) of noise, so the relative noise differs 25-fold between buses;
the data are in MW with ``s_base`` 10 MVA. ``n_rich`` more buses per fleet have what
such a band lacks: 1,500 rows on a +/-12% swing at 8 MW (Q0 0.6 P0).

On that band no ordinary bus's data fix its shares' split along the curvature
``a1 - 2 a2 + a3`` (sd 0.12 at best, 16 on thin buses): the split is its class's, set by
the class mean and the class spread along that direction. With the spread's scale fixed
by the hyperprior (until 2026-11-29) the shares covered only where the truth's spread was
the prior's: 89.4% at 0.1 and 82% at 0.2 on these fleets. With each class's scale learned
(``HierPrior.spread_scale``, the default) from what the data see, the spread along the
slope ``2 a1 + a2``, they cover at every spread tried (0.05, 0.1, 0.2). The buses of a
class share the class mean's error along the curvature, so a fleet's share intervals hit
or miss together, class by class: one fleet is a few trials, not hundreds, and the checks
below are on means over fleets with the spread of single fleets measured.

``make test`` runs 3 fleets at spread 0.1 and 3 at 0.2 (seconds); ``make validate``
(LOADBAYES_VALIDATE=1) 40 fleets at each of 0.05, 0.1 and 0.2, two-sided.
"""

import os

import numpy as np
import pandas as pd
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.partitions import ReadSpec
from loadbayes.fleet.run import run_fleet

pytestmark = pytest.mark.statistical

FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"
#: The issue's margin: +/-1.96 binomial sd of 300 intervals at 0.95.
MARGIN = 0.038

MIXES = {
    "residential": (0.45, 0.25, 0.60, 0.20),
    "commercial": (0.20, 0.30, 0.35, 0.40),
    "industrial": (0.05, 0.15, 0.10, 0.30),
}
S_BASE = 10.0  # MVA
NOISE_MW = 0.01


def hetero_fleet(seed, n_buses=60, spread=0.1, n_rich=0):
    rng = np.random.default_rng(seed)
    names = list(MIXES)
    nb = n_buses + n_rich
    cls = rng.integers(0, 3, nb)
    theta = np.array([MIXES[names[c]] for c in cls]) + spread * rng.standard_normal((nb, 4))
    p0 = np.exp(rng.uniform(np.log(0.3), np.log(8.0), nb))
    q0 = p0 * rng.uniform(0.2, 0.6, nb)
    rows, truth = [], []
    for b in range(nb):
        rich = b >= n_buses
        n = 1500 if rich else int(rng.integers(60, 1501))
        half = 0.12 if rich else rng.uniform(0.02, 0.04)
        if rich:
            p0[b], q0[b] = 8.0, 4.8
        v = 1.0 + half * rng.uniform(-1, 1, n)
        a1, a2, a4, a5 = theta[b]
        p = p0[b] * (a1 * v**2 + a2 * v + 1 - a1 - a2) + NOISE_MW * rng.standard_normal(n)
        q = q0[b] * (a4 * v**2 + a5 * v + 1 - a4 - a5) + NOISE_MW * rng.standard_normal(n)
        bus = f"b{b:03d}"
        rows.append(
            pd.DataFrame({"bus_id": bus, "customer_class": names[cls[b]], "v": v, "p": p, "q": q})
        )
        truth.append(
            {"bus": bus, "a1": a1, "a2": a2, "a4": a4, "a5": a5, "p0": p0[b] / S_BASE,
             "q0": q0[b] / S_BASE, "curv_p": _data_sd(v, p), "curv_q": _data_sd(v, q)}
        )  # fmt: skip
    return pd.concat(rows, ignore_index=True), pd.DataFrame(truth)


def _data_sd(v, y):
    """The bus's own least-squares sd of its shares along (1, -2) / sqrt 5 (delta method)."""
    y = y / S_BASE
    x = np.c_[np.ones_like(v), v**2 - 1, v - 1]
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    s2 = np.sum((y - x @ beta) ** 2) / (len(y) - 3)
    cov = s2 * np.linalg.inv(x.T @ x)
    jac = np.array([[-beta[1], beta[0], 0.0], [-beta[2], 0.0, beta[0]]]) / beta[0] ** 2
    u = np.array([1.0, -2.0]) / np.sqrt(5.0)
    return float(np.sqrt(u @ jac @ cov @ jac.T @ u))


def _fit(tmp_path, seed, **kw):
    rows, truth = hetero_fleet(seed, **kw)
    path = tmp_path / f"fleet{seed}.parquet"
    rows.to_parquet(path)
    res = run_fleet(
        str(path), ReadSpec(class_col="customer_class", s_base=S_BASE), pool="class",
        p0="auto", q0="auto", sampler=SamplerSettings(chains=2, draws=1500, burn=500, seed=3),
    )  # fmt: skip
    bus = res.table[res.table["level"] == "bus"]
    return bus.merge(truth, on="bus"), res


def _inside(rows, truth):
    return (rows["hdi_low"].to_numpy() <= truth) & (truth <= rows["hdi_high"].to_numpy())


@pytest.fixture(scope="module")
def fleets(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hetero")
    return [_fit(tmp, seed, n_rich=3) for seed in range(3)]


@pytest.fixture(scope="module")
def wide(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hetero_wide")
    return [_fit(tmp, seed, n_rich=3, spread=0.2) for seed in range(3)]


def _hits(bus):
    """One fleet's interval hits per quantity: dp_dv, dq_dv and the shares a1, a2, a4, a5."""
    out = {}
    for p, t in (("dp_dv", bus["p0"] * (2 * bus["a1"] + bus["a2"])),
                 ("dq_dv", bus["q0"] * (2 * bus["a4"] + bus["a5"]))):  # fmt: skip
        r = bus["parameter"] == p
        out[p] = _inside(bus[r], t[r].to_numpy())
    for p in ("a1", "a2", "a4", "a5"):
        r = bus["parameter"] == p
        out[p] = _inside(bus[r], bus.loc[r, p].to_numpy())
    return out


def _rates(fleet_list):
    """Per fleet, the share of intervals that cover: slopes, a1 and a2, all four shares."""
    rows = []
    for bus, _ in fleet_list:
        h = _hits(bus)
        rows.append({
            "slopes": np.r_[h["dp_dv"], h["dq_dv"]].mean(),
            "a1_a2": np.r_[h["a1"], h["a2"]].mean(),
            "shares": np.r_[h["a1"], h["a2"], h["a4"], h["a5"]].mean(),
        })  # fmt: skip
    return pd.DataFrame(rows)


def test_slopes_and_shares_cover_at_two_spreads(fleets, wide):
    # Six fleets of 60 buses (+3 rich), 95% HDIs: three at a true spread of 0.1, three at
    # 0.2; 756 slope (dP/dV, dQ/dV) and 1,512 share (a1, a2, a4, a5) intervals. The buses
    # of a class hit or miss together along the curvature, so the six fleets' mean is
    # judged against what single fleets were measured to do (seeds 100-119 of this
    # generator and sampler, 20 fleets a spread): shares 0.965 at 0.1 (sd 0.048 a fleet)
    # and 0.962 at 0.2 (sd 0.044); slopes 0.953 (sd 0.016). With the class scale fixed at
    # the hyperprior's 0.1 (spread_scale=None, the default until 2026-11-29) the shares
    # were 0.894 (sd 0.061) and 0.775 (sd 0.076): this test fails on it.
    # (a) Shares: the mean of the six fleets at least 0.95 - 0.038 (the margin, the
    # binomial one of 300 independent intervals): resampling the 40 measured fleets, a mean
    # of three at each spread falls below it 0.8% of the time (the false alarm), and 99.9%
    # of the time with the fixed scale. The upper side (over-coverage) needs more fleets
    # than seconds allow: make validate checks both sides on 40 fleets a spread.
    # (b) Slopes, what the data fix: the mean within 0.029 of 0.95 (the binomial margin of
    # 756 intervals, 0.016, widened by the measured design effect): false alarm < 0.01%.
    both = pd.concat([_rates(fleets), _rates(wide)], ignore_index=True)
    assert sum(b["parameter"].eq("a1").sum() for b, _ in fleets + wide) == 378
    assert both["shares"].mean() >= 0.95 - MARGIN, both
    assert abs(both["slopes"].mean() - 0.95) <= 0.029, both


@pytest.mark.skipif(not FULL, reason="make validate (LOADBAYES_VALIDATE=1): 120 fleets")
@pytest.mark.parametrize("spread", [0.05, 0.1, 0.2])
def test_shares_cover_within_the_margin_at_each_spread(tmp_path, spread):
    # 40 fleets a spread (seeds 100-139): 7,560 share intervals, 120 classes' errors
    # along the curvature. The mean over the fleets of all four shares within the issue's
    # margin (0.95 +/- 0.038) on both sides, of a1, a2 at least 0.95 - 0.038 (the issue's
    # under-coverage), of the slopes within 0.022. Measured (2026-11-29, 2 shared cores,
    # 8.7 min): shares 0.964, 0.964, 0.961 at 0.05, 0.1, 0.2 (sd a fleet 0.051, 0.045,
    # 0.040); a1, a2 0.957, 0.955, 0.953 (sd 0.081, 0.075, 0.060); slopes 0.951, 0.952,
    # 0.952 (sd 0.019). The nearest bound is 3 sd of a mean of 40 away (shares at 0.05
    # against 0.988), the others 3.4 sd and more: false alarm about 0.3% over the spreads.
    rates = _rates([_fit(tmp_path, seed, n_rich=3, spread=spread) for seed in range(100, 140)])
    print(spread, rates.mean().to_dict(), rates.std().to_dict())
    assert abs(rates["shares"].mean() - 0.95) <= MARGIN, rates.describe()
    assert rates["a1_a2"].mean() >= 0.95 - MARGIN, rates.describe()
    assert abs(rates["slopes"].mean() - 0.95) <= 0.022, rates.describe()


def test_the_table_says_which_buses_shares_are_their_class(fleets):
    # (c) Per bus and channel, prior_driven (the ratio of item 1: posterior to prior sd
    # along a1 - 2 a2 + a3 from the bus's data and its class spread, above 0.7) must be
    # set where the bus's own least-squares sd along it is above 3 spreads (the prior
    # then gives over 90% of the precision: ratio near 1) and clear where it is below
    # half a spread (ratio 0.45 at most); in between either may be right. The rich buses
    # (sd about 0.02) are the clear ones. On 20 fleets (seeds 100-119) the ratio of the
    # thin ones was 0.87 or more, of the rich ones 0.35 or less: no miss, no false alarm
    # (the ratio uses the posterior means of tau and Sigma only, far from 0.7 on either
    # side). On main (no column) the test fails.
    thin = rich = 0
    for bus, res in fleets:
        assert "prior_driven" in bus.columns
        for params, curv in ((("a1", "a2", "a3"), "curv_p"), (("a4", "a5", "a6"), "curv_q")):
            rows = bus[bus["parameter"] == params[0]]
            flag = rows["prior_driven"].astype(bool).to_numpy()
            sd = rows[curv].to_numpy()
            thin_b, rich_b = sd > 3 * 0.1, sd < 0.5 * 0.1
            thin += thin_b.sum()
            rich += rich_b.sum()
            assert flag[thin_b].all(), rows.loc[thin_b & ~flag, ["bus", "prior_sd_ratio"]]
            assert not flag[rich_b].any(), rows.loc[rich_b & flag, ["bus", "prior_sd_ratio"]]
            # the three shares of a channel carry the same flag, and the words say it
            for p in params[1:]:
                same = bus[bus["parameter"] == p]["prior_driven"].astype(bool).to_numpy()
                assert (same == flag).all()
            said = (
                rows["warnings"]
                .str.contains(f"{params[0]}, {params[1]} not determined separately", regex=False)
                .to_numpy()
            )
            assert (said == flag).all()
        # the run says it once, with the count
        assert any("not determined separately" in w for w in res.settings["warnings"])
    assert thin >= 100 and rich >= 15, (thin, rich)
